"""Boundary-integral penalty: its small-strain solve, its walls in the load steps and its
reactions, with its declaration (PENALTY).

    K = K_bulk + beta int_Gamma (n.u)(n.v)   (rollers; u.v on fixed edges),  beta = beta0 M / h
    (n the outward normal at each point: constant on a straight edge, radial on an arc)

With u = u^h + u^a the penalised quantity n.u - u_n = n.u^h, so the essential data need no
extra load. The error is O(1/beta0) even for a linear solution; the condition number grows
like beta0. In the load steps: f = beta int P(dw - g) . v, a constant tangent; on a contact wall the
penalty-regularised contact law with beta_n = beta_t = beta (baselines.contact_walls).
"""
from __future__ import annotations

from dataclasses import dataclass
from time import perf_counter

import numpy as np

from baselines.boundary import bulk_system, edge_asm, grid_solution, mass_form, solve_weak
from baselines.contact_walls import History, PenaltyContact, with_other_walls
from baselines.edge_reactions import edge_fields, needs, resultant, violation
from baselines.wall_points import penalty_wall, wall_points
from ibm.boundary_method import BoundaryMethod, Parameter, Supports
from ibm.implicit_boundary import SUPPORT
from ibm.small.model import Model, Solution
from ibm.large.treatment import SUPPORT_THRESHOLD, StepContext, StepTerms

# The error is 2.05 / beta0 on the seed cases, so 1e6 puts err_u near 2e-7, level with the IBM at
# its default band width, with an equilibrated condition estimate of 3e7-3e8 (the beta0 sweep of docs/methods-compared.md).
DEFAULT_BETA0 = 1e6


def solve_penalty(model: Model, beta0: float = DEFAULT_BETA0, support_threshold: float = 1e-4,
                  estimate_condition: bool = True) -> Solution:
    start = perf_counter()
    bulk = bulk_system(model)
    beta = beta0 * model.material.M / model.grid.h
    K = bulk.K
    for edge in bulk.edges:
        K = K + beta * edge_asm(mass_form(edge.kind), model, edge)
    U, info = solve_weak(model, bulk, K, bulk.f, start, support_threshold, estimate_condition)
    info.update(beta=beta)
    return grid_solution(model, U, info, start)


@dataclass(frozen=True)
class Penalty:
    """The penalty in the load steps: f = beta int P(dw - g) . v, beta = beta0 M / h."""

    beta0: float = DEFAULT_BETA0
    support_threshold: float = SUPPORT_THRESHOLD

    vector_walls = True       # walls translate by any vector
    contact = True            # contact walls: the penalty-regularised law (baselines.contact_walls)

    def step(self, context: StepContext) -> StepTerms:
        points = wall_points(context)
        beta = self.beta0 * context.material.M / context.grid.h
        if not context.contact:
            wall, _, _ = penalty_wall(points, beta)
            return StepTerms(wall=wall, cells=points.cells, support_threshold=self.support_threshold,
                             info={"beta": beta})
        contact = PenaltyContact(History.of(context, points), beta, beta)
        rest = points.subset(~np.isin(points.wall, np.unique(contact.points.wall)))
        others = penalty_wall(rest, beta)[0] if len(rest.x) else None
        return StepTerms(wall=with_other_walls(contact, others), cells=points.cells, symmetric=False,
                         support_threshold=self.support_threshold,
                         info={"beta": beta}, accept=contact.accept, line_search=True)


def penalty_reactions(model: Model, solution: Solution) -> dict:
    """F_e = -beta int_e (n.u^h) n ds (roller), -beta int_e u^h ds (fixed)."""
    beta = needs(solution, "beta", "penalty")
    return {edge.edge: -beta * resultant(edge, violation(edge, u_h))
            for edge, u_h, _, _, _ in edge_fields(model, solution, "penalty")}


class PenaltyMethod(BoundaryMethod):
    name = "penalty"
    summary = "boundary-integral penalty, beta = beta0 M / h"
    parameters = (Parameter("beta0", DEFAULT_BETA0, "penalty factor: beta = beta0 M / h", label="penalty factor β₀",
                            symbol="β₀", log_scale=True), SUPPORT)
    supports = Supports(granted=("contact",))

    def solve(self, model, beta0=DEFAULT_BETA0, support_threshold=1e-4):
        return solve_penalty(model, beta0, support_threshold)

    def treatment(self, beta0=DEFAULT_BETA0, support_threshold=SUPPORT_THRESHOLD):
        return Penalty(beta0, support_threshold)

    def reactions(self, model, solution):
        return penalty_reactions(model, solution)


PENALTY = PenaltyMethod()
