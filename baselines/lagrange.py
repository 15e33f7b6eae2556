"""Lagrange multipliers for essential edges: the stable method's small-strain solve, walls in the
load steps and reactions, with its declaration (LAGRANGE); the multiplier spaces shared with
baselines.lagrange_nodal.

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
Both solve the saddle-point system through ibm.solvers.linear.solve_system and refuse a numerically
singular one (condition estimate above COND_LIMIT).
"""
from __future__ import annotations

from dataclasses import dataclass
from time import perf_counter

import numpy as np
import scipy.sparse as sp

from baselines.boundary import (MERGE_FRACTION, EdgePoints, bulk_system, check_condition, edge_asm, grid_solution,
                                mass_form, merge_short, multiplier_system, reduction, trace_operator,
                                traction_variation)
from baselines.contact_multipliers import multiplier_terms
from baselines.edge_reactions import edge_fields, multiplier_reactions, resultant, violation
from baselines.wall_points import penalty_wall, wall_points
from ibm.boundary_method import BoundaryMethod, Parameter, Supports
from ibm.implicit_boundary import SUPPORT
from ibm.small.model import BoundaryTraction, Model, Solution
from ibm.large.treatment import SUPPORT_THRESHOLD, StepContext, StepTerms
from ibm.solvers.linear import solve_system

# One point per cell can leave zero-energy modes along the boundary that piecewise-constant
# constraints cannot see; the pointwise augmentation (augment M / h) int (n.u^h)(n.v) removes
# them, and it vanishes for the exact solution, so the method stays consistent.
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


def merged_pieces(edge: EdgePoints, h: float, fraction: float = MERGE_FRACTION) -> np.ndarray:
    """Multiplier group (m,) of each edge point: pieces shorter than fraction * h join the
    previous piece along the edge (the next one at the edge's start).

    A piece of length l in a barely cut cell gives a multiplier row nearly dependent on its
    neighbour's, and the saddle system's condition grows as h / l (1e-8 h: cond ~1e12);
    one constant over the merged piece keeps the patch test exact. In 3D the pieces are face
    pieces in cells, in the face quadrature's order, and "short" is an area below fraction h^2.
    """
    return merge_short(edge.piece, edge.points.weight, h ** (edge.normal.shape[1] - 1), fraction)


def traction_of(kind: str, normal: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """sigma n (m, 2) at points with outward normals (m, 2) from their multipliers (m, c)."""
    return -lam * normal if kind == "roller" else -lam


def saddle_solve(model: Model, bulk, K, blocks, start: float, support_threshold: float):
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
    U, multipliers, info = saddle_solve(model, bulk, K, blocks, start, support_threshold)
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


@dataclass(frozen=True)
class Lagrange:
    """Lagrange multipliers in the load steps: one constant per wall piece in a cut cell (pieces shorter
    than h/100 merged), int psi P(dw - g) = 0, with the augmentation (augment M / h) int P(dw - g) . v."""

    augment: float = DEFAULT_AUGMENT
    support_threshold: float = SUPPORT_THRESHOLD

    vector_walls = True       # walls translate by any vector
    contact = True            # contact walls: multipliers with an active set (baselines.contact_multipliers)

    def step(self, context: StepContext) -> StepTerms:
        points = wall_points(context)
        C, g, wall = self._walls(context, points)
        if context.contact:
            return multiplier_terms(context, points, (C, g, wall), points.cells,
                                    {"support_threshold": self.support_threshold})
        return StepTerms(constraints=(C, g), wall=wall, cells=points.cells,
                         support_threshold=self.support_threshold, info={"n_multipliers": C.shape[0]})

    def _walls(self, context: StepContext, points):
        """(C, g, the augmentation's wall) of the walls that are no contact walls."""
        rows, g, start, kept = [], [], 0, np.zeros(len(points.x), bool)
        for edge in points.edges:
            m = len(edge.points)
            part = slice(start, start + m)
            start += m
            if edge.edge in context.contact:
                continue
            kept[part] = True
            group = merged_pieces(edge, context.grid.h, MERGE_FRACTION)
            directions = components(edge.kind, edge.normal)                             # (m, c, d)
            c = directions.shape[1]
            values = np.einsum("mci,mia,m->mca", directions, points.Nv[part], points.weight[part])
            row = group[:, None, None] * c + np.arange(c)[None, :, None]
            n_rows = (group.max() + 1) * c
            rows.append(sp.coo_matrix((values.ravel(), (np.broadcast_to(row, values.shape).ravel(),
                                       np.broadcast_to(points.dofs[part][:, None, :], values.shape).ravel())),
                                      shape=(n_rows, points.n_dofs)))
            # C dU = g: the same rows applied to the wall's uniform displacement
            target = np.einsum("mci,mi,m->mc", directions, points.g[part], points.weight[part])
            g.append(np.bincount((group[:, None] * c + np.arange(c)).ravel(),
                                 target.ravel(), minlength=n_rows))
        C = sp.vstack(rows, format="csr") if rows else sp.csr_matrix((0, points.n_dofs))
        g = np.concatenate(g) if g else np.zeros(0)
        if self.augment <= 0 or not kept.any():
            return C, g, None
        augmented = points if kept.all() else points.subset(kept)
        return C, g, penalty_wall(augmented, self.augment * context.material.M / context.grid.h)[0]


def lagrange_reactions(model: Model, solution: Solution) -> dict:
    """F_e = -int_e [lam + a (M / h) n.u^h] n ds (roller), -int_e [lam + a (M / h) u^h] ds (fixed): the
    multipliers and the augmentation a, which vanishes where the constraint holds pointwise."""
    result = multiplier_reactions(model, solution, "lagrange")
    stiffness = solution.info.get("augment", 0.0) * model.material.M / model.grid.h
    if stiffness > 0:
        for edge, u_h, _, _, _ in edge_fields(model, solution, "lagrange"):
            result[edge.edge] = result[edge.edge] - stiffness * resultant(edge, violation(edge, u_h))
    return result


class LagrangeMethod(BoundaryMethod):
    name = "lagrange"
    summary = "Lagrange multipliers, one constant per edge piece in a cut cell (stable)"
    parameters = (Parameter("augment", DEFAULT_AUGMENT, "augmentation factor: (augment M / h) int (n.u^h)(n.v); "
                            "0 switches it off", low_inclusive=True, label="augmentation a", symbol="a"), SUPPORT)
    supports = Supports({"amg": "its saddle-point system is indefinite, which CG with multigrid cannot solve"},
                        granted=("contact",))

    def solve(self, model, augment=DEFAULT_AUGMENT, support_threshold=1e-4):
        return solve_lagrange(model, augment, support_threshold)

    def treatment(self, augment=DEFAULT_AUGMENT, support_threshold=SUPPORT_THRESHOLD):
        return Lagrange(augment, support_threshold)

    def reactions(self, model, solution):
        return lagrange_reactions(model, solution)


LAGRANGE = LagrangeMethod()
