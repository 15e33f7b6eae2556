"""Lagrange multipliers for essential edges (method notes section 3).

    [[K, G^T], [G, 0]] [u; lambda] = [f; 0],   G = int_Gamma psi (n.N)   (rollers; psi N on fixed edges)

n the outward normal at each point (radial on an arc, so a roller arc's multiplier is a pressure).

With u = u^h + u^a the constraints on u^h are homogeneous. Two multiplier spaces:
- `lagrange` (stable): one constant per piece of an edge inside one grid cell (one per
  component on fixed edges). Tractions: sigma n = -lambda n (rollers), -lambda (fixed).
  On an arc a piece is the arc's part inside one cell (consecutive sub-arcs in that cell).
- `lagrange-nodal` (naive): point collocation where the edge crosses grid lines and at its
  vertices (a vertex belongs to the essential edge starting there). It over-constrains small
  cuts: the multiplier tractions -lambda_c / (tributary length) oscillate along the edge and
  the displacement locks. Kept only to show that failure, never a default; straight edges only.
Both solve the saddle-point system through ibm.solve.solve_system and refuse a numerically
singular one (condition estimate above COND_LIMIT).
"""
from __future__ import annotations

from time import perf_counter

import numpy as np
import scipy.sparse as sp

from baselines.boundary import (EdgePoints, bulk_system, check_condition, edge_asm, grid_solution, mass_form,
                                multiplier_system, reduction, trace_operator, traction_variation)
from ibm.exceptions import InputError
from ibm.grid import Grid
from ibm.model import BoundaryTraction, Model, Solution
from ibm.solve import solve_system

# Material-point integration with one point per cell can leave zero-energy modes of K along the
# boundary that piecewise-constant constraints cannot see (the saddle system is then singular,
# condition estimate ~1e17); nodes that share one lonely point are tied by ibm.support, and
# the pointwise augmentation (augment M / h) int (n.u^h)(n.v) guards against the rest. It
# vanishes for the exact solution (n.u^h = 0 there), so it keeps the method consistent and the
# multiplier meaning intact; augment = 1 costs nothing in conditioning.
DEFAULT_AUGMENT = 1.0
COND_LIMIT = 1e13


def components(kind: str, normal: np.ndarray) -> np.ndarray:
    """Constrained directions (m, c, d) at points with outward normals (m, d): the normal on a
    roller (c = 1), every axis on a fixed edge or face (c = d)."""
    if kind == "roller":
        return normal[:, None, :]
    d = normal.shape[1]
    return np.broadcast_to(np.eye(d), (len(normal), d, d))


def constraint_rows(model: Model, x, cells, weight, group, directions: np.ndarray, first_row: int) -> sp.coo_matrix:
    """Rows sum_{q in group g} weight_q d_q.N(x_q) for each group g and constrained direction d
    (directions (m, c, 2) at the points, from `components`)."""
    Nv, dofs = trace_operator(model, x, cells)                                    # (m, 2, 8), (m, 8)
    values = np.einsum("mci,mia,m->mca", directions, Nv, weight)                 # (m, c, 8)
    c = directions.shape[1]
    rows = first_row + group[:, None, None] * c + np.arange(c)[None, :, None]
    rows = np.broadcast_to(rows, values.shape)
    cols = np.broadcast_to(dofs[:, None, :], values.shape)
    n_rows = (group.max() + 1) * c
    return sp.coo_matrix((values.ravel(), (rows.ravel() - first_row, cols.ravel())),
                         shape=(n_rows, model.dim * model.grid.n_nodes))


MERGE_FRACTION = 1e-2


def merged_pieces(edge: EdgePoints, h: float, fraction: float = MERGE_FRACTION) -> np.ndarray:
    """Multiplier group (m,) of each edge point: pieces shorter than fraction * h join the
    previous piece along the edge (the next one at the edge's start).

    A piece of length l in a barely cut cell gives a multiplier row nearly dependent on its
    neighbour's, and the saddle system's condition grows as h / l (1e-8 h: cond ~1e12);
    one constant over the merged piece keeps the patch test exact. In 3D the pieces are face
    pieces in cells, in the face quadrature's order, and "short" is an area below fraction h^2.
    """
    length = np.bincount(edge.piece, weights=edge.points.weight)
    short = length < fraction * h ** (edge.normal.shape[1] - 1)
    if short.all():
        return np.zeros_like(edge.piece)
    index = np.where(short, -1, np.arange(len(length)))
    forward = np.maximum.accumulate(index)                       # last long piece before
    backward = np.minimum.accumulate(np.where(index < 0, len(length), index)[::-1])[::-1]
    group = np.where(forward >= 0, forward, backward)
    return np.unique(group, return_inverse=True)[1][edge.piece]


def traction_of(kind: str, normal: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """sigma n (m, 2) at points with outward normals (m, 2) from their multipliers (m, c)."""
    return -lam * normal if kind == "roller" else -lam


def _saddle_solve(model: Model, bulk, K, blocks, start: float, support_threshold: float):
    """Solve with constraint blocks G_e; return U, the multipliers of each block, info."""
    G = sp.vstack(blocks, format="csr")
    r = reduction(model, bulk, support_threshold)
    A, b = multiplier_system(K, G, bulk.f, r)
    assembled = perf_counter()
    x, info = solve_system(A, b, True)
    check_condition(info, COND_LIMIT, "multiplier")
    n = r.T.shape[1]
    U = np.zeros(model.dim * model.grid.n_nodes)
    U[r.dofs] = r.T @ x[:n]
    info.update(ndof=n, n_extended=r.n_extended, n_multipliers=G.shape[0], time_assemble=assembled - start,
                time_solve=perf_counter() - assembled)
    return U, np.split(x[n:], np.cumsum([blk.shape[0] for blk in blocks])[:-1]), info


def solve_lagrange(model: Model, augment: float = DEFAULT_AUGMENT, support_threshold: float = 1e-4,
                   estimate_condition: bool = True) -> Solution:
    """One constant multiplier per edge piece inside a cut cell, plus the consistent augmentation
    (augment M / h) int (n.u^h)(n.v) (0 switches it off)."""
    start = perf_counter()
    bulk = bulk_system(model)
    groups = [merged_pieces(e, model.grid.h) for e in bulk.edges]
    directions = [components(e.kind, e.normal) for e in bulk.edges]                 # (m, c, 2) per edge
    blocks = [constraint_rows(model, e.points.x, e.points.cells, e.points.weight, g, d, 0).tocsr()
              for e, g, d in zip(bulk.edges, groups, directions)]
    K = bulk.K
    if augment > 0:
        for e in bulk.edges:
            K = K + augment * model.material.M / model.grid.h * edge_asm(mass_form(e.kind), model, e)
    U, multipliers, info = _saddle_solve(model, bulk, K, blocks, start, support_threshold)
    info["augment"] = augment
    x, weight, edge_ids, value = [], [], [], []
    for e, g, d, lam in zip(bulk.edges, groups, directions, multipliers):
        x.append(e.points.x), weight.append(e.points.weight)
        edge_ids.append(np.full(len(e.points), e.edge))
        value.append(traction_of(e.kind, e.normal, lam.reshape(-1, d.shape[1])[g]))   # (m, 2)
    tractions = BoundaryTraction(np.concatenate(x), np.concatenate(weight), np.concatenate(edge_ids),
                                 np.concatenate(value))
    if model.dim == 2:     # along each edge; a face has no one direction to order its points by
        info["traction_variation"] = traction_variation(tractions, model.body)
    return grid_solution(model, U, info, start, tractions)


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
    U, multipliers, info = _saddle_solve(model, bulk, bulk.K, blocks, start, support_threshold)
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
