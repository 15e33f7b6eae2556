"""The general fem baseline (gmsh P2 triangles): mesh bridge, constraints, patch test, rates."""
from __future__ import annotations

import numpy as np
import pytest
import sympy
from scipy.spatial import cKDTree
from skfem import Basis, CellBasis, ElementTriP1, ElementTriP2, ElementVector, FacetBasis

from baselines.fem import mesh as fem_mesh
from baselines.boundary import values_at
from baselines.fem.method import solve_fem
from baselines.fem.mesh import TriangleLocator, constraint_transform, mesh_polygon, node_dofs
from ibm.geometry.arcs import Arc
from ibm.geometry.outline import Body, rectangle
from ibm.exceptions import InputError, SolveError
from ibm.discretise.grid import Grid
from ibm.models.elastic import Elastic
from ibm.small.model import Loads, Model, build_model
from ibm.discretise.points import MaterialPoints

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
    monkeypatch.setattr("baselines.fem.method.solve_fem_mesh", lambda *a, **k: pytest.fail("took the mesh path"))
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
    """Straight pieces only: the affine mesh path, values recorded before arcs existed."""
    body = Body(np.array([[0.0, 0.0], [100.0, 0.0], [50.0, 80.0]]), ("roller", "traction", "roller"))
    solution = solve_fem(build_model(body, MATERIAL, Loads(body_force=lambda x: np.tile([0.0, -1.0], (len(x), 1))), 10.0, 1))
    assert solution.info["n_elements"] > 60 and np.all(solution.u[:, 1] < 0)
    recorded_u = [[-0.015023627837714123, -0.014754030055020802], [-0.014769893177902439, -0.055182869379621524],
                  [-0.02607920345776483, -0.10982980961752722]]
    recorded_sigma = [[-19.83062649584203, -2.9236815903572486, -39.09318804603633],
                      [-6.240391380541369, -5.8492379111101105, -37.335136035120925],
                      [1.7340191009913921, -5.298447363381534, -20.89556173067374]]
    sigma = solution.sigma[[0, 5, 17]]
    assert np.allclose(solution.u[[0, 5, 17]], recorded_u, rtol=1e-10, atol=0)
    assert np.allclose(np.stack([sigma[:, 0, 0], sigma[:, 0, 1], sigma[:, 1, 1]], 1), recorded_sigma, rtol=1e-10, atol=0)


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


# --- arcs: curved (isoparametric) P2 elements -----------------------------------------------------

A_IN, B_OUT = 50.0, 100.0           # the quarter annulus' radii


def annulus() -> Body:
    """The quarter annulus A_IN < r < B_OUT, 0 < theta < 90 degrees, rotated and shifted like
    the L: rollers on the two straight symmetry lines, outer arc free, inner arc traction."""
    a, b = A_IN, B_OUT
    centre = ORIGIN.copy()
    return Body(ORIGIN + np.array([[a, 0], [b, 0], [0, b], [0, a]]) @ R.T, ("roller", "free", "roller", "traction"),
                frame=R, arcs=(None, Arc(centre), None, Arc(centre, clockwise=True)))


def half_disc(kinds=("fixed", "roller", "traction")) -> Body:
    """The disc of radius 40 about ORIGIN above its diameter (in the rotated frame): the
    diameter split at xi = 10, then one 180-degree counter-clockwise arc."""
    local_vertices = np.array([[-40.0, 0.0], [10.0, 0.0], [40.0, 0.0]])
    return Body(ORIGIN + local_vertices @ R.T, kinds, frame=R, arcs=(None, None, Arc(ORIGIN.copy())))


def arc_nodes(polygon, k: int):
    """Ends (2, m, 2) and midside nodes (m, 2) of the mesh facets on piece k."""
    mesh, facets = polygon.mesh, polygon.piece_facets[k]
    return np.transpose(mesh.p[:, mesh.facets[:, facets]], (1, 2, 0)), mesh.doflocs[:, mesh.nvertices + facets].T


def test_arcs_are_meshed_on_their_circles():
    """Corner and midside nodes of arc facets lie on the circle (midsides at the facets'
    middle angles), interior midside nodes at edge midpoints; a 180-degree arc is split at
    its middle; the curved mesh's area and arc lengths approach the exact ones."""
    for body, h in ((annulus(), 10.0), (half_disc(), 8.0)):
        polygon = mesh_polygon(body, h)
        mesh = polygon.mesh
        assert not mesh.affine
        on_arc = np.zeros(mesh.nfacets, bool)
        for k, arc in enumerate(body.arcs):
            if arc is None:
                continue
            radius, start, sweep = body.arc_angles(k)
            ends, mid = arc_nodes(polygon, k)
            for x in (*ends, mid):
                assert np.abs(np.linalg.norm(x - arc.center, axis=1) - radius).max() < 1e-12 * radius
            angle = [np.arctan2(*(x - arc.center).T[::-1]) for x in (*ends, mid)]
            halfway = np.angle(np.exp(1j * angle[0]) + np.exp(1j * angle[1]))
            assert np.abs(np.angle(np.exp(1j * (angle[2] - halfway)))).max() < 1e-9
            chords = np.linalg.norm(ends[1] - ends[0], axis=1)
            assert chords.max() < 1.05 * h and np.isclose(chords.sum(), radius * abs(sweep), rtol=1e-2)
            facets = FacetBasis(mesh, ElementTriP2(), facets=polygon.piece_facets[k], intorder=12)
            assert abs(facets.dx.sum() - radius * abs(sweep)) < 1e-4 * radius * abs(sweep)
            on_arc[polygon.piece_facets[k]] = True
            assert np.count_nonzero(polygon.curved[mesh.f2t[0, polygon.piece_facets[k]]]) == len(chords)
        if body.n_edges == 3:                                                   # split at the top
            top = ORIGIN + R @ [0.0, 40.0]
            assert np.linalg.norm(mesh.p.T - top, axis=1).min() < 1e-12
        straight = mesh.doflocs[:, mesh.nvertices:][:, ~on_arc] - mesh.p[:, mesh.facets[:, ~on_arc]].mean(axis=1)
        assert np.abs(straight).max() < 1e-12 * B_OUT
        assert np.count_nonzero(polygon.curved) == len(np.unique(mesh.f2t[0, on_arc]))
        edges = np.linalg.norm(np.diff(mesh.p[:, mesh.facets], axis=1), axis=0) / h   # element size ~ h
        assert edges.max() < 1.4 and 0.8 < edges.mean() < 1.05
        area = CellBasis(mesh, ElementTriP1(), intorder=2).dx.sum()
        assert abs(area - body.area) < 1e-5 * body.area


def test_curved_locator_inverts_the_p2_map():
    """Points in the bulges between a convex arc and its chords (outside every chord triangle)
    and anywhere inside are located exactly (F_e(X) = x); points on the circles (outside the
    P2 facets by up to chord^4 / (512 R^3)), a little outside the convex arc, or in the sliver
    between a concave arc and its chords are moved onto the mesh; far points are refused."""
    body = annulus()
    polygon = mesh_polygon(body, 10.0)
    mesh = polygon.mesh
    rng = np.random.default_rng(2)
    X = rng.uniform(0, 0.5, (50, 2))
    e = rng.integers(0, mesh.nelements, 50)
    locate = fem_mesh.CurvedLocator(mesh, polygon.curved)
    phi, _ = fem_mesh.p2_shapes(X)
    mapped = mesh.mapping().F(X.T[:, :, None], tind=e)[:, :, 0].T
    assert np.abs(np.einsum("mi,mid->md", phi, locate.nodes[e]) - mapped).max() < 1e-12 * B_OUT

    def polar(radius, angle):
        return ORIGIN + np.stack([radius * np.cos(angle), radius * np.sin(angle)], 1) @ R.T

    ends, mid = arc_nodes(polygon, 1)                                           # the outer (convex) arc
    mid_angle = np.arctan2(*((mid - ORIGIN) @ R).T[::-1])
    sagitta = B_OUT - np.linalg.norm(0.5 * (ends[0] + ends[1]) - ORIGIN, axis=1)
    bulge = polar(B_OUT - 0.5 * sagitta, mid_angle)                            # between arc and chord
    theta = np.linspace(0, np.pi / 2, 301)
    inside = polar(rng.uniform(A_IN, B_OUT, 400), rng.uniform(0, np.pi / 2, 400))
    exact = np.concatenate([bulge, inside, body.vertices])
    assert np.all(np.any(TriangleLocator(mesh.p, mesh.t).closest(bulge)[1] != bulge, axis=1))
    elements, X = locate(exact)
    phi, _ = fem_mesh.p2_shapes(X.T)
    assert np.abs(np.einsum("mi,mid->md", phi, locate.nodes[elements]) - exact).max() < 1e-10 * B_OUT
    assert X.min() > -1e-12 and X.sum(axis=0).max() < 1 + 1e-12
    ends, mid = arc_nodes(polygon, 3)                                           # the inner (concave) arc
    depth = A_IN - np.linalg.norm(0.5 * (ends[0] + ends[1]) - ORIGIN, axis=1)     # the chords' sagitta
    sliver = polar(A_IN - 0.5 * depth, np.arctan2(*((mid - ORIGIN) @ R).T[::-1]))
    rims = [polar(B_OUT, theta), polar(A_IN, theta), polar(B_OUT + 1e-9, theta)]
    elements, X = locate(np.concatenate(rims + [sliver]))
    assert X.min() > -1e-12 and X.sum(axis=0).max() <= 1 + 1e-12
    phi, _ = fem_mesh.p2_shapes(X.T)
    moved = np.einsum("mi,mid->md", phi, locate.nodes[elements])
    gap = np.linalg.norm(moved - np.concatenate(rims + [sliver]), axis=1)
    assert gap[:3 * len(theta)].max() < 10.0 ** 4 / (512 * A_IN ** 3)
    assert np.all(gap[3 * len(theta):] < depth) and np.all(gap[3 * len(theta):] > 0.4 * depth)  # onto the facet
    with pytest.raises(InputError, match="outside"):
        locate(np.array([[500.0, 500.0]]))


def lame(p: float = 10.0):
    """Lame's thick cylinder under inner pressure p (plane strain), about ORIGIN: u (n, 2) and
    sigma (n, 2, 2) of global points."""
    lam, mu = MATERIAL.lam, MATERIAL.mu
    a, b = A_IN, B_OUT
    A = p * a ** 2 / (b ** 2 - a ** 2)

    def polar(x):
        d = x - ORIGIN
        r = np.linalg.norm(d, axis=1)
        return r, d / r[:, None]

    def u(x):
        r, e = polar(x)
        return (A / (2 * mu) * (mu / (lam + mu) * r + b ** 2 / r))[:, None] * e

    def sigma(x):
        r, e = polar(x)
        t = np.stack([-e[:, 1], e[:, 0]], 1)
        s_rr, s_tt = A * (1 - b ** 2 / r ** 2), A * (1 + b ** 2 / r ** 2)
        return s_rr[:, None, None] * e[:, :, None] * e[:, None, :] + s_tt[:, None, None] * t[:, :, None] * t[:, None, :]

    return u, sigma


def test_lame_cylinder_converges_at_rate_three_on_curved_elements():
    """The quarter annulus, rollers on the symmetry lines, sigma n on the inner arc (n the
    body's outward normal), outer arc free. Relative L2 of u on a unit lattice (points in the
    outer arc's bulges included): rate >= 2.8 over h = 20, 10, 5 (measured 2.84: 1.20e-3,
    1.85e-4, 2.35e-5; arcs as chords give rate 2.0 and 6.1e-4 at h = 5)."""
    u, sigma = lame()
    body = annulus()
    loads = Loads(tractions={3: lambda x: np.einsum("nij,nj->ni", sigma(x), body.outward(3, x))})
    s = np.arange(0.25, B_OUT, 1.0)
    xi, eta = (a.ravel() for a in np.meshgrid(s, s))
    keep = (np.hypot(xi, eta) > A_IN) & (np.hypot(xi, eta) < B_OUT)
    x = ORIGIN + np.stack([xi[keep], eta[keep]], 1) @ R.T
    hs, errors = [20.0, 10.0, 5.0], []
    for h in hs:
        grid = Grid.covering(body, h)
        solution = solve_fem(Model(body, MATERIAL, loads, grid, MaterialPoints(x, np.ones(len(x)), grid.locate(x))))
        errors.append(np.linalg.norm(solution.u - u(x)) / np.linalg.norm(u(x)))
    rate = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert rate >= 2.8 and errors[-1] < 3e-5, (rate, errors)
    assert solution.info["residual"] < 1e-10


def facet_normals(polygon, body: Body, k: int):
    """x (n, 2) on the mesh's curved facets of piece k -> (n, 2) their outward unit normals
    (the P2 curves' own, not the circle's): the facet parameter by Newton's method."""
    (a, b), c = arc_nodes(polygon, k)
    tree = cKDTree(c)

    def normals(x):
        candidates = tree.query(x, 2)[1]                                        # (n, 2)
        A, B, C = a[candidates], b[candidates], c[candidates]                   # (n, 2, 2)
        d = B - A
        s = np.clip(np.sum((x[:, None] - A) * d, 2) / np.sum(d * d, 2), 0, 1)
        for _ in range(20):
            F = (A * ((1 - s) * (1 - 2 * s))[..., None] + B * (s * (2 * s - 1))[..., None]
                 + C * (4 * s * (1 - s))[..., None])
            dF = A * (4 * s - 3)[..., None] + B * (4 * s - 1)[..., None] + C * (4 - 8 * s)[..., None]
            ddF = 4 * A + 4 * B - 8 * C
            g = np.sum(dF * (F - x[:, None]), 2)
            s = s - g / (np.sum(ddF * (F - x[:, None]), 2) + np.sum(dF * dF, 2))
        best = np.argmin(np.linalg.norm(F - x[:, None], axis=2), axis=1)
        t = dF[np.arange(len(x)), best]
        n = np.stack([t[:, 1], -t[:, 0]], 1) / np.linalg.norm(t, axis=1)[:, None]
        return n * np.sign(np.sum(n * body.outward(k, x), 1))[:, None]

    return normals


def test_linear_field_on_a_half_disc():
    """u = G x + c (biaxial stress in the rotated frame, plus a rotation) on the half disc: fixed
    and roller on the diameter, the lift carries u, traction on the 180-degree arc. With the
    traction sigma n_h of the mesh's own curved facets the isoparametric P2 solution is exact
    (measured 1e-16); with the circle's normal n it is not (the P2 facets' normals differ by
    O((h / R)^3)), but close (measured 1.5e-8 at h = 8, 7.4e-10 at h = 4)."""
    lam, mu = MATERIAL.lam, MATERIAL.mu
    stress = np.diag([5.0, -3.0])
    strain = np.linalg.solve([[lam + 2 * mu, lam], [lam, lam + 2 * mu]], np.diag(stress))
    G = R @ (np.diag(strain) + np.array([[0.0, -1e-3], [1e-3, 0.0]])) @ R.T
    sigma, c = R @ stress @ R.T, np.array([0.01, -0.02])
    body = half_disc()

    def exact(x):
        return x @ G.T + c

    lift = lambda x: (exact(x), np.broadcast_to(G, (len(x), 2, 2)))
    theta = np.linspace(0, np.pi, 181)
    rim = ORIGIN + 40 * np.stack([np.cos(theta), np.sin(theta)], 1) @ R.T
    lattice = np.stack(np.meshgrid(np.arange(-39.5, 40, 1.0), np.arange(0.25, 40, 1.0)), -1).reshape(-1, 2)
    x = ORIGIN + lattice[np.hypot(*lattice.T) < 40] @ R.T
    scale = np.abs(exact(x)).max()
    errors = {}
    for h, consistent in ((8.0, True), (8.0, False), (4.0, False)):
        normal = facet_normals(mesh_polygon(body, h), body, 2) if consistent else (lambda x: body.outward(2, x))
        loads = Loads(tractions={2: lambda x: normal(x) @ sigma}, lift=lift)
        grid = Grid.covering(body, h)
        solution = solve_fem(Model(body, MATERIAL, loads, grid, MaterialPoints(x, np.ones(len(x)), grid.locate(x))))
        u_rim, sigma_rim, _ = solution.evaluate(rim)
        errors[h, consistent] = max(np.abs(solution.u - exact(x)).max(), np.abs(u_rim - exact(rim)).max()) / scale
        if consistent:
            assert errors[h, consistent] <= 1e-9, errors
            assert np.abs(solution.sigma - sigma).max() <= 1e-9 * 5 and np.abs(sigma_rim - sigma).max() <= 1e-9 * 5
    assert errors[8.0, False] < 3e-8 and errors[4.0, False] < errors[8.0, False] / 10, errors
