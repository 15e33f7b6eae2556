"""Core IBM-MPM: shape functions, Dirichlet functions, band quadrature, material points."""

import numpy as np
import pytest

from ibm import dirichlet
from ibm.quadrature.bands import band_quadrature, band_regions, edge_quadrature
from ibm.geometry.outline import Body, rectangle
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid
from ibm.discretise.points import material_points

L = 100.0
EPS = np.finfo(float).eps
KINDS = ("roller", "roller", "traction", "roller")


def block(angle=30.0, offset=(0.37, 0.29), h=10.0, kinds=KINDS):
    return rectangle(L, L, kinds, angle, np.array(offset) * h)


@pytest.mark.parametrize("seed", [0, 1])
def test_partition_of_unity_and_gradients_sum_to_zero(seed):
    grid = Grid(h=2.5, lower=(-3, 4), shape=(7, 5))
    rng = np.random.default_rng(seed)
    x = grid.origin + rng.random((500, 2)) * np.array(grid.shape) * grid.h
    N, dN = grid.shape_functions(x, grid.locate(x))
    assert np.abs(N.sum(axis=1) - 1).max() < 1e-14
    assert np.abs(dN.sum(axis=1)).max() < 1e-14
    # linear fields are reproduced exactly, values and gradients
    nodes = grid.nodes()[grid.cell_nodes(grid.locate(x))]            # (n, 4, 2)
    assert np.abs(np.einsum("pi,pid->pd", N, nodes) - x).max() < 1e-12
    assert np.abs(np.einsum("pij,pik->pjk", dN, nodes) - np.eye(2)).max() < 1e-13


def test_locate_rejects_points_outside_the_grid():
    grid = Grid(h=1.0, lower=(0, 0), shape=(2, 2))
    with pytest.raises(InputError, match="outside the grid"):
        grid.locate(np.array([[2.5, 0.5]]))


def test_scalar_dirichlet_function():
    delta = 0.3
    phi = np.array([0.0, 0.15, 0.3, 1.0])
    D, dD = dirichlet.scalar(phi, delta)
    assert np.allclose(D, [0.0, 0.75, 1.0, 1.0], atol=1e-15)
    assert np.allclose(dD, [2 / delta, 1 / delta, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("kinds", [KINDS, ("fixed", "roller", "free", "fixed")])
def test_matrix_function_vanishes_on_essential_edges(kinds):
    body = block(kinds=kinds)
    delta = 2.0
    t = np.linspace(0.05, 0.95, 7)
    for k in body.essential_edges:
        x = body.starts[k] + t[:, None] * body.tangents[k]
        Dm, _ = dirichlet.matrix(body, x, delta)
        n = body.normals[k]
        if kinds[k] == "roller":   # the normal component of D v vanishes for every v
            # phi of a point on the edge is zero up to coordinate rounding, eps |x|
            assert np.abs(np.einsum("i,pia->pa", n, Dm)).max() < 8 * EPS * L / delta
        else:
            assert np.abs(Dm).max() < 8 * EPS * L / delta


@pytest.mark.parametrize("kinds", [KINDS, ("fixed", "roller", "free", "fixed")])
def test_matrix_function_gradient_matches_finite_differences(kinds):
    body = block(angle=30.0, kinds=kinds)
    delta = 3.0
    rng = np.random.default_rng(3)
    # points near the base-left corner, where two bands overlap, and in single bands
    local = np.concatenate([rng.random((20, 2)) * delta, rng.random((20, 2)) * [L, 2 * delta]])
    x = body.starts[0] + local @ body.frame.T
    grad, fd = dirichlet_gradients(body, x, delta)
    assert np.abs(fd - grad).max() < 1e-6 / delta


def dirichlet_gradients(body, x: np.ndarray, delta: float, eps: float = 1e-6):
    """grad D (n, 2, 2, 2) and its central finite differences of step eps, both [p, i, a, j]."""
    _, grad = dirichlet.matrix(body, x, delta)
    fd = np.stack([(dirichlet.matrix(body, x + eps * e, delta)[0] - dirichlet.matrix(body, x - eps * e, delta)[0])
                   / (2 * eps) for e in np.eye(2)], axis=-1)
    return grad, fd


def _monomial_integral(polygon_xy: np.ndarray, a: int, b: int) -> float:
    """int x^a y^b over a polygon (counter-clockwise), by the divergence theorem on its edges (exact)."""
    x0, y0 = polygon_xy.T
    x1, y1 = np.roll(polygon_xy, -1, axis=0).T
    # int x^a y^b dA = 1/(a+1) oint x^(a+1) y^b dy, the edge integrals by a Gauss rule exact for the degree
    g, w = np.polynomial.legendre.leggauss(a + b + 2)
    t = (g + 1) / 2
    x = x0[:, None] + t * (x1 - x0)[:, None]
    y = y0[:, None] + t * (y1 - y0)[:, None]
    return float(np.sum(w / 2 * x ** (a + 1) * y ** b * (y1 - y0)[:, None]) / (a + 1))


@pytest.mark.parametrize("sides", [3, 4, 5, 6, 7])
def test_quadrilateral_fan_rule_is_exact_to_its_degree(sides):
    """Convex polygons (triangles as collapsed quadrilaterals) against exact monomial integrals."""
    import shapely

    from ibm.quadrature.rules import fan_quadrilaterals, order_for_degree, quadrilateral_points
    rng = np.random.default_rng(sides)
    angles = np.sort(rng.uniform(0, 2 * np.pi, sides))
    vertices = np.stack([np.cos(angles), np.sin(angles)], axis=1) * rng.uniform(0.5, 2.0) + rng.uniform(-1, 1, 2)
    quads, owner = fan_quadrilaterals(np.array([shapely.Polygon(vertices)], dtype=object))
    assert len(quads) == (sides - 1) // 2 and np.all(owner == 0)
    for degree in (2, 6, 10):
        x, w, _ = quadrilateral_points(quads, order_for_degree(degree))
        for a in range(degree + 1):
            b = degree - a
            exact = _monomial_integral(vertices, a, b)
            assert abs(np.sum(w * x[:, 0] ** a * x[:, 1] ** b) - exact) < 1e-12 * max(1.0, abs(exact))
    x, w, _ = quadrilateral_points(quads, order_for_degree(2))
    assert abs(w.sum() - shapely.Polygon(vertices).area) < 1e-13


@pytest.mark.parametrize("angle", [90.0, 45.0, 30.0, 12.5])
@pytest.mark.parametrize("delta_rel", [0.3, 1e-3, 1e-6])
def test_band_area_is_delta_times_length_minus_overlaps(angle, delta_rel):
    h = 10.0
    body = block(angle=angle, h=h)
    delta = delta_rel * h
    qp = band_quadrature(body, Grid.covering(body, h), delta)
    # three roller edges of a square: two corners where bands overlap
    expected = 3 * delta * L - 2 * delta ** 2
    # band corners are differences of coordinates of size L: rounding eps L per unit length
    assert abs(qp.weight.sum() - expected) < 1e-13 * expected + 4 * EPS * L * L


def _integral_D_squared(delta, length):
    """int_0^length D(phi)^2 dphi: delta * 8/15 in the band, plus the rest."""
    return delta * 8 / 15 + (length - delta)


def _integral_dD_squared(delta):
    return 4 / (3 * delta)


@pytest.mark.parametrize("angle", [90.0, 30.0, 71.0])
@pytest.mark.parametrize("delta_rel", [0.45, 1e-2, 1e-5])
def test_band_quadrature_integrates_dirichlet_products_exactly(angle, delta_rel):
    """On a square with fixed base and fixed left side, D = D_base(eta) D_left(xi) separates,
    so int (D^2 - 1) and int |grad D|^2 over the body are products of 1-D integrals. The
    quadrature must be exact across the overlap corner and the kink at phi = delta."""
    h = 10.0
    body = block(angle=angle, h=h, kinds=("fixed", "free", "free", "fixed"))
    delta = delta_rel * h
    qp = band_quadrature(body, Grid.covering(body, h), delta)
    Dm, grad = dirichlet.matrix(body, qp.x, delta)
    D = Dm[:, 0, 0]
    I2 = _integral_D_squared(delta, L)
    # exact up to rounding: phi carries the rounding eps |x| of coordinates of size L, relative eps L / delta
    tolerance = 1e-12 + 4 * EPS * L / delta
    expected = I2 * I2 - L * L
    assert abs(np.sum(qp.weight * (D ** 2 - 1)) - expected) < tolerance * abs(expected)
    grad_sq = np.sum(grad[:, 0, 0, :] ** 2, axis=1)
    expected = 2 * _integral_dD_squared(delta) * I2          # |grad D|^2 = D_b'^2 D_l^2 + D_b^2 D_l'^2
    assert abs(np.sum(qp.weight * grad_sq) - expected) < tolerance * expected


def test_band_points_lie_in_their_cells_and_inside_the_body():
    h = 10.0
    body = block(angle=30.0, h=h)
    grid = Grid.covering(body, h)
    qp = band_quadrature(body, grid, 0.2 * h)
    corner = grid.cell_corners(qp.cells)
    assert np.all((qp.x >= corner - 1e-9) & (qp.x <= corner + h + 1e-9))
    assert body.signed_distance(qp.x).min() > -1e-9


def test_edge_quadrature_length_and_cells():
    h = 10.0
    body = block(angle=30.0, h=h)
    grid = Grid.covering(body, h)
    for k in range(4):
        qp = edge_quadrature(body, grid, k, 0.5)
        assert abs(qp.weight.sum() - L) < 1e-12 * L
        corner = grid.cell_corners(qp.cells)
        assert np.all((qp.x >= corner - 1e-9) & (qp.x <= corner + h + 1e-9))


@pytest.mark.parametrize("angle", [90.0, 45.0, 30.0, 7.0])
@pytest.mark.parametrize("ppc", [1, 2, 3])
def test_material_point_volumes_sum_to_the_area(angle, ppc):
    h = 10.0
    body = block(angle=angle, h=h)
    points = material_points(body, Grid.covering(body, h), ppc)
    assert abs(points.volume.sum() - body.area) < 1e-11 * body.area
    assert np.all(points.volume > 0) and np.all(points.volume <= (h / ppc) ** 2 * (1 + 1e-12))
    assert body.signed_distance(points.x).min() > 0
    # each point lies in the cell its domain belongs to
    grid = Grid.covering(body, h)
    corner = grid.cell_corners(points.cells)
    assert np.all((points.x >= corner) & (points.x <= corner + h))


def test_aligned_block_has_one_full_point_per_cell():
    body = rectangle(L, L, KINDS, 90.0, np.zeros(2))
    points = material_points(body, Grid.covering(body, 10.0), 1)
    assert len(points) == 100 and np.allclose(points.volume, 100.0)


def test_non_commuting_roller_corner_is_rejected():
    # a parallelogram whose rollers meet at 120 degrees (vertex 1)
    v = np.array([[0.0, 0.0], [50.0, 0.0], [75.0, 43.30127], [25.0, 43.30127]])
    body = Body(v, ("roller", "roller", "free", "free"))
    with pytest.raises(InputError, match="roller edges 0 and 1 meet at 120 degrees"):
        band_regions(body, 0.1)
    # fixed edges commute with anything: accepted
    band_regions(Body(v, ("fixed", "roller", "free", "free")), 0.1)


@pytest.mark.parametrize("delta", [0.0, -1.0, float("nan"), 60.0])
def test_bad_band_width_is_rejected(delta):
    with pytest.raises(InputError, match="band width"):
        band_regions(block(), delta)


def test_bad_bodies_are_rejected():
    # non-convex outlines are bodies; self-intersecting ones, zero-length pieces and clockwise ones are not
    assert not Body(np.array([[0, 0], [2, 0], [1, 0.2], [1, 2]], float), ("free",) * 4).convex
    with pytest.raises(InputError, match="pieces 0 and 2 cross or touch"):
        Body(np.array([[0, 0], [2, 2], [2, 0], [0, 2]], float), ("free",) * 4)
    with pytest.raises(InputError, match="piece 1 from \\(1, 0\\) to \\(1, 0\\) has zero length"):
        Body(np.array([[0, 0], [1, 0], [1, 0], [0, 1]], float), ("free",) * 4)
    with pytest.raises(InputError, match="fold back"):
        Body(np.array([[0, 0], [2, 0], [1, 0], [1, 1]], float), ("free",) * 4)
    with pytest.raises(InputError, match="clockwise"):
        Body(np.array([[0, 0], [0, 1], [1, 1], [1, 0]], float), ("free",) * 4)
    with pytest.raises(InputError, match="piece 1: kind 'pinned'"):
        Body(np.array([[0, 0], [1, 0], [0, 1]], float), ("free", "pinned", "free"))
    with pytest.raises(InputError, match="ppc"):
        material_points(block(), Grid.covering(block(), 10.0), 0)


@pytest.mark.parametrize("angle,offset", [(90.0, (0.0, 0.0)), (45.0, (0.1, 0.9)), (30.0, (0.37, 0.29))])
def test_band_points_only_in_cells_that_hold_material(angle, offset):
    h = 10.0
    body = block(angle=angle, offset=offset, h=h)
    grid = Grid.covering(body, h)
    points = material_points(body, grid, 1)
    qp = band_quadrature(body, grid, 1e-5 * h)
    assert set(np.unique(qp.cells)) <= set(np.unique(points.cells))


def test_grid_aligned_frame_is_exact():
    from ibm.geometry.frames import frame_of_angle
    for angle, expected in [(90.0, np.eye(2)), (0.0, np.array([[0.0, 1.0], [-1.0, 0.0]]))]:
        assert np.array_equal(frame_of_angle(angle), expected)


def test_subnormal_coordinates_do_not_lose_area():
    """A corner at 1e-308 once lost 8% of a cell's area in the polygon clipping."""
    tiny = np.array([2.2250738585072014e-308] * 2)
    body = rectangle(100.0, 60.0, ("roller", "fixed", "traction", "roller"), 1.0, tiny * 3.0)
    points = material_points(body, Grid.covering(body, 3.0), 1)
    assert abs(points.volume.sum() - body.area) < 1e-11 * body.area


def test_band_width_check_of_a_wall_sharing_its_side_with_the_strip():
    """The moved outline of the 45-degree column (step 1, h = 50/16): GEOS 3.14 intersects the body
    with a strip whose side lies on the base to a single point; the check measures 50 across the
    base and 10 across the side rollers whatever the overlay does with shared sides."""
    from ibm.quadrature.bands import check_delta
    v = np.array([[0.9374999999999978, 0.6250000000000022], [8.008567811865476, -6.446067811865476],
                  [41.75158374299181, 27.29694811926086], [40.74222497070414, 28.307891029032074],
                  [39.73230260010495, 29.318269979069388], [38.72215264891926, 30.328421685833483],
                  [37.711990959452706, 31.338563480423804], [36.70192628832098, 32.34880659365159],
                  [35.69169958899338, 33.35888949493607], [34.68023447808837, 34.367734478088366]])
    body = Body(v, ("fixed", "roller") + ("free",) * 7 + ("roller",))
    check_delta(body, 3.125e-5)
    with pytest.raises(InputError, match=r"it must be < 5 \(half the body's width across edge 1\)"):
        check_delta(body, 5.5)
    with pytest.raises(InputError, match=r"it must be < 23\.8\d* \(half the body's width across edge 0\)"):
        check_delta(Body(v, ("fixed",) + ("free",) * 9), 24.0)
