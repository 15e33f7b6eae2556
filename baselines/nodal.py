"""Nodal constraints, with their declaration (NODAL): the normal component (both on fixed edges) of
every grid node on an essential edge's line is fixed, as most MPM codes do, at small strain and in
each load step (the wall's motion). Only for straight edges on grid
lines: any other edge, and every essential arc, is refused. With u = u^h + u^a the constrained
nodal values of u^h are zero.
"""
from __future__ import annotations

from dataclasses import dataclass
from time import perf_counter

import numpy as np

from baselines.boundary import bulk_system, grid_solution, piece_reactions
from ibm.exceptions import InputError
from baselines.edge_reactions import residual_reactions
from ibm.boundary_method import BoundaryMethod, Supports
from ibm.small.model import Model, Solution
from ibm.large.treatment import StepContext, StepTerms
from ibm.solvers.linear import active_dofs, solve_system

ON_LINE = 1e-9


def wall_nodes(grid, point: np.ndarray, normal: np.ndarray, edge: int) -> tuple[np.ndarray, int]:
    """Nodes on the line (3D: plane) through `point` with normal `normal`, which must be a grid line
    (plane), and the normal's axis."""
    axis = int(np.argmax(np.abs(normal)))
    coordinate = point[axis]
    if abs(abs(normal[axis]) - 1) > 1e-12 or abs(coordinate / grid.h - np.round(coordinate / grid.h)) > ON_LINE:
        where = (lambda v: "(" + ", ".join(f"{c:.6g}" for c in v) + ")")
        what, on = ("edge", "line") if grid.dim == 2 else ("face", "plane")
        hint = ("an angle of 0, 90, 180 or 270 degrees" if grid.dim == 2 else
                "angle 0, 90, 180 or 270 with tilt 0, 90, 180 or 270")
        raise InputError(f"method 'nodal' needs every essential {what} on a grid {on}; {what} {edge} (normal "
                         f"{where(normal)}, through {where(point)}) is not; use {hint} and an offset putting "
                         f"the {what}s on grid {on}s")
    return np.flatnonzero(np.abs(grid.nodes()[:, axis] - coordinate) <= ON_LINE * grid.h), axis


def piece_nodes(body, grid, lines: dict[int, np.ndarray]) -> dict[int, np.ndarray]:
    """The constrained nodes each essential piece k answers for: of the nodes on its line (lines[k]),
    those whose foot on the line lies nearest to k's stretch among the pieces on that line (ties to
    each), so the nodes past a piece's end count to it."""
    x = grid.nodes()

    def gap(j, nodes):          # distance along the line from the nodes' feet to piece j's stretch
        t = (x[nodes] - body.starts[j]) @ body.tangents[j] / body.lengths[j]
        return np.maximum(np.maximum(-t, t - body.lengths[j]), 0.0)

    result = {}
    for k, nodes in lines.items():
        same = [j for j, other in lines.items() if np.array_equal(other, nodes)]        # the pieces on k's line
        gaps = np.stack([gap(j, nodes) for j in same])                                  # (n_same, n_nodes)
        result[k] = nodes[gaps[same.index(k)] <= gaps.min(axis=0) + ON_LINE * grid.h]
    return result


def solve_nodal(model: Model, estimate_condition: bool = True) -> Solution:
    start = perf_counter()
    body, grid = model.body, model.grid
    for k in body.essential_edges:
        if body.arcs and body.arcs[k] is not None:
            raise InputError(f"method 'nodal' constrains the grid nodes on straight essential edges along grid lines; "
                             f"piece {k} is an essential ({body.kinds[k]}) arc, which no grid line holds: "
                             "use penalty, nitsche, lagrange, ibm-limit or ibm")
    d = grid.dim
    fixed, on_piece = [], {}
    for k in body.essential_edges:       # before assembling: an edge off the grid is refused at once
        point = body.starts[k] if d == 2 else body.faces[k][0]
        nodes, axis = wall_nodes(grid, point, body.normals[k], k)
        fixed += [d * nodes + c for c in ([axis] if body.kinds[k] == "roller" else range(d))]
        on_piece[k] = nodes
    bulk = bulk_system(model)
    dofs = active_dofs(grid, bulk.points.cells)
    free = np.setdiff1d(dofs, np.concatenate(fixed))
    assembled = perf_counter()
    U = np.zeros(d * grid.n_nodes)
    U[free], info = solve_system(bulk.K[free][:, free], bulk.f[free], estimate_condition)
    info.update(ndof=len(free), time_assemble=assembled - start, time_solve=perf_counter() - assembled)
    if d == 3:       # the reactions' corner sharing (piece_reactions) is written for edges
        return grid_solution(model, U, info, start)
    residual = (bulk.K @ U - bulk.f).reshape(-1, 2)                        # (n_nodes, 2)
    on_piece = piece_nodes(body, grid, on_piece)
    normals = {k: np.broadcast_to(-body.normals[k], (len(nodes), 2)) for k, nodes in on_piece.items()}
    return grid_solution(model, U, info, start,
                         reactions=piece_reactions(dict(enumerate(body.kinds)), on_piece, normals, residual))


@dataclass(frozen=True)
class Nodal:
    """Nodes on a wall line get the wall's motion: its normal component (roller) or both (fixed);
    nodes with less than support_threshold of a cell's support are tied (none by default, as AMPLE)."""

    support_threshold: float = 0.0

    def step(self, context: StepContext) -> StepTerms:
        body, d = context.body, context.grid.dim
        dofs, values = [], []
        for wall, edge in enumerate(body.essential_edges):
            nodes, axis = wall_nodes(context.grid, context.lines.points[wall], context.lines.normals[wall], edge)
            g = context.wall_vector(wall)
            for c in ([axis] if body.kinds[edge] == "roller" else range(d)):
                dofs.append(d * nodes + c)
                values.append(np.full(len(nodes), g[c]))
        dofs, first = np.unique(np.concatenate(dofs), return_index=True)
        return StepTerms(fixed=(dofs, np.concatenate(values)[first]), support_threshold=self.support_threshold,
                         info={"n_fixed": len(dofs)})


class NodalMethod(BoundaryMethod):
    name = "nodal"
    summary = "strong constraints on the grid nodes of essential edges (edges on grid lines only)"
    parameters = ()
    supports = Supports({
        "arcs": "it constrains the grid nodes on straight essential edges along grid lines, and no grid line holds "
                "an arc (use penalty, nitsche, lagrange, ibm-limit or ibm)",
        "off-grid": "it constrains the grid nodes on each wall, so every wall must lie on a grid line"})

    def solve(self, model):
        return solve_nodal(model)

    def treatment(self, support_threshold=0.0):
        return Nodal(support_threshold)

    def reactions(self, model, solution):
        return residual_reactions(solution)


NODAL = NodalMethod()
