"""Body-fitted finite-element reference (scikit-fem).

The body must be a rectangle in its local frame `body.frame` (columns e_xi, e_eta): it is
meshed there by Q4 elements of about the grid's cell size, where every edge is axis-aligned,
so rollers are imposed strongly by dropping one displacement component per node (both on
fixed edges). Full 2 x 2 Gauss integration for the stiffness, 4 x 4 for the loads. The
essential data come from the lift: u = u^h + u^a with u^h = 0 (normal part on rollers) on the
essential edges. Results are rotated back (u = R u_loc, sigma = R sigma_loc R^T) and evaluated
at the same material points as every other method, by locating each point in the mesh.
Each essential side's reaction is the residual K U - f at its constrained nodes, rotated back
(baselines.boundary.piece_reactions). Any other body (a simple outline of lines and arcs,
non-convex allowed, essential arcs too) goes to baselines.fem.mesh (gmsh P2 triangles).
"""
from __future__ import annotations

from time import perf_counter

import numpy as np
from skfem import Basis, ElementQuad1, ElementVector, FacetBasis, LinearForm, MeshQuad, asm
from skfem.helpers import ddot, dot, sym_grad
from skfem.models.elasticity import linear_elasticity

from baselines.boundary import piece_reactions, point_basis, values_at
from baselines.edge_reactions import residual_reactions
from baselines.fem.mesh import solve_fem_mesh
from ibm.boundary_method import BoundaryMethod, Supports
from ibm.geometry.outline import Body
from ibm.exceptions import InputError
from ibm.small.model import Model, Solution
from ibm.solvers.linear import solve_system

# the local displacement component normal to each rectangle edge (base, right, top, left), and its
# outward normal in the local frame
NORMAL_COMPONENT = (1, 0, 1, 0)
OUTWARD = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])


def local_rectangle(body: Body) -> tuple[float, float]:
    """Width and height of the body in its local frame; InputError unless it is a rectangle
    with vertices (0, 0), (L, 0), (L, H), (0, H) relative to its first vertex."""
    local = (body.vertices - body.vertices[0]) @ body.frame
    if body.n_edges != 4:
        raise InputError(f"the fem baseline needs a rectangle; the body has {body.n_edges} edges")
    L, H = local[2]
    expected = np.array([[0, 0], [L, 0], [L, H], [0, H]])
    if not np.allclose(local, expected, atol=1e-9 * max(L, H)):
        raise InputError("the fem baseline needs a body that is a rectangle in its local frame "
                         "(base along e_xi, starting at the first vertex)")
    return float(L), float(H)


def _sides(L: float, H: float):
    """Facet tests of the local sides, in edge order base, right, top, left."""
    tol = 1e-9 * max(L, H)
    return (lambda x: np.abs(x[1]) < tol, lambda x: np.abs(x[0] - L) < tol,
            lambda x: np.abs(x[1] - H) < tol, lambda x: np.abs(x[0]) < tol)


def solve_fem(model: Model, estimate_condition: bool = True) -> Solution:
    start = perf_counter()
    body, material, loads = model.body, model.material, model.loads
    try:
        L, H = local_rectangle(body)
    except InputError:
        return solve_fem_mesh(model, estimate_condition)
    R, origin = body.frame, body.vertices[0]
    lam, mu = material.lam, material.mu
    h = model.grid.h
    nx, ny = max(1, int(np.ceil(L / h - 1e-9))), max(1, int(np.ceil(H / h - 1e-9)))
    mesh = MeshQuad.init_tensor(np.linspace(0, L, nx + 1), np.linspace(0, H, ny + 1))
    element = ElementVector(ElementQuad1())
    basis = Basis(mesh, element, intorder=3)          # 2 x 2 Gauss points
    load_basis = Basis(mesh, element, intorder=7)     # 4 x 4 for loads

    def to_global(x_loc):                             # (2, ...) local -> (n, 2) global points
        return (x_loc.reshape(2, -1).T @ R.T) + origin

    def lift_local(x_loc):                            # u^a, grad u^a in the local frame at (2, ...) points
        shape = x_loc.shape[1:]
        u, grad = model.lift(to_global(x_loc))
        return (u @ R).T.reshape(2, *shape), np.einsum("ai,pij,jb->abp", R.T, grad, R).reshape(2, 2, *shape)

    K = asm(linear_elasticity(lam, mu), basis)

    @LinearForm
    def loads_form(v, w):
        u_a, grad_a = lift_local(w.x)
        eps_a = 0.5 * (grad_a + np.swapaxes(grad_a, 0, 1))
        sigma_a = 2 * mu * eps_a + lam * np.einsum("ii...->...", eps_a) * np.eye(2)[:, :, None, None]
        f = -ddot(sigma_a, sym_grad(v))
        if loads.body_force is not None:
            b = (loads.body_force(to_global(w.x)) @ R).T.reshape(w.x.shape)
            f = f + dot(b, v)
        return f

    f = asm(loads_form, load_basis)
    sides = _sides(L, H)
    for k, traction in loads.tractions.items():
        facets = mesh.facets_satisfying(sides[k])
        @LinearForm
        def traction_form(v, w):
            t = (traction(to_global(w.x)) @ R).T.reshape(w.x.shape)
            return dot(t, v)
        f = f + asm(traction_form, FacetBasis(mesh, element, facets=facets, intorder=7))

    fixed = []
    for k in body.essential_edges:
        dofs = basis.get_dofs(mesh.facets_satisfying(sides[k]))
        names = ("u^1", "u^2") if body.kinds[k] == "fixed" else (("u^1", "u^2")[NORMAL_COMPONENT[k]],)
        fixed += [dofs.nodal[name] for name in names]
    fixed = np.unique(np.concatenate(fixed)) if fixed else np.zeros(0, int)
    free = np.setdiff1d(np.arange(basis.N), fixed)
    assembled = perf_counter()
    U = np.zeros(basis.N)
    U[free], info = solve_system(K[free][:, free], f[free], estimate_condition)
    solved = perf_counter()
    residual = (K @ U - f)[basis.nodal_dofs].T                                     # (n_nodes, 2), local frame
    nodes = {k: mesh.nodes_satisfying(sides[k]) for k in body.essential_edges}
    local = piece_reactions(dict(enumerate(body.kinds)), nodes,
                            {k: np.broadcast_to(OUTWARD[k], (len(at), 2)) for k, at in nodes.items()}, residual)

    # The mesh is uniform in the local frame, so a point's element follows from floor division
    # (scikit-fem's general element_finder searches all elements: minutes for 1e5 points).
    spacing = np.array([L / nx, H / ny])
    centres = mesh.p[:, mesh.t].mean(axis=1).T                                    # (n_elements, 2)
    table = np.empty((nx, ny), dtype=np.int64)
    ij = np.floor(centres / spacing).astype(int)
    table[ij[:, 0], ij[:, 1]] = np.arange(mesh.nelements)

    def finder(xi, eta):
        i = np.clip(np.floor(xi / spacing[0]).astype(int), 0, nx - 1)
        j = np.clip(np.floor(eta / spacing[1]).astype(int), 0, ny - 1)
        return table[i, j]

    def evaluate(x: np.ndarray, cells: np.ndarray | None = None):
        """u, sigma, sigma_zz at global points x (n, 2) inside the body (`cells` is ignored)."""
        x_loc = (x - origin) @ R
        x_loc = np.clip(x_loc, 0.0, [L, H])           # points on the outline stay in the mesh
        elements = finder(*x_loc.T)
        u_loc, grad_loc = values_at(point_basis(mesh, element, x_loc, elements), U)
        u_a, grad_a = model.lift(x)
        u = u_loc @ R.T + u_a
        grad = R @ grad_loc @ R.T + grad_a
        eps = 0.5 * (grad + np.swapaxes(grad, 1, 2))
        trace = eps[:, 0, 0] + eps[:, 1, 1]
        sigma = 2 * mu * eps + lam * trace[:, None, None] * np.eye(2)
        return u, sigma, lam * trace

    u, sigma, sigma_zz = evaluate(model.points.x)
    info.update(ndof=len(free), n_elements=mesh.nelements, time_assemble=assembled - start,
                time_solve=solved - assembled, time_s=perf_counter() - start)
    return Solution(u, sigma, sigma_zz, evaluate, info, reactions={k: R @ F for k, F in local.items()})


class BodyFittedFEM(BoundaryMethod):
    """The body-fitted reference: it meshes the body itself (Q4 on rectangles, gmsh P2 triangles on any
    other outline, Hex1 on the 3D boxes, P2 load steps for plasticity, total-Lagrangian Hencky at finite
    strain), so walls are imposed strongly wherever they lie."""

    name = "fem"
    summary = "body-fitted finite elements (scikit-fem), rollers imposed strongly"
    parameters = ()
    supports = Supports({"load-steps-3d": "the body-fitted reference has no 3D load steps yet"}, body_fitted=True)

    def solve(self, model):
        return solve_fem(model)

    def reactions(self, model, solution):
        return residual_reactions(solution)


FEM = BodyFittedFEM()
