"""Body-fitted small-strain plasticity reference on any simple outline: gmsh P2 triangles, load steps.

The body is meshed as in baselines.fem.mesh (6-node triangles, isoparametric on arcs) and its
essential pieces are imposed strongly through U = T q (constraint_transform; the essential data
are zero, so there is no lift). Each Gauss point carries one material state. A load step from
t_0 to t_1 solves for the increment dU of the nodal displacement by Newton's method with the
consistent tangent of the core's kernel (ibm.large.equilibrium, which integrates a small-strain model
on the initial configuration):

    T^T (t_1 f_p - f_int(dU)) = 0,   f_int = sum_g w_g G_g^T sigma_g(state_g,n, G_g dU),

f_p the pressures' load: p > 0 compressive along the inward normal of its piece (on an arc the
circle's own, radial, normal), integrated along the curved facets by fem_mesh's facet rules.
A straight roller or fixed piece may move along its inward normal (`motions`, a settlement): its
nodes take the prescribed part of t m n in U = T q + t g (a roller's normal part, its tangential
part free; a fixed piece's both). The
force on each essential piece is the residual at its constrained DOFs, sum over its nodes of the
internal force (the reaction the supports exert is its negative).
Converged when ||T^T R|| <= tolerance * max(||f_ext||, ||f_int||) from the second evaluation
on (or at the residual's rounding floor once it stalls). A step that fails (no convergence
within MAX_ITERATIONS, a non-finite residual, a singular solve) is retried with its increment
halved, up to max_cuts times, then ibm.large.newton.StepFailure is raised.

Gauss rule: degree ORDER = 2 (3 points per triangle), exact for the elastic stiffness of a
straight P2 element (strain degree 1) and the fewest points with a full-rank element stiffness
(9 strain constraints for 12 - 3 deformation modes), so the fewest incompressibility
constraints once the plastic flow is isochoric. The degree-4 rule (6 points) of fem_mesh can be
chosen with `order`; both reach the limit load of Hill's cylinder (tests/baselines/fem/test_plastic.py).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from skfem import Basis, ElementTriP2, ElementVector, FacetBasis, LinearForm, asm
from skfem.helpers import dot

from baselines.fem.mesh import (CURVED_LOAD_ORDER, LOAD_ORDER, constraint_transform, mesh_polygon, node_dofs,
                                require_held)
from ibm.large.equilibrium import PointSet, ReducedPattern, evaluate
from ibm.geometry.outline import Body
from ibm.exceptions import InputError, NotConverged, SolveError, StepFailure
from ibm.large.kinematics import is_small
from ibm.large.newton import SOLVE_TOLERANCE
from ibm.solvers.linear import solve_system

ORDER = 2               # Gauss rule of the stiffness and the states (3 points per triangle)
MAX_ITERATIONS = 25     # Newton iterations per (sub)step
ROUND_OFF = 64.0        # the residual's floor, in units of eps * ||sum of |point forces| ||


def gauss_points(basis: Basis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """DOFs (m, 12), G (m, 4, 12) (rows du_i/dx_a, i a row-major) and weights (m,) at every Gauss
    point (m = elements x points, element-major)."""
    nel, nq = basis.dx.shape
    grads = np.stack([np.asarray(basis.basis[j][0].grad) for j in range(basis.Nbfun)], axis=-1)  # (2, 2, nel, nq, 12)
    G = grads.transpose(2, 3, 0, 1, 4).reshape(nel * nq, 4, basis.Nbfun)
    dofs = np.repeat(basis.element_dofs.T, nq, axis=0)
    return dofs, G, basis.dx.ravel()


def pressure_load(body: Body, polygon, element, pressures: dict[int, float], n_dofs: int) -> np.ndarray:
    """(n_dofs,) the load of the total pressures: traction -p n_out on each piece k (n_out the
    body's outward normal at the facet quadrature points, the circle's on an arc)."""
    mesh = polygon.mesh
    f = np.zeros(n_dofs)
    for k, p in pressures.items():
        if not (isinstance(k, (int, np.integer)) and 0 <= k < body.n_edges):
            raise InputError(f"pressure piece {k!r} is not allowed; the body has pieces 0 .. {body.n_edges - 1}")
        if k in body.essential_edges:
            raise InputError(f"piece {k} is {body.kinds[k]}; a pressure needs a natural (traction or free) piece")
        if not np.isfinite(p):
            raise InputError(f"pressure {p!r} on piece {k} is not allowed; it must be finite")
        order = CURVED_LOAD_ORDER if body.arcs and body.arcs[k] is not None else LOAD_ORDER
        facets = FacetBasis(mesh, element, facets=polygon.piece_facets[k], intorder=order)
        x = np.asarray(facets.global_coordinates())                             # (2, n_facets, n_qp)
        t = -float(p) * body.outward(k, x.reshape(2, -1).T).T.reshape(x.shape)
        f += asm(LinearForm(lambda v, w: dot(w.t, v)), facets, t=t)
    return f


def run_fem_plastic(body: Body, material, pressures: dict[int, float], h: float, steps: int,
                    tolerance: float = 1e-9, max_cuts: int = 8, after_step=None, order: int = ORDER,
                    motions: dict[int, float] | None = None) -> SimpleNamespace:
    """Ramp `pressures` (piece -> total p) in `steps` load steps on the P2 mesh of `body` (size h).

    after_step(record), after every converged step, sees {"step", "t" (load fraction), "cuts",
    "newton_iterations" (summed over the substeps), "residuals" (relative, every evaluation),
    "ndof", "nodes" (n_nodes, 2), "displacement" (n_nodes, 2), "piece_nodes" (node ids per piece),
    "forces" (piece -> (2,) internal force on its nodes, for every essential piece)}
    and may return a dict that is added to the record. Returns the polygon mesh, nodes,
    displacement, the Gauss points' state and stress (m, 3, 3), t, ndof and the step records, all
    at the last converged (sub)step; raises StepFailure when a step fails after max_cuts cuts (that
    state is on the exception's `progress`).
    """
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InputError(f"steps {steps!r} is not allowed; it must be an integer >= 1")
    if not is_small(material):
        raise InputError("the fem plasticity reference is for small-strain models (ibm.models.small_strain)")
    if order not in (2, 4):
        raise InputError(f"Gauss rule order {order!r} is not allowed; allowed: 2 (3 points), 4 (6 points)")
    polygon = mesh_polygon(body, h)
    mesh = polygon.mesh
    element = ElementVector(ElementTriP2())
    basis = Basis(mesh, element, intorder=order)
    dofs, G, weight = gauss_points(basis)
    node = node_dofs(basis)                                                    # (2, n_nodes)
    T = constraint_transform(body, polygon, node)
    require_held(T, mesh.doflocs.T, node)
    f_load = pressure_load(body, polygon, element, pressures, basis.N)
    motion = np.zeros(basis.N)                        # g: the total prescribed displacement of moving pieces
    for k, m in (motions or {}).items():
        if body.kinds[k] not in ("roller", "fixed") or (body.arcs and body.arcs[k] is not None):
            raise InputError(f"piece {k} ({body.kinds[k]}) cannot move; only straight roller and fixed pieces take a "
                             "motion")
        nodes_k = polygon.piece_nodes[k]
        for a in range(2):
            motion[node[a, nodes_k]] = float(m) * body.normals[k][a]
    external_unit = np.linalg.norm(f_load)
    state = material.initial(len(weight))
    pattern = ReducedPattern.of([PointSet(dofs, G, weight, state)], np.arange(basis.N), basis.N, T)
    U = np.zeros(basis.N)
    progress = SimpleNamespace(polygon=polygon, nodes=mesh.doflocs.T.copy(), displacement=np.zeros((node.shape[1], 2)),
                               state=state, sigma=np.zeros((len(weight), 3, 3)), t=0.0, steps=[], ndof=T.shape[1],
                               forces={})

    def substep(t1: float, state):
        """dU, the response and the residuals of the (sub)step to load fraction t1 from `state`."""
        f_ext = t1 * f_load
        dU = (t1 - progress.t) * motion
        residuals = []
        sets = [PointSet(dofs, G, weight, state)]
        for iteration in range(MAX_ITERATIONS + 1):
            result = evaluate(material, sets, dU)
            reduced = T.T @ (f_ext - result.force)
            scale = max(t1 * external_unit, np.linalg.norm(result.force))
            relative = float(np.linalg.norm(reduced) / scale) if scale > 0 else float(np.linalg.norm(reduced))
            if not np.isfinite(relative):
                raise FloatingPointError(f"the residual is not finite (iteration {iteration})")
            residuals.append(relative)
            stalled = iteration >= 2 and relative > 0.1 * residuals[-2]
            floor = ROUND_OFF * np.finfo(float).eps * np.linalg.norm(result.magnitude)
            if iteration >= 1 and (relative <= tolerance or (stalled and np.linalg.norm(reduced) <= floor)):
                return dU, result, iteration, residuals
            if iteration == MAX_ITERATIONS:
                raise NotConverged(f"relative residual {relative:.3g} after {iteration} iterations")
            # the core loop's inexact Newton tolerance: a near-singular tangent (the mechanism forming) still
            # gives a correction, the next residual judges it; a singular one raises SolveError (a cut)
            step, _ = solve_system(pattern.matrix(result.values), reduced, estimate_condition=False, symmetric=True,
                                   tolerance=SOLVE_TOLERANCE)
            dU = dU + T @ step

    for step in range(1, steps + 1):
        target, cuts, iterations, residuals = step / steps, 0, 0, []
        while progress.t < target - 1e-14:
            increment = min(target - progress.t, (1 / steps) / 2 ** cuts)
            try:
                dU, response, count, history = substep(progress.t + increment, progress.state)
            except (NotConverged, FloatingPointError, SolveError) as failure:    # singular: past a limit load
                cuts += 1
                if cuts > max_cuts:
                    error = StepFailure(f"load step {step} did not converge after {max_cuts} step cuts ({failure})")
                    error.progress = progress
                    raise error from None
                continue
            U += dU
            progress.displacement = U[node].T.copy()                            # (n_nodes, 2)
            progress.state, progress.sigma = response.responses[0].state, response.responses[0].sigma
            progress.forces = {k: np.array([response.force[node[a, polygon.piece_nodes[k]]].sum() for a in range(2)])
                               for k in body.essential_edges}
            progress.t += increment
            iterations += count
            residuals += history
        record = {"step": step, "t": progress.t, "cuts": cuts, "newton_iterations": iterations,
                  "residuals": residuals, "ndof": T.shape[1], "nodes": progress.nodes,
                  "displacement": progress.displacement, "piece_nodes": polygon.piece_nodes,
                  "forces": progress.forces}
        progress.steps.append(record)
        if after_step is not None:
            record.update(after_step(record) or {})
    return progress
