"""General outlines: non-convex bodies, conditions on part of a side, walls and their bands."""
import numpy as np
import pytest
import shapely

from baselines.registry import METHODS
from ibm import dirichlet
from ibm.quadrature.bands import band_quadrature, band_regions
from ibm.geometry.frames import frame_of_angle
from ibm.geometry.outline import Body
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid
from ibm.models.elastic import Elastic
from ibm.small.model import Loads, build_model
from ibm.discretise.points import material_points

MATERIAL = Elastic(1e4, 0.3)
L_SHAPE = np.array([[0, 0], [100, 0], [100, 50], [50, 50], [50, 100], [0, 100]], float)


def placed(local: np.ndarray, angle: float, offset, h: float) -> np.ndarray:
    return np.asarray(offset, float) * h + local @ frame_of_angle(angle).T


def test_walls_join_collinear_pieces_of_one_kind_and_end_where_the_body_turns_in():
    # base split free | fixed | fixed | free, right side roller, re-entrant corner between two rollers
    v = np.array([[0, 0], [20, 0], [40, 0], [60, 0], [100, 0], [100, 50], [50, 50], [50, 100], [0, 100]], float)
    kinds = ("free", "fixed", "fixed", "free", "roller", "roller", "roller", "traction", "traction")
    body = Body(v, kinds)
    assert not body.convex
    walls = body.walls
    assert [(w.kind, w.pieces) for w in walls] == [("fixed", (1, 2)), ("roller", (4,)), ("roller", (5,)),
                                                   ("roller", (6,))]
    assert walls[0].length == pytest.approx(40.0) and walls[0].extend == (0.0, 0.0)    # ends inside the base
    assert walls[1].extend == (0.0, 0.0)                 # right angles: the band ends with the wall
    assert walls[2].extend == (0.0, 0.0) and walls[3].extend == (0.0, 0.0)             # re-entrant corner


def test_a_wall_runs_on_past_an_obtuse_convex_corner_as_far_as_the_body_needs():
    # a trapezoid: the base meets the right side at 135 degrees, the left side at 60
    v = np.array([[0, 0], [100, 0], [150, 50], [50 / np.sqrt(3), 50]])
    body = Body(v, ("fixed", "roller", "free", "free"))
    base = body.walls[0]
    assert base.extend[1] == pytest.approx(1.0) and base.extend[0] == 0.0     # cot 45 = 1; the acute end: 0
    # inside the body the base's distance is the distance to its line, also beyond its end
    x = np.array([[101.0, 0.5], [110.0, 9.0], [3.0, 2.0]])
    phi, grad = base.distance(x, 10.0)
    assert phi == pytest.approx(x[:, 1]) and grad == pytest.approx(np.array([[0, 1.0]] * 3))


def test_dirichlet_function_of_a_partial_edge_is_continuous_and_ends_at_the_piece():
    v = np.array([[0, 0], [40, 0], [60, 0], [100, 0], [100, 100], [0, 100]], float)
    body = Body(v, ("free", "fixed", "free", "roller", "free", "roller"))
    delta = 5.0
    t = np.linspace(0, 100, 20001)
    for height in (0.0, 1.0, 4.0):
        x = np.stack([t, np.full_like(t, height)], axis=1)
        D, grad = dirichlet.matrix(body, x, delta)
        assert np.max(np.abs(np.diff(D[:, 0, 0]))) < 5e-3          # no jump along the base
    x = np.stack([t, np.zeros_like(t)], axis=1)
    D, _ = dirichlet.matrix(body, x, delta)
    on_piece = (t >= 40) & (t <= 60)
    assert np.all(D[on_piece, 0, 0] == 0) and np.all(D[on_piece, 1, 1] == 0)       # fixed on the piece
    beyond = (np.abs(t - 50) > 10 + delta) & (t > delta) & (t < 100 - delta)   # clear of the side rollers too
    assert np.all(D[beyond] == np.eye(2))                     # free beyond the piece's band
    # past the ends the distance runs round the corner of the band's box: D(max(y, |t - 60|))
    x = np.array([[63.0, 1.0], [62.0, 2.5]])
    D, _ = dirichlet.matrix(body, x, delta)
    s = np.array([3.0, 2.5]) / delta
    assert D[:, 0, 0] == pytest.approx(2 * s - s * s, rel=1e-14)


def test_dirichlet_gradient_matches_finite_differences_in_every_branch():
    body = Body(L_SHAPE, ("traction", "traction", "roller", "fixed", "traction", "traction"))
    delta = 8.0
    rng = np.random.default_rng(3)
    x = np.array([50, 50]) + rng.uniform(-7, 7, (400, 2))
    x = x[shapely.contains_xy(shapely.Polygon(L_SHAPE), x[:, 0], x[:, 1])]
    from tests.ibm.test_core import dirichlet_gradients
    grad, fd = dirichlet_gradients(body, x, delta)
    for j in range(2):
        # points within eps of a kink (a branch switch) see a one-sided slope: they are few
        close = np.max(np.abs(fd[..., j] - grad[..., j]), axis=(1, 2)) < 1e-6
        assert close.mean() > 0.97


@pytest.mark.parametrize("angle,offset", [(90.0, (0.0, 0.0)), (30.0, (0.37, 0.29)), (17.3, (0.61, 0.13))])
def test_band_regions_tile_the_bands_of_a_non_convex_body(angle, offset):
    h, delta = 10.0, 3.0
    body = Body(placed(L_SHAPE, angle, offset, h), ("traction", "roller", "roller", "fixed", "traction", "roller"))
    regions = band_regions(body, delta)
    union = shapely.union_all([r for _, r in regions])
    bands = shapely.union_all([shapely.Polygon(w.box(delta)) for w in body.walls])
    expected = shapely.intersection(shapely.Polygon(body.vertices), bands)
    assert sum(r.area for _, r in regions) == pytest.approx(expected.area, rel=1e-12)   # disjoint ...
    assert shapely.symmetric_difference(union, expected).area < 1e-9 * expected.area   # ... and complete
    # the band quadrature integrates polynomials of the regions' degree exactly, cell by cell
    qp = band_quadrature(body, Grid.covering(body, h), delta)
    assert qp.weight.sum() == pytest.approx(expected.area, rel=1e-12)
    centre = body.vertices.mean(axis=0)
    f = lambda x: ((x[:, 0] - centre[0]) / 50) ** 3 * ((x[:, 1] - centre[1]) / 50) ** 3   # noqa: E731
    from tests.ibm.test_core import _monomial_integral
    exact = 0.0
    for geometry in shapely.get_parts(expected):
        for ring, sign in [(geometry.exterior, 1)] + [(hole, -1) for hole in geometry.interiors]:
            xy = np.asarray(ring.coords)[:-1]
            xy = xy if shapely.is_ccw(ring) else xy[::-1]
            exact += sign * _monomial_integral((xy - centre) / 50, 3, 3) * 50 ** 2
    assert np.sum(qp.weight * f(qp.x)) == pytest.approx(exact, rel=1e-10, abs=1e-12 * expected.area)


@pytest.mark.parametrize("angle,offset", [(90.0, (0.0, 0.0)), (30.0, (0.37, 0.29)), (61.7, (0.83, 0.41))])
def test_material_points_tile_a_non_convex_body(angle, offset):
    h = 7.0
    body = Body(placed(L_SHAPE, angle, offset, h), ("free",) * 6)
    points = material_points(body, Grid.covering(body, h), 2)
    assert points.volume.sum() == pytest.approx(7500.0, rel=1e-12)
    # a domain clipped at a re-entrant corner is not convex: its centroid (still the exact
    # one-point rule for linear integrands over it) may lie outside the body, never outside its box
    outline = shapely.Polygon(body.vertices)
    outside = ~shapely.contains_xy(outline.buffer(1e-9), *points.x.T)
    assert np.all(shapely.distance(outline, shapely.points(points.x[outside])) < h / 2 * np.sqrt(0.5))


def linear_patch(angle: float, offset, h: float, partial: bool):
    """The L-shape (or a square whose base is traction | fixed | traction) with a linear field
    whose essential data are homogeneous: u = (a eta, b eta) vanishes on the fixed base piece;
    on the L, u = (a (xi - 50), 0) vanishes on the fixed piece xi = 50 and is a roller field on eta = 50."""
    R = frame_of_angle(angle)
    corner = np.asarray(offset, float) * h
    if partial:
        local = np.array([[0, 0], [30, 0], [70, 0], [100, 0], [100, 100], [0, 100]], float)
        kinds = ("traction", "fixed", "traction", "traction", "traction", "traction")
        G = np.array([[0.0, 2e-3], [0.0, -1e-3]])                          # grad u, local
        origin = np.zeros(2)
    else:
        local, kinds = L_SHAPE, ("traction", "traction", "roller", "fixed", "traction", "traction")
        G = np.array([[1e-3, 0.0], [0.0, 0.0]])
        origin = np.array([50.0, 0.0])
    body = Body(corner + local @ R.T, kinds, frame=R)
    Gg = R @ G @ R.T
    eps = 0.5 * (Gg + Gg.T)
    sigma = 2 * MATERIAL.mu * eps + MATERIAL.lam * np.trace(eps) * np.eye(2)

    def exact(x):
        return ((x - corner) @ R - origin) @ G.T @ R.T

    def traction_of(k):
        outward = -body.normals[k]
        return lambda x: np.broadcast_to(sigma @ outward, (len(x), 2))

    loads = Loads(tractions={k: traction_of(k) for k in body.edges_of_kind("traction")})
    return build_model(body, MATERIAL, loads, h, 2), exact, sigma


@pytest.mark.parametrize("partial", [False, True], ids=["l-shape", "partial-edge"])
@pytest.mark.parametrize("angle,offset", [(90.0, (0.0, 0.0)), (30.0, (0.37, 0.29)), (61.7, (0.83, 0.41))])
@pytest.mark.parametrize("method", ["nitsche", "lagrange", "fem", "ibm"])
def test_linear_fields_on_non_convex_bodies_and_partial_edges(method, angle, offset, partial):
    model, exact, sigma = linear_patch(angle, offset, 10.0, partial)
    solution = METHODS[method](model)
    u = exact(model.points.x)
    err_u = np.abs(solution.u - u).max() / np.abs(u).max()
    err_sigma = np.abs(solution.sigma - sigma).max() / np.abs(sigma).max()
    if method == "ibm":       # D u^h is not linear in the bands: small, not round-off (seed: 1e-6)
        assert err_u < 1e-5 and err_sigma < 1e-3
    else:
        assert err_u < 1e-9 and err_sigma < 1e-8


@pytest.mark.parametrize("vertices,kinds,message", [
    ([[0, 0], [2, 2], [2, 0], [0, 2]], ("free",) * 4, "pieces 0 and 2 cross or touch"),
    ([[0, 0], [1, 0], [1, 0], [0, 1]], ("free",) * 4, "piece 1 from (1, 0) to (1, 0) has zero length"),
    ([[0, 0], [0, 1], [1, 1], [1, 0]], ("free",) * 4, "the outline runs clockwise"),
    ([[0, 0], [1, 0], [1, 1], [0, 1]], ("free", "free", "glued", "free"), "piece 2: kind 'glued' is not one of"),
])
def test_bad_outlines_are_named_in_one_line(vertices, kinds, message):
    with pytest.raises(InputError) as error:
        Body(np.array(vertices, float), kinds)
    assert message in str(error.value) and "\n" not in str(error.value)


# --- rates on the L-shape (non-convex; fixed and roller pieces meet at the re-entrant corner) -------
# Placements: the study's default (30 degrees, offset 0.37, 0.29) and one drawn at random once.
# The gates: L2 >= 1.9 and energy >= 0.95 for fem, lagrange, nitsche and the IBM with its
# documented band law delta = 0.001 h^2. Cut cells make the level-to-level rates swing (2.0, 1.1, 3.1
# for nitsche at 30 degrees): the IBM's fit needs six levels (h = 10 .. 0.3125) at 30 degrees to
# settle above 1.9 (five give 1.84, six 1.92; at the second placement five give 1.96).
L_SHAPE_PLACEMENTS = {"default": (30.0, (0.37, 0.29)), "random": (17.3, (0.61, 0.13))}


@pytest.mark.parametrize("placement", L_SHAPE_PLACEMENTS)
@pytest.mark.parametrize("method,levels,law", [("fem", 4, None), ("lagrange", 4, None), ("nitsche", 4, None),
                                               ("ibm", 6, "0.001*h^2")])
def test_l_shape_converges_at_the_optimal_rates(method, levels, law, placement):
    from studies.run.case import CaseSpec
    from studies.run.convergence import converge
    angle, offset = L_SHAPE_PLACEMENTS[placement]
    if method == "ibm" and placement == "random":
        levels = 5
    result = converge(CaseSpec(problem="l-shape", method=method, angle=angle, offset=offset, ppc=2), levels, law)
    assert result["rates"]["err_l2"] >= 1.9
    assert result["rates"]["err_energy"] >= 0.95
