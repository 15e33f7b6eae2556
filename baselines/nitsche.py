"""Symmetric Nitsche method, rollers and fixed edges: its small-strain solve, its walls in the load
steps and its reactions, with its declaration (NITSCHE).

    K = K_bulk - int_Gamma [(n.v)(n.sigma(u) n) + (n.u)(n.sigma(v) n)] + (gamma M / h) int_Gamma (n.u)(n.v)
    (fixed edges: v.sigma(u) n, u.sigma(v) n and u.v), n outward at each point (radial on an arc).

With u = u^h + u^a the essential data enter as the load int (n.v)(n.sigma(u^a) n). The method
is consistent, so it reproduces a linear solution to round-off - but only when gamma beats the
cut-dependent inverse constant. When it does not, the matrix is indefinite (or, near the
threshold, nearly singular); we check both and refuse to return a number.
"""
from __future__ import annotations

from dataclasses import dataclass
from time import perf_counter

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from baselines.boundary import (bulk_system, consistency_form, consistency_load, edge_asm, edge_basis,
                                grid_solution, mass_form, solve_weak, symmetric)
from baselines.contact_walls import History, NitscheContact, with_other_walls
from baselines.edge_reactions import edge_fields, needs, resultant, stress
from baselines.wall_points import penalty_wall, wall_points
from ibm.boundary_method import BoundaryMethod, Parameter, Supports
from ibm.implicit_boundary import SUPPORT
from ibm.large.kinematics import gradient_operator, increment, is_small, planar
from ibm.small.model import Model, Solution
from ibm.large.treatment import SUPPORT_THRESHOLD, StepContext, StepTerms
from ibm.solvers.linear import equilibrate
from ibm.exceptions import SolveError

# Twice the largest gamma a positive definite matrix needed over the confined block's angles and
# placements (the gamma sweep of docs/methods-compared.md), with a condition estimate far below the penalty's.
DEFAULT_GAMMA = 1e3
# Largest condition estimate of the equilibrated matrix we accept as "not near-singular".
COND_LIMIT = 1e13


def negative_pivots(A: sp.spmatrix) -> int:
    """Number of negative eigenvalues of symmetric A, from the pivots of an LDL^T-like
    factorization (symmetric ordering, diagonal pivots: Sylvester's law of inertia).

    Returns -1 when the factorization had to pivot off the diagonal (inertia unknown).
    """
    scale = equilibrate(A)
    S = sp.diags(scale)
    As = sp.csc_matrix(S @ A @ S)
    try:
        lu = spla.splu(As, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:
        return 1   # an exactly zero pivot: singular, reported like an indefinite matrix
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return -1
    return int(np.sum(lu.U.diagonal() < 0))


def solve_nitsche(model: Model, gamma: float = DEFAULT_GAMMA, support_threshold: float = 1e-4,
                  estimate_condition: bool = True) -> Solution:
    start = perf_counter()
    bulk = bulk_system(model)
    lam, mu, M = model.material.lam, model.material.mu, model.material.M
    K, f = bulk.K, bulk.f.copy()
    for edge in bulk.edges:
        basis = edge_basis(model, edge)
        K = (K - symmetric(edge_asm(consistency_form(edge.kind, lam, mu), model, edge, basis))
             + gamma * M / model.grid.h * edge_asm(mass_form(edge.kind), model, edge, basis))
        f += consistency_load(model, edge)

    def check(A, info):
        # the solve tried Cholesky first: it stands only on a positive definite matrix (PARDISO meets no
        # non-positive pivot, SuperLU keeps symmetric pivots with a positive diagonal), so a refused
        # one is counted, for the message, and no positive definite matrix is factorized twice
        if info["structure"] == "spd":
            return
        negative = negative_pivots(A)
        what = f"{negative} negative eigenvalues" if negative > 0 else "indefinite pivots"
        raise SolveError(f"Nitsche matrix is not positive definite ({what}): gamma={gamma:g} is below "
                         "the inverse constant of the smallest cut; raise --gamma")

    U, info = solve_weak(model, bulk, K, f, start, support_threshold, True, check)
    if info["cond_est"] > COND_LIMIT:
        raise SolveError(f"Nitsche matrix is nearly singular (condition estimate {info['cond_est']:.3g} > "
                         f"{COND_LIMIT:.0e}): gamma={gamma:g} is close to the inverse constant of the "
                         "smallest cut; raise --gamma")
    info.update(gamma=gamma)
    return grid_solution(model, U, info, start)


def material_traction(model, G: np.ndarray, state, n: np.ndarray):
    """dU_local (m, k d) -> (the nominal traction P n (m, d), its derivative (m, d, k d)) at wall points with
    gradient operators G (m, d d, k d), the covering points' state and outward normals n (m, d); P the first
    Piola stress of the step from `state` (sigma on the initial configuration at small strain)."""
    m, d = n.shape

    def traction(local):
        dF = increment(G, local)
        response = model.update(dF, state, dim=d)
        if is_small(model):          # on the initial configuration: P = sigma, dP = a
            J, inverse = np.ones(m), np.broadcast_to(np.eye(d), (m, d, d))
        else:
            J, inverse = np.linalg.det(dF[:, :d, :d]), np.linalg.inv(dF[:, :d, :d])
        first_piola = J[:, None, None] * response.sigma[:, :d, :d] @ inverse.transpose(0, 2, 1)
        # dP_imkn = J inverse_mj a_ijkl inverse_nl; its traction n_m dP_imkn, contracted in two steps
        a = response.tangent[:, :d, :d, :d, :d]
        v = J[:, None] * np.einsum("qm,qmj->qj", n, inverse)
        dT = np.matmul(np.einsum("qj,qijkl->qikl", v, a), inverse.transpose(0, 2, 1)[:, None])   # (m, d, d, d)
        return np.einsum("qij,qj->qi", first_piola, n), np.matmul(dT.reshape(m, d, d * d), G)
    return traction


@dataclass(frozen=True)
class Nitsche:
    """Nitsche in the load steps: f = -int P(Pi n) . v - int P(dw - g) . (A_n : grad v) n
    + (gamma M / h) int P(dw - g) . v, Pi the first Piola stress of the step from the covering point's
    state, A_n the spatial tangent at the step start (frozen, so the symmetric term stays bilinear and
    vanishes wherever dw = g); the exact linearisation of the first term makes the tangent unsymmetric.
    On a contact wall, Chouly, Hild and Renard's contact and friction with the same gamma M / h
    (baselines.contact_walls; theta 1: symmetric)."""

    gamma: float = DEFAULT_GAMMA
    support_threshold: float = SUPPORT_THRESHOLD
    theta: float = 1.0

    vector_walls = True       # walls translate by any vector
    contact = True            # contact walls: baselines.contact_walls.NitscheContact

    def step(self, context: StepContext) -> StepTerms:
        points = wall_points(context)
        if not context.contact:
            return StepTerms(wall=self._walls(context, points), cells=points.cells, symmetric=False,
                             support_threshold=self.support_threshold, info={"gamma": self.gamma})
        history = History.of(context, points)
        grid = context.grid
        N, dN = grid.shape_functions(history.points.x, history.points.cells)
        state = context.state.take(context.state_of(history.points.x))
        traction = material_traction(context.material, gradient_operator(N, dN), state, history.points.normal)
        contact = NitscheContact(history, self.gamma * context.material.M / grid.h, self.theta,
                                 lambda dU: traction(dU[history.points.dofs]))
        rest = points.subset(~np.isin(points.wall, np.unique(history.points.wall)))
        others = self._walls(context, rest) if len(rest.x) else None
        return StepTerms(wall=with_other_walls(contact, others), cells=points.cells, symmetric=False,
                         support_threshold=self.support_threshold,
                         info={"gamma": self.gamma}, accept=contact.accept, line_search=True)

    def _walls(self, context: StepContext, points):
        """The Dirichlet walls' dU -> (force, tangent) (the class doc)."""
        grid, model = context.grid, context.material
        N, dN = grid.shape_functions(points.x, points.cells)
        G = gradient_operator(N, dN)                                             # (m, d d, k d)
        state = context.state.take(context.state_of(points.x))
        m, d = len(points.weight), grid.dim
        A_n = planar(model.update(np.broadcast_to(np.eye(3), (m, 3, 3)).copy(), state, dim=d).tangent, d)   # (m, d d, d d)
        n = points.normal

        def traction_operator(A):    # (m, d, d d): (A : grad) n, component i = sum_J A[(i, J), .] n_J
            return np.einsum("qiJc,qJ->qic", A.reshape(m, d, d, d * d), n)

        stabilised, K3, g_load = penalty_wall(points, self.gamma * model.M / grid.h)
        PNv = np.matmul(points.projector, points.Nv) * points.weight[:, None, None]     # (m, d, k d)
        traction_n = np.matmul(traction_operator(A_n), G)                             # (m, d, k d)
        symmetric_part = -points.blocks(traction_n, PNv)                               # -int P(dw) . (A_n:grad v) n
        symmetric_load = -np.bincount(points.dofs.ravel(), np.einsum(
            "qic,qi->qc", traction_n, np.einsum("qij,qj->qi", points.projector, points.g)
            * points.weight[:, None]).ravel(), minlength=points.n_dofs)
        traction = material_traction(model, G, state, n)

        def wall(dU):
            nominal, derivative = traction(dU[points.dofs])
            force = -np.bincount(points.dofs.ravel(), np.einsum("qia,qi->qa", PNv, nominal).ravel(),
                                 minlength=points.n_dofs)
            K1 = -points.blocks(PNv, derivative)
            force += symmetric_part @ dU - symmetric_load
            stab_force, _ = stabilised(dU)
            return force + stab_force, K1 + symmetric_part + K3

        return wall


def nitsche_reactions(model: Model, solution: Solution) -> dict:
    """F_e = int_e [n.sigma(u) n - (gamma M / h) n.u^h] n ds (roller), int_e [sigma(u) n - (gamma M / h) u^h] ds
    (fixed); the symmetric term tests grad c = 0."""
    gamma = needs(solution, "gamma", "nitsche")
    stiffness = gamma * model.material.M / model.grid.h
    result = {}
    for edge, u_h, grad_h, _, grad_a in edge_fields(model, solution, "nitsche"):
        n = edge.normal
        t = np.einsum("pij,pj->pi", stress(model, grad_h + grad_a), n) - stiffness * u_h     # sigma(u) n - s u^h
        if edge.kind == "roller":
            t = np.sum(t * n, axis=1)[:, None] * n
        result[edge.edge] = resultant(edge, t)
    return result


class NitscheMethod(BoundaryMethod):
    name = "nitsche"
    summary = "symmetric Nitsche, stabilisation gamma M / h"
    parameters = (Parameter("gamma", DEFAULT_GAMMA, "Nitsche stabilisation factor: gamma M / h",
                            label="Nitsche factor γ", symbol="γ", log_scale=True), SUPPORT)
    supports = Supports(granted=("contact",))

    def solve(self, model, gamma=DEFAULT_GAMMA, support_threshold=1e-4):
        return solve_nitsche(model, gamma, support_threshold)

    def treatment(self, gamma=DEFAULT_GAMMA, support_threshold=SUPPORT_THRESHOLD):
        return Nitsche(gamma, support_threshold)

    def reactions(self, model, solution):
        return nitsche_reactions(model, solution)


NITSCHE = NitscheMethod()
