"""penalty-particles: the penalty imposed at boundary particles, a method of ibm-mpm from another package.

Boundary particles are placed along each essential edge, `particles_per_cell` per cell length,
evenly (the midpoints of equal parts), each carrying its share of the edge's length as weight, the
way boundary particles impose non-conforming conditions in Kratos MPM and in Chandra et al. (2021).
The penalty acts at the particles:

    K = K_bulk + beta sum_q w_q N(x_q)^T P N(x_q),   beta = beta0 M / h,   P = n n (roller) or I (fixed)

With u = u^h + u^a the penalised quantity is P u^h (the lift carries the essential data), as in
`penalty`, whose Gauss points per piece between grid lines integrate the same term exactly; here
the particles' even spacing does not follow the grid lines, so the term carries a quadrature error
as well as the penalty's O(1/beta0).

In the load steps the particles lie on each wall's stretch of the current outline, whose vertices
move with the material, so they slide along the wall with it: f = beta sum_q w_q P(dw(x_q) - g).

Registered through the entry point in this package's pyproject.toml; `pip install examples/plugin`
makes `ibm-study solve --method penalty-particles` and `methods = ["penalty-particles"]` in a study
spec work, with no change to ibm-mpm.
"""
from __future__ import annotations

from dataclasses import dataclass
from time import perf_counter

import numpy as np
import scipy.sparse as sp

from baselines.boundary import bulk_system, grid_solution, solve_weak
from baselines.wall_points import WallPoints, penalty_wall, points_on_walls
from ibm.boundary_method import BoundaryMethod, Parameter, Supports
from ibm.exceptions import InputError
from ibm.large.treatment import SUPPORT_THRESHOLD, StepContext, StepTerms

BETA0 = Parameter("beta0", 1e6, "penalty factor: beta = beta0 M / h", label="penalty factor β₀", symbol="β₀",
                  log_scale=True)
DENSITY = Parameter("particles_per_cell", 2.0, "boundary particles per cell length along each essential edge",
                    high=64.0, label="particles per cell", symbol="n_b")
SUPPORT = Parameter("support_threshold", 1e-4, "nodes with less than this fraction of a cell's support are tied "
                    "to a well-supported neighbour; 0 ties none", high=0.5, low_inclusive=True,
                    label="support threshold", symbol="s", load_step_default=SUPPORT_THRESHOLD)


def particles(body, grid, edge: int, per_cell: float):
    """Boundary particles on straight edge `edge`: positions (m, 2), weights (m,) and cells (m,), the
    cells taken on the body's side of the edge."""
    if body.arcs and body.arcs[edge] is not None:
        raise InputError(f"method 'penalty-particles' places its particles on straight edges; piece {edge} is an arc")
    length = body.lengths[edge]
    m = max(1, int(np.ceil(length / grid.h * per_cell)))
    t = (np.arange(m) + 0.5) / m
    x = body.starts[edge] + t[:, None] * (body.ends[edge] - body.starts[edge])
    return x, np.full(m, length / m), grid.locate_towards(x, body.normals[edge])


def particle_points(body, grid, per_cell: float, wall_vector=None) -> WallPoints:
    """The particles of every essential edge as wall points (baselines.wall_points.points_on_walls)."""
    return points_on_walls(body, grid, lambda edge: particles(body, grid, edge, per_cell), wall_vector)


@dataclass(frozen=True)
class ParticlePenalty:
    """The walls in a load step: the penalty at particles on wall ∩ current outline."""

    beta0: float = BETA0.default
    particles_per_cell: float = DENSITY.default
    support_threshold: float = SUPPORT_THRESHOLD

    def step(self, context: StepContext) -> StepTerms:
        points = particle_points(context.body, context.grid, self.particles_per_cell, context.wall_vector)
        beta = self.beta0 * context.material.M / context.grid.h
        wall, _, _ = penalty_wall(points, beta)
        return StepTerms(wall=wall, cells=points.cells, support_threshold=self.support_threshold,
                         info={"beta": beta, "n_particles": len(points.x)})


class PenaltyParticles(BoundaryMethod):
    name = "penalty-particles"
    summary = "penalty at boundary particles moving with the material (as Kratos MPM), beta = beta0 M / h"
    parameters = (BETA0, DENSITY, SUPPORT)
    supports = Supports({"3d": "its particles are placed along 2D edges",
                         "load-steps-3d": "its particles are placed along 2D edges",
                         "arcs": "it places its particles on straight edges"})

    def solve(self, model, beta0=BETA0.default, particles_per_cell=DENSITY.default, support_threshold=1e-4):
        start = perf_counter()
        bulk = bulk_system(model)
        points = particle_points(model.body, model.grid, particles_per_cell)
        beta = beta0 * model.material.M / model.grid.h
        _, K_wall, _ = penalty_wall(points, beta)
        U, info = solve_weak(model, bulk, sp.csr_matrix(bulk.K + K_wall), bulk.f, start, support_threshold)
        info.update(beta=beta, n_particles=len(points.x), particles_per_cell=particles_per_cell)
        return grid_solution(model, U, info, start)

    def treatment(self, beta0=BETA0.default, particles_per_cell=DENSITY.default, support_threshold=SUPPORT_THRESHOLD):
        return ParticlePenalty(beta0, particles_per_cell, support_threshold)

    def reactions(self, model, solution):
        """F_e = -beta sum_q w_q P u^h(x_q) over the edge's particles."""
        grid, body = model.grid, model.body
        beta = solution.info["beta"]
        result = {}
        for edge in body.essential_edges:
            x, weight, cells = particles(body, grid, edge, solution.info["particles_per_cell"])
            N, _ = grid.shape_functions(x, cells)
            u_h = np.einsum("pI,pIa->pa", N, solution.nodal[grid.cell_dofs(cells)].reshape(len(x), -1, 2))
            n = -body.normals[edge]
            violation = (u_h @ n)[:, None] * n if body.kinds[edge] == "roller" else u_h
            result[edge] = -beta * weight @ violation
        return result


PENALTY_PARTICLES = PenaltyParticles()
