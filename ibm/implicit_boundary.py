"""The implicit boundary method, band form: its small-strain solve, its walls in the load steps
and its reactions, with its declaration (IMPLICIT_BOUNDARY).

    u = D u^h + u^a,   v = D v^h
    K = sum_p B_p^T C B_p V_p  +  int_bands (B~^T C B~ - B^T C B) dOmega
    f = (body force, lift and traction loads, split the same way)
"""
from __future__ import annotations

from dataclasses import dataclass
from time import perf_counter

import numpy as np

from ibm import dirichlet
from ibm.small import forms
from ibm.quadrature.bands import band_quadrature, edge_quadrature
from ibm.boundary_method import BoundaryMethod, Parameter, Supports
from ibm.exceptions import InputError
from ibm.small.model import Model, Solution
from ibm.solvers.rigid_modes import require_constrained
from ibm.solvers.linear import active_dofs, solve_system
from ibm.discretise.support import extension
from ibm.large.treatment import BAND_KINEMATICS, SUPPORT_THRESHOLD, StepContext, StepTerms
from ibm.large.walls import wall_lift, wall_predictor


def solve_ibm(model: Model, delta_rel: float = 1e-5, support_threshold: float = 1e-4,
              estimate_condition: bool = True) -> Solution:
    """Solve with Dirichlet functions of band width delta = delta_rel * h.

    Nodes whose support fraction int_Omega N_I / h^d is below `support_threshold` are
    extended from a well-supported neighbour cell (ibm.discretise.support); 0 switches that off.
    """
    start = perf_counter()
    grid, body = model.grid, model.body
    delta = delta_rel * grid.h

    def D(x, region=None):
        return dirichlet.matrix(body, x, delta, region=region)

    points, band = model.points.quadrature(), band_quadrature(body, grid, delta)
    edges = {k: edge_quadrature(body, grid, k, delta) for k in model.loads.tractions}

    def with_band(form):   # material-point form plus the exact band correction
        return form(model, points) + form(model, band, D) - form(model, band)

    K = forms.corrected_stiffness(model, points, band, D, assemble=False)   # = with_band(forms.stiffness)
    f = with_band(forms.body_force) + with_band(forms.lift_force) + forms.traction_force(model, edges, D)
    assembled = perf_counter()

    dofs = active_dofs(grid, points.cells, band.cells)
    tie = extension(grid, model.points, dofs, support_threshold)
    K, f = tie.reduce(K, f, dofs)   # CSR of the final unknowns, straight from K's slots
    # the extension reproduces linear fields, so rigid modes of the reduced system are exact
    require_constrained(K, grid, dofs[tie.kept])
    U = np.zeros(grid.dim * grid.n_nodes)
    kept_dofs = dofs[tie.kept]                                             # (x, y) pairs of the kept nodes
    kept, info = solve_system(K, f, estimate_condition, symmetric=True,  # T^T K T of a symmetric form
                              positions=grid.nodes()[kept_dofs[0::grid.dim] // grid.dim])
    U[dofs] = tie.T @ kept
    solved = perf_counter()

    evaluate = forms.field_evaluator(model, U, D)
    u, sigma, sigma_zz = evaluate(model.points.x, model.points.cells)
    info.update(ndof=len(tie.kept), n_extended=len(tie.extended), min_support=tie.min_support,
                n_band_points=len(band), delta=delta,
                time_assemble=assembled - start, time_solve=solved - assembled,
                time_s=perf_counter() - start)
    return Solution(u, sigma, sigma_zz, evaluate, info, nodal=U)


@dataclass(frozen=True)
class ImplicitBoundary:
    """The seed's implicit boundary method in the loop: Dirichlet functions of the walls at the
    step start (band width delta = delta_rel h), a lift carrying the walls' motion, and the band
    correction integrated exactly on band ∩ current body.

    band: the band points' response, "finite" (the model's own at the trial dF) or "linearised"
    (the covering point's step-start response to first order in the increment: affine band forces,
    a constant band tangent; ibm.large.newton.point_sets); "auto": linearised in 3D, finite in 2D. At
    finite strain grad D du ~ du_n / delta, du_n the plain field's normal trace on a wall: a band
    point folds once du_n < -delta / 2, so a thin band wants the linearised response when the first
    iterates' traces exceed that (the 3D column's do at the walls' edges).
    """

    delta_rel: float = 1e-5
    support_threshold: float = SUPPORT_THRESHOLD
    band: str = "auto"

    def __post_init__(self):
        if self.band not in BAND_KINEMATICS:
            raise ValueError(f"band {self.band!r} is not allowed; allowed: {', '.join(BAND_KINEMATICS)}")

    def step(self, context: StepContext) -> StepTerms:
        kinematics = self.band if self.band != "auto" else ("linearised" if context.grid.dim == 3 else "finite")
        body, delta = context.body, self.delta_rel * context.grid.h
        band = band_quadrature(body, context.grid, delta)

        def D(x, region=None):
            return dirichlet.matrix(body, x, delta, region=region)

        return StepTerms(dirichlet=D, lift=wall_lift(body, context.increments, delta), band=band,
                         predictor=wall_predictor(body, context.grid, context.increments),
                         support_threshold=self.support_threshold, band_kinematics=kinematics,
                         info={"delta": delta, "n_band_points": len(band)})


# --- reactions ------------------------------------------------------------------------------------

def band_reactions(model: Model, solution: Solution) -> dict[int, np.ndarray]:
    """F_e . c = a(u, w) - l(w) with w = (D_(-e) - D) c, D_(-e) the product of the walls' Dirichlet
    functions without wall e's. D_(-e) c is free on wall e and meets the other walls' constraints;
    D c is a test field of the method, whose residual vanishes, so w may replace D_(-e) c. w is zero
    outside wall e's band and its material-point part c - c is zero, so only the exact band
    quadrature sees it:
        F_e . c = int_band [sigma(u) : grad w - b.w] dOmega - int_Gamma_t t.w ds.
    Away from other bands w = (1 - D(phi)) n (n.c) on a roller ((1 - D(phi)) c on a fixed wall), so
    F_e . c = int_band D'(phi) n.sigma n (n.c) dOmega: the band's D'-weighted mean of the normal
    stress, not the stress at the wall. Where a fixed wall's band overlaps another's,
    (I - D_a)(I - D_b) c counts to neither (an O(delta) gap in the balance; zero where rollers meet
    at right angles). On a wall of several pieces, each band point counts to the piece its foot on
    the wall lies on."""
    body, grid = model.body, model.grid
    if "delta" not in solution.info:
        raise InputError("the solution carries no 'delta': reactions by 'ibm' need a solution of 'ibm'")
    delta = solution.info["delta"]
    band = band_quadrature(body, grid, delta)
    _, sigma, _ = solution.evaluate(band.x, band.cells)                           # sigma(D u^h + u^a)
    D, grad_D = dirichlet.matrix(body, band.x, delta)                              # (n, 2, 2), (n, 2, 2, 2)
    force = np.zeros((len(band), 2)) if model.loads.body_force is None else model.loads.body_force(band.x)
    loaded = [edge_quadrature(body, grid, k, delta) for k in model.loads.tractions]
    tractions = [(qp, model.loads.tractions[k](qp.x), dirichlet.matrix(body, qp.x, delta)[0])
                 for k, qp in zip(model.loads.tractions, loaded)]
    result = {}
    for w, wall in enumerate(body.walls):
        D_w, grad_w = dirichlet.matrix(body, band.x, delta, leave_out=w)
        # w_a = (D_w - D) e_a: grad w_a [p, i, j] = (grad_w - grad_D)[p, i, a, j]
        density = (np.einsum("pij,piaj->pa", sigma, grad_w - grad_D)
                   - np.einsum("pi,pia->pa", force, D_w - D)) * band.weight[:, None]       # (n, 2)
        share = [(band.x, density)]
        for qp, t, D_t in tractions:
            D_tw = dirichlet.matrix(body, qp.x, delta, leave_out=w)[0]
            share.append((qp.x, -np.einsum("pi,pia->pa", t, D_tw - D_t) * qp.weight[:, None]))
        for x, values in share:
            piece = _piece_of(body, wall, x)
            for k in wall.pieces:
                result[k] = result.get(k, np.zeros(2)) + values[piece == k].sum(axis=0)
    return result


def _piece_of(body, wall, x: np.ndarray) -> np.ndarray:
    """The piece (n,) of `wall` whose stretch of the wall the foot of each point x (n, 2) lies on."""
    if len(wall.pieces) == 1:
        return np.full(len(x), wall.pieces[0])
    _, t = wall.local(x)
    ends = np.cumsum([body.lengths[k] for k in wall.pieces])[:-1]
    return np.asarray(wall.pieces)[np.searchsorted(ends, t)]


# --- the declaration ------------------------------------------------------------------------------

DEFAULT_DELTA_REL = 1e-5
DELTA_REL = Parameter("delta_rel", DEFAULT_DELTA_REL, "band width delta / h of the Dirichlet functions",
                      high=1.0, label="band width δ/h", symbol="δ/h", log_scale=True)
SUPPORT = Parameter("support_threshold", 1e-4, "nodes with less than this fraction of a cell's support are tied "
                    "to a well-supported neighbour (ibm.discretise.support); 0 ties none", high=0.5, low_inclusive=True,
                    label="support threshold", symbol="s", load_step_default=SUPPORT_THRESHOLD)


class ImplicitBoundaryMethod(BoundaryMethod):
    name = "ibm"
    summary = "implicit boundary method, band form (Dirichlet functions in a band of width delta)"
    parameters = (DELTA_REL, SUPPORT)
    supports = Supports(band_kinematics=True)

    def solve(self, model, delta_rel=DEFAULT_DELTA_REL, support_threshold=1e-4, estimate_condition=None):
        if estimate_condition is None:       # the condition estimate is a 2D diagnostic
            estimate_condition = model.grid.dim == 2
        return solve_ibm(model, delta_rel, support_threshold, estimate_condition)

    def treatment(self, delta_rel=DEFAULT_DELTA_REL, support_threshold=SUPPORT_THRESHOLD, band="auto"):
        return ImplicitBoundary(delta_rel, support_threshold, band)

    def reactions(self, model, solution):
        return band_reactions(model, solution)


IMPLICIT_BOUNDARY = ImplicitBoundaryMethod()
