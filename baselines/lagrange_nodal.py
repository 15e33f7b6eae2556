"""Lagrange multipliers collocated at grid-line crossings (the naive choice), with its declaration
(LAGRANGE_NODAL): point collocation where the edge crosses grid lines and at its vertices (a vertex
belongs to the essential edge starting there). It over-constrains small cuts: the multiplier
tractions -lambda_c / (tributary length) oscillate along the edge and the displacement locks. Kept
only to show that failure, never a default; straight edges only.
"""
from __future__ import annotations

from time import perf_counter

import numpy as np

from baselines.boundary import EdgePoints, bulk_system, grid_solution, traction_variation
from baselines.edge_reactions import multiplier_reactions
from baselines.lagrange import saddle_solve, components, constraint_rows, traction_of
from ibm.boundary_method import BoundaryMethod, Supports
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid
from ibm.implicit_boundary import SUPPORT
from ibm.small.model import BoundaryTraction, Model, Solution


def grid_crossings(a: np.ndarray, b: np.ndarray, grid: Grid) -> np.ndarray:
    """Sorted parameters t in [0, 1] of the segment a -> b: its ends and its grid-line crossings."""
    d = b - a
    t = [np.array([0.0, 1.0])]
    for axis in range(2):
        if abs(d[axis]) > 0:
            lines = grid.h * np.arange(np.ceil(min(a[axis], b[axis]) / grid.h),
                                       np.floor(max(a[axis], b[axis]) / grid.h) + 1)
            t.append((lines - a[axis]) / d[axis])
    t = np.unique(np.clip(np.concatenate(t), 0.0, 1.0))
    return t[np.concatenate([[True], np.diff(t) > 1e-12])]


def collocation_points(model: Model, edge: EdgePoints) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Collocation points (m, 2), their cells (m,) and tributary lengths (m,) on one straight edge."""
    body, grid, k = model.body, model.grid, edge.edge
    if body.arcs and body.arcs[k] is not None:
        raise InputError(f"method 'lagrange-nodal' collocates at the grid-line crossings of straight edges; piece {k} "
                         f"is an essential ({edge.kind}) arc: make it straight or use lagrange")
    t = grid_crossings(body.starts[k], body.ends[k], grid)
    if ((k + 1) % body.n_edges) in body.essential_edges:
        t = t[:-1]                      # the end vertex belongs to the next essential edge
    x = body.starts[k] + t[:, None] * body.tangents[k]
    bounds = np.concatenate([[0.0], (t[1:] + t[:-1]) / 2, [1.0]])
    length = (bounds[1:] - bounds[:-1]) * body.lengths[k]
    inward = body.normals[k] + 1e-9 * (body.ends[k] - body.starts[k]) / body.lengths[k]
    cells = grid.locate_towards(x, inward)
    return x, cells, length


def solve_lagrange_nodal(model: Model, support_threshold: float = 1e-4, estimate_condition: bool = True) -> Solution:
    """Point multipliers at grid-line crossings and vertices (the naive choice)."""
    start = perf_counter()
    bulk = bulk_system(model)
    points = [collocation_points(model, e) for e in bulk.edges]
    normals = [model.body.outward(e.edge, x) for e, (x, _, _) in zip(bulk.edges, points)]
    blocks = [constraint_rows(model, x, cells, np.ones(len(x)), np.arange(len(x)), components(e.kind, n), 0).tocsr()
              for e, (x, cells, _), n in zip(bulk.edges, points, normals)]
    U, multipliers, info = saddle_solve(model, bulk, bulk.K, blocks, start, support_threshold)
    xs, weight, edge_ids, value = [], [], [], []
    for e, (x, _, length), n, lam in zip(bulk.edges, points, normals, multipliers):
        forces = lam.reshape(len(x), -1)
        xs.append(x), weight.append(length), edge_ids.append(np.full(len(x), e.edge))
        value.append(traction_of(e.kind, n, forces / length[:, None]))
    tractions = BoundaryTraction(np.concatenate(xs), np.concatenate(weight), np.concatenate(edge_ids),
                                 np.concatenate(value))
    if model.dim == 2:     # along each edge; a face has no one direction to order its points by
        info["traction_variation"] = traction_variation(tractions, model.body)
    return grid_solution(model, U, info, start, tractions)


class LagrangeNodalMethod(BoundaryMethod):
    name = "lagrange-nodal"
    summary = "Lagrange multipliers collocated at grid-line crossings (naive, inf-sup unstable)"
    parameters = (SUPPORT,)
    supports = Supports({
        "3d": "its collocation points are the grid-line crossings of straight edges, which a face does not have",
        "load-steps": "its collocated multipliers are inf-sup unstable already at small strain; it is kept only "
                      "to show that failure (use lagrange)",
        "load-steps-3d": "its collocated multipliers are inf-sup unstable already at small strain (use lagrange)",
        "arcs": "it collocates at the grid-line crossings of straight edges (use lagrange)",
        "amg": "its saddle-point system is indefinite, which CG with multigrid cannot solve"})

    def solve(self, model, support_threshold=1e-4):
        return solve_lagrange_nodal(model, support_threshold)

    def reactions(self, model, solution):
        return multiplier_reactions(model, solution, "lagrange-nodal")


LAGRANGE_NODAL = LagrangeNodalMethod()
