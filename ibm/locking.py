"""A remedy for volumetric locking: the mean dilatation (B-bar) at small strain.

Plastic flow is isochoric, so bilinear cells with several points each lock: every point adds its
own volumetric constraint. B-bar (Hughes 1980) keeps the deviatoric strain of each point and gives
every material point of a cell the cell's mean dilatation, one volumetric constraint per cell:

    grad u_bar = grad u - (div u / d) I + (theta_c / d) I,   theta_c = sum_p V_p div u(x_p) / sum_p V_p

over the cell's points. Then sum over the cell's points of V (theta_c - div u) vanishes, so a
uniform stress is still in equilibrium (the patch test), and grad u_bar = grad u for a linear
field. The operator stays linear in the cell's nodal values; with the standard basis every point
of a cell has the cell's nodes (GIMP's wider supports are refused with locking fbar). The IBM's
band correction keeps its own kinematics (ibm.newton.point_sets): taking the band into the mean
as well made its Newton iteration diverge on Hill's cylinder, leaving it out collapses at the
limit like the other methods (tests/test_collapse.py).
"""
from __future__ import annotations

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
    n, dd, kd = G.shape
    d = int(round(np.sqrt(dd)))
    match = nodes[:, :, None] == cell_nodes[:, None, :]                        # (n, k, 4)
    if not np.all(match.any(axis=1)):
        raise ValueError("a point's support misses a node of the cell it lies in")
    position = np.argmax(match, axis=1)                                        # (n, 4) node slot per cell node
    centre = np.zeros((n, kd))
    columns = (d * position[:, :, None] + np.arange(d)).reshape(n, -1)         # (n, 4 d)
    np.put_along_axis(centre, columns, mean, axis=1)
    own = divergence(G)                                                        # (n, k d) div u at the point
    bar = G.copy()
    for i in range(d):
        bar[:, i * d + i] += (centre - own) / d
    return bar
