"""Newton-Raphson for one load step, with the consistent tangent and every residual recorded.

    R(dU) = f_ext(t) - f_int(dU) - C^T lambda,   K = d f_int / d dU (+ wall terms),
    solve [T^T K T, (C T)^T; C T, 0] [dx; dlambda] = [T^T R; g - C dU],   dU += T dx,

on the active DOFs (nodes of the points' bases, the band and the wall terms), T the tiny-cell
extension (ibm.discretise.support). Prescribed DOFs enter with the first solve (its right-hand side
carries -K_free,fixed u_fixed), so the first evaluation is at the converged state of the last
step. Converged when ||T^T R|| <= tolerance * max(||f_ext||, ||f_int||) over the active DOFs
(f_int holds the wall reactions of nodal constraints), from the second evaluation on; with no
external force (a settlement) the scale is the size of the internal forces themselves,
||sum_p |f_p| ||, since weakly imposed walls leave no net reaction on the grid. A residual at its
rounding floor, ||T^T R|| <= round_off eps ||sum |terms| + |K| |dU| || (wall terms included), is
converged too: a stiff penalty or the IBM's thin band (stiffness ~ 1/delta) can put that floor
above the tolerance; such steps are counted (`at_round_off`). An update that makes det F <= 0
somewhere is halved (up to max_halvings times; counted as `newton_halvings`). NaN, det F <= 0
at the step start or after the halvings, or no convergence raise, so the driver can cut the step.
"""
from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

from ibm.discretise.locking import CellGroups, divergence, mean_dilatation
from ibm.discretise.points import MaterialPoints
from ibm.discretise.support import extension
from ibm.exceptions import NotConverged
from ibm.large.equilibrium import Blocks, PointSet, ReducedPattern, evaluate, merged, pattern_sum, split_by_columns
from ibm.large.kinematics import gradient_operator, is_small, planar
from ibm.quadrature.bands import edge_quadrature
from ibm.solvers.linear import Reuse, solve_system
from ibm.solvers.rigid_modes import require_constrained

# A Newton correction needs no more than a few digits: the next iteration corrects what the
# solve left (inexact Newton, converging while the correction's relative residual is < 1); a
# stiff penalty puts the solve's own floor near 1e-8, the IBM's thin band on a coarse inclined
# grid near 5e-6. A singular system (residual ~ 1) is still refused.
SOLVE_TOLERANCE = 1e-4
# Halvings of a Newton update the line search of a contact step may take (StepTerms.line_search).
LINE_SEARCH = 6




@dataclass(frozen=True)
class Control:
    tolerance: float = 1e-9
    max_iterations: int = 25
    max_cuts: int = 8
    round_off: float = 64.0       # the residual's floor, in units of eps * ||sum of |terms| ||
    max_halvings: int = 10        # of a Newton update that would fold a point


@dataclass(frozen=True, eq=False)
class StepSolution:
    dU: np.ndarray
    state: object
    sigma: np.ndarray
    iterations: int
    residuals: list
    info: dict


def _load(grid, x, cells, values, D=None) -> np.ndarray:
    """sum_q N_I (D^T v)_a at points x (m, d) of `cells` for vectors v (m, d) that include the weights."""
    N, _ = grid.shape_functions(x, cells)
    if D is not None:
        values = np.einsum("pia,pi->pa", D, values)
    return np.bincount(grid.cell_dofs(cells).ravel(), (N[:, :, None] * values[:, None, :]).ravel(),
                       minlength=grid.dim * grid.n_nodes)


def _dirichlet(terms, band):
    """D and grad D at band points, in their band regions if they carry them (3D moment-fitted rules)."""
    return terms.dirichlet(band.x) if band.region is None else terms.dirichlet(band.x, band.region)


def external_force(context, terms, loading, t: float, V0: np.ndarray, band_sets, outline) -> np.ndarray:
    """Body force (points and band correction), pressures and traction paths on the current traction edges
    at fraction t."""
    grid, basis = context.grid, context.basis
    b = t * np.asarray(loading.body_force, float)
    n_dofs = grid.dim * grid.n_nodes
    f = np.zeros(n_dofs)
    if np.any(b):
        f += np.bincount(basis.dofs.ravel(), (basis.S[:, :, None] * (V0[:, None] * b[None])[:, None, :]).ravel(),
                         minlength=n_dofs)
        if terms.band is not None and len(terms.band):
            band, owner = terms.band, band_sets[0]
            # body force per unit current volume: rho_0 g / J of the covering point
            J = 1.0 if is_small(context.material) else np.linalg.det(owner.state.F)
            per_volume = (band.weight / J)[:, None] * b[None]
            D = _dirichlet(terms, band)[0]
            f += _load(grid, band.x, band.cells, per_volume, D) - _load(grid, band.x, band.cells, per_volume)
    body = context.body
    delta = terms.info.get("delta")
    small = is_small(context.material)       # the body itself, not the tracked outline
    for k in range(body.n_edges):
        p = loading.pressures.get(k if small else int(outline.edge[k]))
        if not p:
            continue
        qp = edge_quadrature(body, grid, k, delta)
        traction = -t * p * body.outward(k, qp.x)                        # compressive: along the inward normal
        D = terms.dirichlet(qp.x)[0] if terms.dirichlet is not None else None
        f += _load(grid, qp.x, qp.cells, qp.weight[:, None] * traction, D)
    for edge, path in loading.traction_path.items():       # a traction vector (d,) on the whole edge
        pieces = [edge] if small else list(np.flatnonzero(outline.edge == edge))
        traction = path.at(t)
        for k in pieces:
            qp = edge_quadrature(body, grid, int(k), delta)
            D = terms.dirichlet(qp.x)[0] if terms.dirichlet is not None else None
            f += _load(grid, qp.x, qp.cells, qp.weight[:, None] * np.broadcast_to(traction, qp.x.shape), D)
    return f


def point_sets(context, terms) -> list[PointSet]:
    """The band points twice (D-kinematics with the lift, +; plain, -), then the material points (plain).

    With terms.band_kinematics "linearised" (the IBM's default in 3D, ibm.large.treatment) both band sets
    take their covering points' step-start response, linearised (ibm.large.equilibrium): the band's force
    is affine in dU within the step, so it has neither the fold barrier (det F > 0) nor Hencky's
    softening in tension (stretch > e) that a band of width delta ~ 1e-5 h meets as soon as the plain
    field's normal trace on a wall is ~ delta (corners and edges of inclined walls, the first iterates).

    With locking fbar the material points take their cell's mean dilatation (ibm.discretise.locking); the band
    correction keeps its own kinematics (its two sets differ only inside the thin band, where the
    Dirichlet functions impose the walls)."""
    grid, basis = context.grid, context.basis
    lift = terms.lift
    sets = []
    if terms.band is not None and len(terms.band):
        band = terms.band
        N, dN = grid.shape_functions(band.x, band.cells)
        D, gradD = _dirichlet(terms, band)
        state = context.state.take(context.state_of(band.x))
        lift_gradient = lift(band.x)[1] if lift is not None else None
        dofs = grid.cell_dofs(band.cells)
        blocks = Blocks.of(dofs)
        linear = None
        if terms.band_kinematics == "linearised" and not is_small(context.material):
            d = grid.dim
            start = context.material.update(np.broadcast_to(np.eye(3), (len(band), 3, 3)).copy(), state, dim=d)
            linear = (planar(start.sigma, d), planar(start.tangent, d))
        sets.append(PointSet(dofs, gradient_operator(N, dN, D, gradD), band.weight, state, lift_gradient, 1.0,
                             blocks=blocks, linear=linear))
        sets.append(PointSet(dofs, gradient_operator(N, dN), band.weight, state, None, -1.0, blocks=blocks,
                             linear=linear))
    G = gradient_operator(basis.S, basis.dS)
    groups = None
    if context.locking == "fbar":
        cells = grid.locate(context.x)
        groups = CellGroups(cells, basis.nodes, grid.cell_nodes(cells))
        if is_small(context.material):          # B-bar: linear in the nodal values
            G = mean_dilatation(G, basis.nodes, groups.cell_nodes, groups.cell_mean(divergence(G), context.volume))
            groups = None
    # material points keep one block per point (summing them first moves the round-off of nearly
    # singular systems: docs/choices.md), split by the nodes they use (a GIMP window fits the widest
    # domain), except with a locking remedy: F-bar's cell means need all the points of a cell in one
    # set, and B-bar's saddle systems keep the tangent's explicit zeros
    material = PointSet(basis.dofs, G, context.volume, context.state, fbar=groups, part=np.arange(len(context.volume)))
    return sets + ([material] if context.locking == "fbar" else split_by_columns(material))


def independent_rows(M: sp.csr_matrix, tolerance: float = 1e-10) -> np.ndarray:
    """Indices of a maximal set of linearly independent rows of M (m, n), by QR with column
    pivoting of the rows restricted to the columns they use (m is the number of wall
    multipliers: small). When the tiny-cell extension ties the nodes of a wall piece to its
    neighbour's, two pieces' constraints can act on the same reduced unknowns."""
    used = np.unique(M.indices)
    if M.shape[0] == 0 or len(used) == 0:
        return np.zeros(0, int)
    dense = M[:, used].toarray()
    # one BLAS thread: on a few hundred rows a threaded pivoted QR spends its time waiting for
    # threads (docs/choices.md)
    with threadpool_limits(limits=1, user_api="blas"):
        _, R, pivot = scipy.linalg.qr(dense.T, mode="economic", pivoting=True)
    diagonal = np.abs(np.diag(R))
    rank = int(np.sum(diagonal > tolerance * max(dense.shape) * diagonal[0]))
    return np.sort(pivot[:rank])


def active_dofs(context, terms, sets) -> np.ndarray:
    grid = context.grid
    used = np.zeros(grid.n_nodes, bool)
    basis = context.basis
    carries = (np.abs(basis.S) + np.abs(basis.dS).sum(axis=2)) > 0
    used[basis.nodes[carries]] = True
    if terms.band is not None and len(terms.band):
        used[grid.cell_nodes(terms.band.cells).ravel()] = True
    if len(terms.cells):
        used[grid.cell_nodes(np.asarray(terms.cells)).ravel()] = True
    nodes = np.flatnonzero(used)
    return (grid.dim * nodes[:, None] + np.arange(grid.dim)).ravel()


@dataclass(eq=False)
class Kept:
    """What a load step leaves the next (ibm.large.loadsteps.run keeps one over its steps): its reduced
    pattern and PARDISO's factors. A step whose points use the last step's nodes (the same triplets,
    active DOFs and sparsity of T: small strain, or material that has not crossed a cell) takes the
    pattern (rebuilt only where T's weights changed) and, for a Cholesky factorization, refactors on
    PARDISO's ordering and symbolic factorization (the same bits as a fresh analysis); otherwise the
    factors are freed before the new pattern is built."""

    solves: Reuse = field(default_factory=Reuse)
    pattern: ReducedPattern | None = None

    def step_pattern(self, sets: list[PointSet], active: np.ndarray, n_dofs: int, T: sp.csr_matrix) -> ReducedPattern:
        """This step's reduced pattern (T with sorted indices), the last step's where it stands. The factors
        are freed first where the structure changed (not held beside the new pattern) or where they are
        not Cholesky's: PARDISO's symmetric-indefinite and LU analyses scale and match on the values
        (iparm 11, 13), so carried to another step's values they pivot unlike a fresh analysis and the
        step's result would change; Cholesky's analysis is the pattern's alone."""
        last = self.pattern
        if last is None or not last.same_structure(sets, active, T):
            self.solves.free()
            last = None
        elif getattr(self.solves.factors, "structure", "spd") != "spd":
            self.solves.free()
        self.pattern = ReducedPattern.of(sets, active, n_dofs, T, last)
        return self.pattern

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.solves.free()
        self.pattern = None


def newton(context, terms, loading, t: float, V0: np.ndarray, control: Control, outline,
           check_rigid: bool = False, kept: Kept | None = None) -> StepSolution:
    """One load step's Newton-Raphson (module docstring); kept: what the last step left (Kept), or None
    (the pattern and factors are this step's own)."""
    grid = context.grid
    n_dofs = grid.dim * grid.n_nodes
    sets = point_sets(context, terms)
    symmetric = terms.symmetric and all(points.fbar is None for points in sets) and terms.multiplier_load is None
    f_ext = external_force(context, terms, loading, t, V0, sets, outline)
    active = active_dofs(context, terms, sets)
    cells = grid.locate(context.x)
    basis = context.basis
    support = np.bincount(basis.nodes.ravel(), (basis.S * context.volume[:, None]).ravel(),
                          minlength=grid.n_nodes) / grid.h ** grid.dim    # GIMP or MPM: sum_p V_p S_vp / h^d
    tie = extension(grid, MaterialPoints(context.x, context.volume, cells), active, terms.support_threshold,
                    support)
    T = tie.T.tocsc()
    dU = np.zeros(n_dofs) if terms.predictor is None else terms.predictor.copy()
    prescribed = np.zeros(n_dofs)
    if terms.fixed is not None:
        fixed, values = terms.fixed
        prescribed[fixed] = values
        is_fixed = np.isin(active, fixed)
        keep_columns = ~is_fixed[tie.kept]
        T = sp.csr_matrix(sp.diags((~is_fixed).astype(float)) @ T[:, keep_columns])
    T = sp.csr_matrix(T)
    T.sort_indices()
    pattern = kept.step_pattern(sets, active, n_dofs, T) if kept is not None else ReducedPattern.of(sets, active,
                                                                                                   n_dofs, T)
    C, g = terms.constraints if terms.constraints is not None else (None, None)
    B = terms.multiplier_load          # forces that follow the multipliers (friction on slipping pieces)
    dropped, independent = 0, None
    if C is not None:   # constraints that the reduced unknowns cannot tell apart would make the system singular
        independent = independent_rows(sp.csr_matrix(C[:, active] @ T))
        dropped = C.shape[0] - len(independent)
        C, g = C[independent], g[independent]
        if B is not None:
            B = sp.csr_matrix(B)[:, independent]
    lam = np.zeros(0 if C is None else C.shape[0])
    residuals, halvings = [], 0

    def state_at(trial):   # internal forces and wall terms at an iterate; FloatingPointError if inadmissible
        evaluation = evaluate(context.material, sets, trial)
        return evaluation, (terms.wall(trial) if terms.wall is not None else None)

    def floor_of(evaluation, wall):
        """The residual's rounding floor: the forces' own rounding and that of their dependence on
        dU (|K| |dU|; a stiff band or wall makes this the larger)."""
        magnitude = evaluation.magnitude + pattern.sensitivity(evaluation.absolute, dU)
        if wall is not None:
            magnitude = magnitude + abs(wall[1]) @ np.abs(dU) + np.abs(wall[0])
        return control.round_off * np.finfo(float).eps * np.linalg.norm(magnitude[active])

    def residual_norm(evaluation, wall, multipliers):
        """||T^T R|| at an iterate (R as in the loop below)."""
        f_int = evaluation.force + (wall[0] if wall is not None else 0.0)
        return np.linalg.norm(T.T @ (f_ext - f_int - constraint_force(multipliers))[active])

    def constraint_force(multipliers):
        """C^T lambda (+ B lambda): the constraints' force on the grid."""
        if C is None:
            return 0.0
        return C.T @ multipliers + (B @ multipliers if B is not None else 0.0)

    external = np.linalg.norm(f_ext[active])
    result, wall_terms = state_at(dU)
    searched = 0
    with nullcontext(kept.solves) if kept is not None else Reuse() as reuse:   # the pattern is fixed within a step
        reused_before = reuse.reused
        for iteration in range(control.max_iterations + 1):
            f_int = result.force
            wall_stiffness = None
            if wall_terms is not None:
                force, wall_stiffness = wall_terms
                f_int = f_int + force
            R = f_ext - f_int - constraint_force(lam)
            scale = max(external, np.linalg.norm(f_int[active])) if external > 0 else np.linalg.norm(
                result.magnitude[active])
            reduced = T.T @ R[active]
            relative = float(np.linalg.norm(reduced) / scale) if scale > 0 else float(np.linalg.norm(reduced))
            if not np.isfinite(relative):
                raise FloatingPointError(f"the residual is not finite (iteration {iteration})")
            if not np.isfinite(result.values).all():     # never hand a solver a matrix it cannot factorize
                raise FloatingPointError(f"the tangent is not finite (iteration {iteration})")
            residuals.append(relative)
            # no residual is computed more accurately than the rounding of its largest terms: a stiff
            # wall term (penalty) or the IBM's thin band can put that floor above the tolerance
            converged = relative <= control.tolerance
            stalled = iteration >= 2 and relative > 0.1 * residuals[-2]     # no longer converging: at a floor?
            if iteration >= 1 and (converged or (stalled and np.linalg.norm(reduced) <= floor_of(result, wall_terms))):
                at_floor = not converged
                break
            if iteration == 0 and np.any(prescribed):   # the prescribed increments, moved to the right-hand side
                K = sp.csr_matrix((result.values, (pattern.rows, pattern.columns)), shape=(n_dofs, n_dofs))
                K = K + (wall_stiffness if wall_stiffness is not None else 0)
                reduced = reduced - T.T @ (K[active][:, active] @ prescribed[active])
                dU += prescribed
            if iteration == control.max_iterations:
                raise NotConverged(f"relative residual {relative:.3g} after {iteration} iterations")
            A = pattern.matrix(result.values)
            if wall_stiffness is not None:
                A = pattern_sum(A, sp.csr_matrix(T.T @ sp.csr_matrix(wall_stiffness)[active][:, active] @ T))
            # a nodal method fixes the modes it removes; a body held by contact may look free at its first
            # iterate (slipping everywhere), so contact steps are not checked
            if check_rigid and iteration == 0 and C is None and terms.fixed is None and terms.accept is None:
                require_constrained(A, grid, active[tie.kept])
            correction, multipliers = np.zeros(n_dofs), np.zeros(len(lam))
            if C is None:
                step, _ = solve_system(A, reduced, estimate_condition=False, symmetric=symmetric,
                                       tolerance=SOLVE_TOLERANCE, reuse=reuse)
                correction[active] = T @ step
            else:
                Cr = sp.csr_matrix(C[:, active] @ T)
                upper = Cr.T if B is None else Cr.T + sp.csr_matrix(T.T @ B[active])
                system = sp.bmat([[A, upper], [Cr, None]], format="csr")
                rhs = np.concatenate([reduced, g - C @ dU])
                step, _ = solve_system(system, rhs, estimate_condition=False, symmetric=symmetric,
                                       tolerance=SOLVE_TOLERANCE, reuse=reuse)
                correction[active] = T @ step[:A.shape[0]]
                multipliers = step[A.shape[0]:]
            # an update that folds a point (det F <= 0) is halved until it does not: the Hencky energy
            # has a barrier there that the linearised step cannot see (a far-off iterate, a weakly
            # supported node); near the solution the full step is taken and convergence stays quadratic
            for cut in range(control.max_halvings + 1):
                alpha = 0.5 ** cut
                try:
                    result, wall_terms = state_at(dU + alpha * correction)
                    break
                except FloatingPointError:
                    if cut == control.max_halvings:
                        raise
            halvings += cut
            if terms.line_search and iteration >= 1:   # a contact's active set: damp what does not reduce R
                current = np.linalg.norm(reduced)
                for _ in range(LINE_SEARCH):
                    if residual_norm(result, wall_terms, lam + alpha * multipliers) <= (1 - 1e-4 * alpha) * current:
                        break
                    alpha /= 2
                    result, wall_terms = state_at(dU + alpha * correction)
                searched += alpha < 1
            dU = dU + alpha * correction
            lam = lam + alpha * multipliers
    material = merged(sets, result.responses, len(context.volume))
    info = {"ndof": int(T.shape[1]), "n_extended": len(tie.extended), "at_round_off": int(at_floor),
            "newton_halvings": halvings, "reused_analyses": reuse.reused - reused_before}
    if terms.line_search:
        info["line_searches"] = searched
    if C is not None:
        info["multipliers"] = lam
        info["constraint_rows"] = independent          # the rows of C the multipliers belong to
        info["dependent_constraints"] = dropped
    return StepSolution(dU, material.state, material.sigma, iteration, residuals, info)
