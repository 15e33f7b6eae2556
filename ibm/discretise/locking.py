"""A remedy for volumetric locking: the mean dilatation, B-bar at small strain and F-bar at large.

Plastic flow is isochoric, so bilinear cells with several points each lock: every point adds its
own volumetric constraint. B-bar (Hughes 1980) keeps the deviatoric strain of each point and gives
every material point of a cell the cell's mean dilatation, one volumetric constraint per cell:

    grad u_bar = grad u - (div u / d) I + (theta_c / d) I,   theta_c = sum_p V_p div u(x_p) / sum_p V_p

over the cell's points. Then sum over the cell's points of V (theta_c - div u) vanishes, so a
uniform stress is still in equilibrium (the patch test), and grad u_bar = grad u for a linear
field. The operator stays linear in the cell's nodal values; with the standard basis every point
of a cell has the cell's nodes (GIMP's wider supports are refused with locking fbar). The IBM's
band correction keeps its own kinematics (ibm.large.newton.point_sets): taking the band into the mean
as well made its Newton iteration diverge on Hill's cylinder, leaving it out collapses at the
limit like the other methods (tests/studies/problems/test_collapse.py).

At large strain (F-bar, de Souza Neto et al. 1996, with the cell's mean Jacobian): each point's
increment dF (relative to x_n) is replaced by dF_bar = (J_c / J)^(1/d) dF in the plane (plane
strain: dF_33 = 1 stays), J = det dF, J_c = sum_p V_p J_p / sum_p V_p over the cell's points
(V the x_n volumes), so det dF_bar = J_c. The stress comes from dF_bar; the internal force keeps
the actual geometry, f = sum_p V_p J_p Gc_p^T sigma(dF_bar). Its linearisation (derived in
tests/ibm/discretise/test_locking.py's docstring and checked there by finite differences) is

    K = sum_p V_p J_p Gc^T [a Gc + q (div_c - div_p)],   q = (a : I - (d - 1) sigma) / d,

a the model's spatial tangent at dF_bar, div_p the point's divergence row (Gc's trace rows),
div_c their mean over the cell weighted by the current volumes V J: unsymmetric, on the same
DOFs as the point's own block.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


LOCKING = ("none", "fbar")


def divergence(G: np.ndarray) -> np.ndarray:
    """(n, k d) the divergence rows sum_i G[:, (i, i)] of gradient operators G (n, d d, k d)."""
    d = int(round(np.sqrt(G.shape[1])))
    return sum(G[:, i * d + i] for i in range(d))


def in_cell_order(rows: np.ndarray, nodes: np.ndarray, cell_nodes: np.ndarray) -> np.ndarray:
    """rows (n, k d) over each point's nodes (n, k) taken in the order of its cell's nodes (n, 4)."""
    n, kd = rows.shape
    d = kd // nodes.shape[1]
    match = nodes[:, :, None] == cell_nodes[:, None, :]                        # (n, k, 4)
    if not np.all(match.any(axis=1)):
        raise ValueError("a point's support misses a node of the cell it lies in")
    position = np.argmax(match, axis=1)
    columns = (d * position[:, :, None] + np.arange(d)).reshape(n, -1)
    return np.take_along_axis(rows, columns, axis=1)


def cell_means(cells: np.ndarray, weights: np.ndarray, rows: np.ndarray, volume_cells: np.ndarray,
               volume: np.ndarray) -> dict:
    """Per cell: sum_q weights_q rows_q (rows in cell order, (n, ...)) over the points `cells` (n,),
    divided by the cell's volume sum_p volume_p (volume_cells (m,) the cells of those points)."""
    unique, inverse = np.unique(np.concatenate([cells, volume_cells]), return_inverse=True)
    size = np.zeros(len(unique))
    np.add.at(size, inverse[len(cells):], volume)
    total = np.zeros((len(unique),) + rows.shape[1:])
    np.add.at(total, inverse[:len(cells)], weights.reshape((-1,) + (1,) * (rows.ndim - 1)) * rows)
    return {"cells": unique, "mean": total / np.where(size > 0, size, 1.0).reshape((-1,) + (1,) * (rows.ndim - 1))}


def mean_dilatation(G: np.ndarray, nodes: np.ndarray, cell_nodes: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """G (n, d d, k d) with its volumetric part replaced by its cell's mean (see the module doc).

    nodes (n, k): each point's nodes (its DOFs are d v + a); cell_nodes (n, 4) the nodes of the cell it
    lies in, all among its own; mean (n, 4 d) the cell's mean dilatation over those cells' DOFs."""
    d = int(round(np.sqrt(G.shape[1])))
    centre = spread(mean, nodes, cell_nodes)
    own = divergence(G)                                                        # (n, k d) div u at the point
    bar = G.copy()
    for i in range(d):
        bar[:, i * d + i] += (centre - own) / d
    return bar


def spread(mean: np.ndarray, nodes: np.ndarray, cell_nodes: np.ndarray) -> np.ndarray:
    """(n, k d): each point's cell row mean (n, 4 d), in cell order, placed on the point's own DOFs."""
    n, k = nodes.shape
    d = mean.shape[1] // cell_nodes.shape[1]
    match = nodes[:, :, None] == cell_nodes[:, None, :]                        # (n, k, 4)
    if not np.all(match.any(axis=1)):
        raise ValueError("a point's support misses a node of the cell it lies in")
    position = np.argmax(match, axis=1)                                        # (n, 4) node slot per cell node
    columns = (d * position[:, :, None] + np.arange(d)).reshape(n, -1)
    out = np.zeros((n, k * d))
    np.put_along_axis(out, columns, mean, axis=1)
    return out


@dataclass(frozen=True, eq=False)
class CellGroups:
    """Which cell each of a set's points lies in (F-bar's means): cells (n,), the point's nodes
    (n, k) and its cell's nodes (n, 4)."""

    cells: np.ndarray
    nodes: np.ndarray
    cell_nodes: np.ndarray

    def cell_mean(self, rows: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """(n, 4 d): the weight-weighted mean over each point's cell of rows (n, k d), in cell order."""
        means = cell_means(self.cells, weight, in_cell_order(rows, self.nodes, self.cell_nodes), self.cells, weight)
        return means["mean"][np.searchsorted(means["cells"], self.cells)]

    def mean_row(self, rows: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """(n, k d): that mean on each point's own DOFs."""
        return spread(self.cell_mean(rows, weight), self.nodes, self.cell_nodes)

    def mean(self, values: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """(n,): the weight-weighted mean of values (n,) over each point's cell."""
        means = cell_means(self.cells, weight, values, self.cells, weight)
        return means["mean"][np.searchsorted(means["cells"], self.cells)]
