"""Body-fitted total-Lagrangian Hencky reference at finite strain (scikit-fem).

The rectangle is meshed in its local frame by Q4 elements of about the grid's cell size, so
every wall is a mesh line and rollers are strong (the top wall's settlement is a prescribed
u_eta). Each load step solves for the total displacement U on the reference configuration X:
F = I + grad_X u at 2 x 2 Gauss points, with the core's kernel (ibm.large.equilibrium) given the
undeformed state, so that dF = F and the volumes are reference volumes: f_int = int grad_X N : P,
K = its exact linearisation. Body force per reference volume; pressure on the reference top (its
length does not change in the confined block). Results at the material points' initial
positions, rotated to the grid's frame.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from skfem import Basis, ElementQuad1, ElementVector, FacetBasis, MeshQuad, LinearForm, asm
from skfem.helpers import dot

from baselines.boundary import point_basis
from ibm.large.equilibrium import PointSet, evaluate
from ibm.exceptions import InputError, StepFailure
from ibm.large.kinematics import is_small
from ibm.discretise.points import material_points
from ibm.discretise.grid import Grid
from ibm.solvers.linear import solve_system
from ibm.large.walls import Outline, WallLines


def _gradients(basis: Basis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """DOFs (m, 8), G (m, 4, 8) and weights (m,) at every Gauss point (m = elements x points)."""
    nel, nq = basis.dx.shape
    grads = np.stack([np.asarray(basis.basis[j][0].grad) for j in range(basis.Nbfun)], axis=-1)  # (2, 2, nel, nq, 8)
    G = grads.transpose(2, 3, 0, 1, 4).reshape(nel * nq, 4, basis.Nbfun)
    dofs = np.repeat(basis.element_dofs.T, nq, axis=0)
    return dofs, G, basis.dx.ravel()


def run_fem(setup, corner: np.ndarray, R: np.ndarray, after_step) -> SimpleNamespace:
    body, material = setup.body, setup.material
    local = (body.vertices - corner) @ R
    L, H = local[2]
    if body.n_edges != 4 or not np.allclose(local, [[0, 0], [L, 0], [L, H], [0, H]], atol=1e-9 * max(L, H)):
        raise InputError("the fem reference needs a rectangle in its local frame")
    nx, ny = max(1, int(np.ceil(L / setup.h - 1e-9))), max(1, int(np.ceil(H / setup.h - 1e-9)))
    mesh = MeshQuad.init_tensor(np.linspace(0, L, nx + 1), np.linspace(0, H, ny + 1))
    element = ElementVector(ElementQuad1())
    basis = Basis(mesh, element, intorder=3)
    dofs, G, weight = _gradients(basis)
    state = material.initial(len(weight))
    tol = 1e-9 * max(L, H)
    sides = (lambda x: np.abs(x[1]) < tol, lambda x: np.abs(x[0] - L) < tol,
             lambda x: np.abs(x[1] - H) < tol, lambda x: np.abs(x[0]) < tol)
    component = (1, 0, 1, 0)                     # local displacement normal to base, right, top, left
    fixed, moving = [], []
    for k in body.essential_edges:
        nodal = basis.get_dofs(mesh.facets_satisfying(sides[k])).nodal
        names = ("u^1", "u^2") if body.kinds[k] == "fixed" else (("u^1", "u^2")[component[k]],)
        fixed += [nodal[name] for name in names]
        if k == 2:
            moving.append(nodal["u^2"])
    fixed = np.unique(np.concatenate(fixed))
    moving = np.concatenate(moving) if moving else np.zeros(0, int)
    free = np.setdiff1d(np.arange(basis.N), fixed)
    b_local = R.T @ setup.loading.body_force
    f_body = asm(LinearForm(lambda v, w: dot(b_local[:, None, None] * np.ones_like(w.x), v)), basis)
    f_pressure = np.zeros(basis.N)
    if 2 in setup.loading.pressures:
        top = FacetBasis(mesh, element, facets=mesh.facets_satisfying(sides[2]), intorder=3)
        f_pressure = asm(LinearForm(lambda v, w: -setup.loading.pressures[2] * v[1]), top)
    settlement = 0.0
    if setup.loading.wall_motion is not None:
        settlement = float(setup.loading.wall_motion[body.essential_edges.index(2)]) if 2 in body.essential_edges else 0.0

    grid = Grid.covering(body, setup.h, setup.margin)
    points = material_points(body, grid, setup.ppc)
    X_local = (points.x - corner) @ R
    X_local = np.clip(X_local, 0.0, [L, H])
    spacing = np.array([L / nx, H / ny])
    ij = np.minimum(np.floor(X_local / spacing).astype(int), [nx - 1, ny - 1])
    table = np.empty((nx, ny), int)
    centre_ij = np.floor(mesh.p[:, mesh.t].mean(axis=1).T / spacing).astype(int)
    table[centre_ij[:, 0], centre_ij[:, 1]] = np.arange(mesh.nelements)
    at_points = point_basis(mesh, element, X_local, table[ij[:, 0], ij[:, 1]])
    p_dofs, p_G, _ = _gradients(at_points)
    p_N = np.stack([np.asarray(at_points.basis[j][0].value)[:, :, 0].T for j in range(at_points.Nbfun)], axis=2)
    p_state = material.initial(len(points.x))
    U = np.zeros(basis.N)
    progress = SimpleNamespace(X=points.x.copy(), V0=points.volume.copy(), x=points.x.copy(),
                               sigma=np.zeros((len(points.x), 3, 3)), t=0.0, steps=[],
                               outline=Outline.of(body), lines=WallLines.of(body))
    sets = [PointSet(dofs, G, weight, state)]
    top_nodes = np.flatnonzero(np.abs(mesh.p[1] - H) < tol)
    for step in range(1, setup.steps + 1):
        t = step / setup.steps
        U[moving] = -t * settlement
        f_ext = t * (f_body + f_pressure)
        residuals = []
        for iteration in range(26):
            result = evaluate(material, sets, U)
            r = f_ext - result.force
            scale = max(np.linalg.norm(f_ext), np.linalg.norm(result.force))
            residuals.append(float(np.linalg.norm(r[free]) / scale))
            if not np.isfinite(residuals[-1]):
                raise StepFailure(f"load step {step}: the residual is not finite")
            if iteration >= 1 and residuals[-1] <= 1e-9:
                break
            if iteration == 25:
                raise StepFailure(f"load step {step} did not converge (relative residual {residuals[-1]:.3g})")
            K = result.tangent(basis.N)
            delta, _ = solve_system(K[free][:, free], r[free], estimate_condition=False, symmetric=True)
            U[free] += delta
        # results at the material points: u, F and the Cauchy stress at X_p (rotated to the grid's frame)
        local_u = np.einsum("pia,pa->pi", p_N, U[p_dofs])
        dF = np.eye(3)[None].repeat(len(local_u), 0)
        dF[:, :2, :2] += (p_G @ U[p_dofs][:, :, None])[:, :, 0].reshape(-1, 2, 2)
        response = material.update(dF, p_state)
        progress.x = progress.X + local_u @ R.T
        rotation = np.eye(3)
        rotation[:2, :2] = R
        progress.sigma = rotation @ response.sigma @ rotation.T
        progress.t = t
        small = is_small(material)            # small strain: the configuration stays
        progress.volume = progress.V0 if small else progress.V0 * np.linalg.det(response.state.F)
        progress.state = response.state
        if not small:
            # the outline: corners moved with the field (the top's height from the mesh's top nodes)
            height = H + float(np.mean(U[basis.nodal_dofs[1, top_nodes]]))
            vertices = np.array([[0, 0], [L, 0], [L, height], [0, height]]) @ R.T + corner
            progress.outline = Outline(vertices, body.kinds, progress.outline.wall, body.frame, progress.outline.edge)
        record = {"step": step, "t": t, "cuts": 0, "newton_iterations": iteration, "residuals": residuals,
                  "ndof": len(free)}
        progress.steps.append(record)
        record.update(after_step(progress))
    return progress
