"""Gauss points on the walls inside a load step, shared by the weak methods' treatments
(penalty, Nitsche, Lagrange): wall terms live on wall ∩ current body (the outline's essential
edges at the step start), ORDER points per piece between grid lines; n is the outward normal,
P the projector n n (roller) or I (fixed), g the wall's displacement this step.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from baselines.boundary import EdgePoints, edge_pieces
from ibm.discretise.assembly import shape_vector
from ibm.quadrature.bands import edge_quadrature
from ibm.large.treatment import StepContext

ORDER = 4   # Gauss points per wall piece


@dataclass(frozen=True, eq=False)
class WallPoints:
    """Gauss points of every wall piece in one step: x (m, d), weight (m,), cells (m,), outward
    normal (m, d), projector P (m, d, d), wall displacement g (m, d), DOFs (m, k d), Nv (m, d, k d)
    (k = 2^d nodes a cell), and the edge points of each wall (for grouping)."""

    x: np.ndarray
    weight: np.ndarray
    cells: np.ndarray
    normal: np.ndarray
    projector: np.ndarray
    g: np.ndarray
    dofs: np.ndarray
    Nv: np.ndarray
    edges: list

    n_dofs: int = 0
    wall: np.ndarray | None = None          # (m,) the wall of each point

    def subset(self, keep: np.ndarray) -> "WallPoints":
        """The points where keep (m,) is true, in their order (no edge grouping)."""
        return WallPoints(self.x[keep], self.weight[keep], self.cells[keep], self.normal[keep], self.projector[keep],
                          self.g[keep], self.dofs[keep], self.Nv[keep], [], self.n_dofs, self.wall[keep])

    def blocks(self, left: np.ndarray, right: np.ndarray) -> sp.csr_matrix:
        """sum_q left_q^T right_q for (m, r, k d) operators, assembled on the points' DOFs."""
        block = np.matmul(left.transpose(0, 2, 1), right)
        order, starts, dofs = self.by_cell
        # few points a cell (2D walls, ~4): summed point by point, the order the 2D results depend on
        # to the last bit; many (3D walls, ~100): summed by cell first, as they share its DOFs
        if len(starts) > len(order) / 8:
            return _assemble(self.dofs, block, self.n_dofs)
        return _assemble(dofs, np.add.reduceat(block[order], starts, axis=0), self.n_dofs)

    @cached_property
    def by_cell(self) -> tuple:
        """(order sorting the points by cell, start of each cell's run, DOFs (c, k d) of each cell)."""
        order = np.argsort(self.cells, kind="stable")
        starts = np.flatnonzero(np.concatenate([[True], np.diff(self.cells[order]) != 0]))
        return order, starts, self.dofs[order[starts]]


def _assemble(dofs: np.ndarray, block: np.ndarray, n: int) -> sp.csr_matrix:
    m = dofs.shape[1]
    return sp.csr_matrix((block.ravel(), (np.repeat(dofs, m, axis=1).ravel(), np.tile(dofs, (1, m)).ravel())),
                         shape=(n, n))


def wall_points(context: StepContext) -> WallPoints:
    """The Gauss points of every wall this step (ORDER per piece between grid lines), with their edges."""
    body, grid = context.body, context.grid
    rules = {edge: edge_quadrature(body, grid, edge, None, order=ORDER) for edge in body.essential_edges}
    edges = [EdgePoints(edge, body.kinds[edge], np.tile(-body.normals[edge], (len(qp), 1)), qp,
                        edge_pieces(body, edge, qp, ORDER)) for edge, qp in rules.items()]
    return points_on_walls(body, grid, lambda edge: (rules[edge].x, rules[edge].weight, rules[edge].cells),
                           context.wall_vector, edges)


def points_on_walls(body, grid, placed, wall_vector=None, edges=()) -> WallPoints:
    """WallPoints from the points `placed(edge) -> (x (m, d), weight (m,), cells (m,))` on every essential
    edge: outward normals, projectors, the wall's displacement wall_vector(k) this step (zero when None)
    and the shape functions; `edges`: the edge points of each wall, when the methods group by them."""
    parts = []
    for wall, edge in enumerate(body.essential_edges):
        x, weight, cells = placed(edge)
        n = -body.normals[edge]
        P = np.outer(n, n) if body.kinds[edge] == "roller" else np.eye(grid.dim)
        g = np.zeros(grid.dim) if wall_vector is None else wall_vector(wall)
        m = len(x)
        parts.append((x, weight, cells, np.tile(n, (m, 1)), np.tile(P, (m, 1, 1)), np.tile(g, (m, 1)),
                      np.full(m, wall)))
    d = grid.dim
    empty = (np.zeros((0, d)), np.zeros(0), np.zeros(0, int), np.zeros((0, d)), np.zeros((0, d, d)), np.zeros((0, d)),
             np.zeros(0, int))        # a body with no walls (held by contact with an obstacle only)
    x, weight, cells, normal, projector, g, walls = (np.concatenate([empty[i]] + [p[i] for p in parts])
                                                     for i in range(7))
    N, _ = grid.shape_functions(x, cells)
    return WallPoints(x, weight, cells, normal, projector, g, grid.cell_dofs(cells), shape_vector(N), list(edges),
                      grid.dim * grid.n_nodes, walls)


def points_on_edges(body, grid, edges) -> WallPoints:
    """Gauss points (ORDER per piece between grid lines) of free edges that may touch an obstacle, with the
    body's outward normals (radial on an arc); `wall` holds -1 - edge, g is zero."""
    parts = []
    for edge in edges:
        rule = edge_quadrature(body, grid, edge, None, order=ORDER)
        parts.append((rule.x, rule.weight, rule.cells, body.outward(edge, rule.x), np.full(len(rule.x), -1 - edge)))
    x, weight, cells, normal, walls = (np.concatenate([p[i] for p in parts]) for i in range(5))
    m, d = x.shape
    N, _ = grid.shape_functions(x, cells)
    return WallPoints(x, weight, cells, normal, np.broadcast_to(np.eye(d), (m, d, d)).copy(), np.zeros((m, d)),
                      grid.cell_dofs(cells), shape_vector(N), [], grid.dim * grid.n_nodes, walls)


def joined(a: WallPoints, b: WallPoints) -> WallPoints:
    """The points of a, then those of b (no edge grouping)."""
    return WallPoints(*(np.concatenate([getattr(a, name), getattr(b, name)]) for name in
                        ("x", "weight", "cells", "normal", "projector", "g", "dofs", "Nv")), [], a.n_dofs,
                      np.concatenate([a.wall, b.wall]))


def penalty_wall(points: WallPoints, beta: float):
    """dU -> (beta int P(dw - g) . v, its constant tangent)."""
    PNv = np.matmul(points.projector, points.Nv) * (beta * points.weight)[:, None, None]
    K = points.blocks(points.Nv, PNv)
    g_load = np.bincount(points.dofs.ravel(), np.einsum("qia,qi->qa", PNv, points.g).ravel(),
                         minlength=points.n_dofs)

    def wall(dU):
        return K @ dU - g_load, K

    return wall, K, g_load
