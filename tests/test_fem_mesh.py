"""The general fem baseline (gmsh P2 triangles): mesh bridge, constraints, patch test, rates."""
from __future__ import annotations

import numpy as np
import pytest
import sympy
from skfem import Basis, CellBasis, ElementTriP2, ElementVector

from baselines import fem_mesh
from baselines.boundary import values_at
from baselines.fem import solve_fem
from baselines.fem_mesh import TriangleLocator, constraint_transform, mesh_polygon, node_dofs
from ibm.geometry import Body, InputError, rectangle
from ibm.grid import Grid
from ibm.material import Elastic
from ibm.model import Loads, Model, build_model
from ibm.points import MaterialPoints
from ibm.solve import SolveError

MATERIAL = Elastic(1e4, 0.3)
ANGLE = np.deg2rad(30.0)
R = np.array([[np.cos(ANGLE), -np.sin(ANGLE)], [np.sin(ANGLE), np.cos(ANGLE)]])   # columns e_xi, e_eta
ORIGIN = np.array([3.7, 2.9])
# the 100 x 100 L-shape in its local frame; the base is split at xi = 30 and 70
L_LOCAL = np.array([[0, 0], [30, 0], [70, 0], [100, 0], [100, 50], [50, 50], [50, 100], [0, 100]], float)


def l_body(kinds) -> Body:
    """The L-shape rotated by 30 degrees and shifted off the grid (pieces as in L_LOCAL)."""
    return Body(ORIGIN + L_LOCAL @ R.T, kinds, frame=R)


def local(x):
    return (x - ORIGIN) @ R


def interior_points(body: Body, spacing: float, grid: Grid) -> MaterialPoints:
    """A lattice of points strictly inside the L (local frame), unit volumes."""
    s = np.arange(spacing / 2, 100, spacing) + 0.01 * spacing
    xi, eta = (a.ravel() for a in np.meshgrid(s, s))
    keep = (xi < 100) & (eta < 100) & ((xi < 50) | (eta < 50))
    x = ORIGIN + np.stack([xi[keep], eta[keep]], axis=1) @ R.T
    return MaterialPoints(x, np.ones(len(x)), cells=grid.locate(x))


def model_of(body: Body, loads: Loads, h: float, spacing: float = 5.0) -> Model:
    grid = Grid.covering(body, h)
    return Model(body, MATERIAL, loads, grid, interior_points(body, spacing, grid))


def traction_of(sigma, body: Body, k: int):
    """x (n, 2) -> sigma(x) n (n, 2) with n the outward normal of piece k; sigma: x -> (n, 2, 2)."""
    n = -body.normals[k]
    return lambda x: sigma(x) @ n


# --- the gmsh -> scikit-fem bridge --------------------------------------------------------

def test_gmsh_p2_nodes_follow_scikit_fem_order():
    """gmsh's 6-node triangle (corners, then midsides of 0-1, 1-2, 2-0) maps onto MeshTri2's
    vertex + facet numbering: every midside node is its facet's midpoint, a quadratic is
    interpolated exactly, and each piece holds its own facets and nodes."""
    body = l_body(("free", "fixed", "free", "traction", "free", "roller", "free", "roller"))
    nodes, triangles, _ = fem_mesh.gmsh_triangles(body.vertices, 12.0)
    corners = nodes[triangles[:, :3]]                                           # (n_elements, 3, 2)
    assert np.abs(nodes[triangles[:, 3:]] - 0.5 * (corners + np.roll(corners, -1, axis=1))).max() < 1e-12
    polygon = mesh_polygon(body, 12.0)
    mesh = polygon.mesh
    assert mesh.doflocs.shape[1] == len(nodes) == mesh.nvertices + mesh.nfacets
    assert np.abs(mesh.doflocs[:, mesh.nvertices:] - mesh.p[:, mesh.facets].mean(axis=1)).max() < 1e-12
    same = [a[np.lexsort(a.T[::-1])] for a in (mesh.doflocs.T, nodes)]        # the same nodes, reordered
    assert np.array_equal(*same)
    basis = Basis(mesh, ElementVector(ElementTriP2()))
    dofs = node_dofs(basis)
    assert np.abs(basis.doflocs[:, dofs[0]] - mesh.doflocs).max() < 1e-12 and np.array_equal(dofs[1], dofs[0] + 1)
    q = lambda x: np.stack([x[:, 0] ** 2 - 3 * x[:, 0] * x[:, 1], 2 * x[:, 1] ** 2 + x[:, 0]], 1)
    U = np.zeros(basis.N)
    U[dofs.T] = q(mesh.doflocs.T)
    x = ORIGIN + np.random.default_rng(0).uniform(2, 48, (200, 2)) @ R.T
    elements, X = TriangleLocator(mesh.p, mesh.t)(x)
    u, grad = values_at(CellBasis(mesh, basis.elem, quadrature=(X[:, :, None], np.ones((200, 1))),
                                  elements=elements), U)
    assert np.abs(u - q(x)).max() < 1e-9 * np.abs(q(x)).max()
    for k in range(body.n_edges):
        s, t = body.starts[k], body.tangents[k] / body.lengths[k]
        on = mesh.doflocs.T[polygon.piece_nodes[k]] - s
        assert np.abs(on @ body.normals[k]).max() < 1e-9
        assert np.isclose((on @ t).max(), body.lengths[k]) and np.isclose((on @ t).min(), 0, atol=1e-9)
        length = np.linalg.norm(np.diff(mesh.p[:, mesh.facets[:, polygon.piece_facets[k]]], axis=1), axis=0).sum()
        assert np.isclose(length, body.lengths[k], rtol=1e-12)
    # the same body gives the same mesh (one thread, fixed algorithm)
    again = fem_mesh.gmsh_triangles(body.vertices, 12.0)
    assert np.array_equal(again[0], nodes) and np.array_equal(again[1], triangles)


def test_locator_finds_vertices_outline_and_refuses_far_points():
    body = l_body(("traction",) * 8)
    mesh = mesh_polygon(body, 9.0).mesh
    locate = TriangleLocator(mesh.p, mesh.t)
    x = np.concatenate([body.vertices, 0.5 * (body.starts + body.ends), mesh.p.T])
    elements, X = locate(x)
    corners = mesh.p[:, mesh.t[:, elements]]                                     # (2, 3, n)
    back = corners[:, 0] + (corners[:, 1] - corners[:, 0]) * X[0] + (corners[:, 2] - corners[:, 0]) * X[1]
    assert np.abs(back.T - x).max() < 1e-11
    assert X.min() > -1e-12 and (X.sum(axis=0)).max() < 1 + 1e-12
    out = body.vertices[5] + 0.1 * (R @ [1.0, 1.0])           # just outside the re-entrant corner
    elements, X = locate(out[None])
    assert X.min() >= -1e-12 and X.sum() <= 1 + 1e-12                            # moved onto the mesh
    with pytest.raises(InputError, match="outside"):
        locate(np.array([[500.0, 500.0]]))


# --- constraints --------------------------------------------------------------------------------

def test_roller_corners_and_collinear_rollers():
    """A node on two rollers with different normals, or a roller and a fixed piece, loses both
    components; on two collinear rollers it keeps the common tangential one."""
    kinds = ("roller", "roller", "fixed", "traction", "free", "roller", "free", "roller")
    body = l_body(kinds)
    polygon = mesh_polygon(body, 10.0)
    basis = Basis(polygon.mesh, ElementVector(ElementTriP2()))
    dofs = node_dofs(basis)
    T = constraint_transform(body, polygon, dofs)
    assert np.allclose((T.T @ T).toarray(), np.eye(T.shape[1]))                 # orthonormal columns
    x = polygon.mesh.doflocs.T

    def rows_at(point):
        node = int(np.argmin(np.linalg.norm(x - point, axis=1)))
        return T[dofs[:, node]].toarray()                                       # (2, n_q)

    tangent = R[:, 0]
    assert np.count_nonzero(rows_at(body.vertices[0])) == 0                    # two rollers, normals e_eta, e_xi
    assert np.count_nonzero(rows_at(body.vertices[2])) == 0                    # roller | fixed
    split = rows_at(body.vertices[1])                                           # roller | roller, collinear
    assert np.count_nonzero(split.any(axis=0)) == 1
    assert np.allclose(np.abs(split[:, split.any(axis=0)][:, 0]), np.abs(tangent))
    middle = rows_at(ORIGIN + R @ [50.0, 75.0])                                 # inside the re-entrant roller
    assert np.count_nonzero(middle.any(axis=0)) == 1
    assert np.allclose(np.abs(middle[:, middle.any(axis=0)][:, 0]), np.abs(R[:, 1]))
    assert np.count_nonzero(rows_at(ORIGIN + R @ [30.0, 30.0]).any(axis=0)) == 2


def test_unheld_body_is_refused():
    """Collinear rollers only: the body slides along them."""
    body = l_body(("roller", "roller", "roller", "traction", "free", "free", "free", "free"))
    with pytest.raises(SolveError, match="rigid-body motion"):
        solve_fem(model_of(body, Loads(), 10.0))


# --- patch test -------------------------------------------------------------------------------

def test_patch_test_on_a_rotated_l_shape():
    """Uniaxial stress s along e_xi plus a rigid motion: free on the base (split free | fixed |
    free), the step and the top, rollers on both sides normal to e_xi (inclined 30 degrees, the
    re-entrant one with nonzero normal data), the exact traction on the right side. The lift
    matches the essential data only: u^a = u + k eta e_eta."""
    s, c, omega, k = 5.0, np.array([0.01, -0.02]), 1e-4, 3e-4
    eps_xx, eps_yy = s * (1 - MATERIAL.nu ** 2) / MATERIAL.E, -s * MATERIAL.nu * (1 + MATERIAL.nu) / MATERIAL.E
    G_local = np.array([[eps_xx, -omega], [omega, eps_yy]])
    G = R @ G_local @ R.T
    sigma = R @ np.diag([s, 0.0]) @ R.T
    kinds = ("free", "fixed", "free", "traction", "free", "roller", "free", "roller")
    body = l_body(kinds)

    def exact(x):
        return (local(x) @ G_local.T + c) @ R.T

    def lift(x):
        eta = local(x)[:, 1]
        return exact(x) + k * eta[:, None] * R[:, 1], np.broadcast_to(G + k * np.outer(R[:, 1], R[:, 1]), (len(x), 2, 2))

    loads = Loads(tractions={3: traction_of(lambda x: np.broadcast_to(sigma, (len(x), 2, 2)), body, 3)}, lift=lift)
    model = model_of(body, loads, 7.0)
    solution = solve_fem(model)
    assert solution.info["n_elements"] > 300 and solution.info["residual"] < 1e-10
    u = exact(model.points.x)
    assert np.abs(solution.u - u).max() <= 1e-9 * np.abs(u).max()
    assert np.abs(solution.sigma - sigma).max() <= 1e-9 * s
    assert np.abs(solution.sigma_zz - MATERIAL.nu * s).max() <= 1e-9 * s
    on = np.concatenate([body.vertices, 0.5 * (body.starts + body.ends)])       # on the outline
    u_on, sigma_on, _ = solution.evaluate(on)
    assert np.abs(u_on - exact(on)).max() <= 1e-9 * np.abs(u).max()
    assert np.abs(sigma_on - sigma).max() <= 1e-9 * s


# --- convergence -------------------------------------------------------------------------------

def entries(f, x):
    """A lambdified sympy matrix (of xi, eta) at global points x (n, 2): (n, rows, cols)."""
    m = f(*local(x).T)
    return np.array([[np.broadcast_to(e, len(x)) for e in row] for row in m], float).transpose(2, 0, 1)


def manufactured():
    """u = (sin a xi cos b eta, cos a xi sin b eta) in the local frame: rollers on xi = 0 and
    eta = 0 hold (zero normal displacement and shear traction). Returns u, sigma and
    b = -div sigma as numpy functions of global points."""
    xi, eta = sympy.symbols("xi eta")
    a, b = 1.3 * sympy.pi / 100, 0.9 * sympy.pi / 100
    u = sympy.Matrix([sympy.sin(a * xi) * sympy.cos(b * eta), sympy.cos(a * xi) * sympy.sin(b * eta)])
    grad = u.jacobian([xi, eta])
    eps = (grad + grad.T) / 2
    sigma = 2 * MATERIAL.mu * eps + MATERIAL.lam * eps.trace() * sympy.eye(2)
    force = -sympy.Matrix([sympy.diff(sigma[i, 0], xi) + sympy.diff(sigma[i, 1], eta) for i in range(2)])
    f_u, f_sigma, f_force = (sympy.lambdify((xi, eta), e, "numpy") for e in (u, sigma, force))
    return (lambda x: entries(f_u, x)[:, :, 0] @ R.T, lambda x: R @ entries(f_sigma, x) @ R.T,
            lambda x: entries(f_force, x)[:, :, 0] @ R.T)


def test_p2_converges_at_least_at_rate_two_and_a_half():
    """Rollers on the base and the left side (their corner loses both components), exact
    tractions elsewhere, b = -div sigma; zero lift. Relative L2 of u on a dense lattice."""
    u, sigma, force = manufactured()
    kinds = ("roller", "roller", "roller", "traction", "traction", "traction", "traction", "roller")
    body = l_body(kinds)
    loads = Loads(body_force=force, tractions={k: traction_of(sigma, body, k) for k in (3, 4, 5, 6)})
    hs, errors = [8.0, 4.0, 2.0, 1.0], []
    for h in hs:
        model = model_of(body, loads, h, spacing=1.0)
        solution = solve_fem(model)
        exact = u(model.points.x)
        errors.append(np.linalg.norm(solution.u - exact) / np.linalg.norm(exact))
    rate = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert rate >= 2.5 and errors[-1] < 1e-6, (rate, errors)


# --- dispatch ------------------------------------------------------------------------------------

def test_rectangles_still_take_the_q4_path(monkeypatch):
    """A rectangle in its frame is solved by the Q4 code exactly as before the general path
    existed (values recorded from that code)."""
    monkeypatch.setattr("baselines.fem.solve_fem_mesh", lambda *a, **k: pytest.fail("took the mesh path"))
    body = rectangle(100.0, 60.0, ("roller", "traction", "free", "fixed"), 30.0, np.array([3.7, 2.9]))
    loads = Loads(body_force=lambda x: np.stack([0 * x[:, 0] + 1.0, -2.0 + 0.01 * x[:, 0]], 1),
                  tractions={1: lambda x: np.stack([0.5 + 0 * x[:, 1], 0.02 * x[:, 1]], 1)})
    solution = solve_fem(build_model(body, MATERIAL, loads, 10.0, 1))
    assert solution.info["n_elements"] == 60 and solution.info["ndof"] == 130
    recorded_u = [[0.140971547202981, -0.2947098559475466], [0.0410563250745039, -0.1754586862601276],
                  [0.0776049862428408, -0.4414065655998664]]
    recorded_sigma = [[55.4928906865135, -45.880766162231865, 114.14606696599911],
                      [60.02756503871305, -40.872530448168014, 135.6153890898849],
                      [29.009166466970495, -40.83426298650299, 75.95523282259202]]
    sigma = solution.sigma[[0, 7, 30]]
    assert np.allclose(solution.u[[0, 7, 30]], recorded_u, rtol=1e-10, atol=0)
    assert np.allclose(np.stack([sigma[:, 0, 0], sigma[:, 0, 1], sigma[:, 1, 1]], 1), recorded_sigma, rtol=1e-10, atol=0)


def test_other_polygons_take_the_mesh_path():
    body = Body(np.array([[0.0, 0.0], [100.0, 0.0], [50.0, 80.0]]), ("roller", "traction", "roller"))
    solution = solve_fem(build_model(body, MATERIAL, Loads(body_force=lambda x: np.tile([0.0, -1.0], (len(x), 1))), 10.0, 1))
    assert solution.info["n_elements"] > 60 and np.all(solution.u[:, 1] < 0)


# --- bad input -----------------------------------------------------------------------------------

def test_self_intersecting_outline_is_refused():
    """Body checks its own outline unless it is a tracked (deformed) one: the mesh checks again."""
    v = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [6.0, -4.0], [0.0, 10.0]])
    body = Body(v, ("fixed",) * 5, tracked=True)
    grid = Grid.covering(body, 2.0)
    x = np.array([[2.0, 5.0]])
    model = Model(body, MATERIAL, Loads(), grid, MaterialPoints(x, np.ones(1), cells=grid.locate(x)))
    with pytest.raises(InputError, match="intersects itself"):
        solve_fem(model)


def test_gmsh_failure_is_an_input_error_and_gmsh_is_finalized(monkeypatch):
    def fail(dim):
        raise Exception("no surface")
    monkeypatch.setattr(fem_mesh.gmsh.model.mesh, "generate", fail)
    with pytest.raises(InputError, match="gmsh could not mesh the body: no surface"):
        mesh_polygon(l_body(("fixed",) * 8), 10.0)
    assert not fem_mesh.gmsh.isInitialized()
