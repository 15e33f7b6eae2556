"""Simplices clipped by half-spaces and Gauss rules on them, against Qhull, shapely and closed forms."""
from itertools import permutations, product
from math import factorial

import numpy as np
import pytest
import shapely
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, Delaunay, HalfspaceIntersection

from ibm.exceptions import InputError
from ibm.geometry.polytope import (box_simplices, clip, clip_all, kuhn_simplices, measure, quadrature, simplex_rule,
                          sums, volumes_and_centroids)

UNIT_CUBE = (np.zeros((1, 3)), np.ones((1, 3)))


def signed_volume(vertices: np.ndarray) -> np.ndarray:
    """(m,) det(x_i - x0) / k! of k-simplices in k-space."""
    k = vertices.shape[1] - 1
    return np.linalg.det(vertices[:, 1:] - vertices[:, :1]) / factorial(k)


def polynomial(x: np.ndarray) -> np.ndarray:
    """A positive polynomial of total degree 4 in 3D."""
    a, b, c = x.T
    return 1 + a + 2 * b ** 2 + a * b * c + 3 * a ** 2 * c ** 2 + b ** 4 + c ** 3 * a + 0.5 * a * b


def reference_polytope(A: np.ndarray, b: np.ndarray) -> ConvexHull | None:
    """The hull of {A x <= b} (bounded) by Qhull, or None when it holds no ball of radius 0.02."""
    norm = np.linalg.norm(A, axis=1)
    d = A.shape[1]
    lp = linprog(np.r_[np.zeros(d), -1.0], A_ub=np.c_[A, norm], b_ub=b, bounds=[(None, None)] * d + [(0, None)])
    if not lp.success or lp.x[-1] < 0.02:
        return None
    return ConvexHull(HalfspaceIntersection(np.c_[A, -b], lp.x[:d]).intersections)


def hull_centroid(hull: ConvexHull) -> np.ndarray:
    """Centroid of a 3D hull from tetrahedra fanned from its vertex mean to its facet triangles."""
    apex = hull.points[hull.vertices].mean(axis=0)
    tetrahedra = np.concatenate([np.broadcast_to(apex, (len(hull.simplices), 1, 3)),
                                 hull.points[hull.simplices]], axis=1)
    size = np.abs(signed_volume(tetrahedra))
    return (size[:, None] * tetrahedra.mean(axis=1)).sum(axis=0) / size.sum()


def hull_integral(hull: ConvexHull, f, degree: int) -> float:
    """Integral of f over a 3D hull: the rule on the tetrahedra of a Delaunay triangulation of its vertices."""
    points = hull.points[hull.vertices]
    tetrahedra = points[Delaunay(points).simplices]                               # (m, 4, 3)
    t, w = simplex_rule(3, degree)
    x = tetrahedra[:, None, 0] + np.einsum("qk,mkd->mqd", t, tetrahedra[:, 1:] - tetrahedra[:, :1])
    return float(np.sum(6 * np.abs(signed_volume(tetrahedra))[:, None] * w * f(x.reshape(-1, 3)).reshape(x.shape[:2])))


def half_plane(normal: np.ndarray, offset: float, size: float = 100.0) -> shapely.Polygon:
    """{x . n <= c} in 2D as a large square."""
    normal = np.asarray(normal, float)
    scale = np.linalg.norm(normal)
    n, c = normal / scale, offset / scale
    t = np.array([-n[1], n[0]])
    p = c * n
    return shapely.Polygon([p + size * t, p - size * t, p - size * (t + n), p + size * (t - n)])


def random_unit(rng, d: int) -> np.ndarray:
    v = rng.normal(size=d)
    return v / np.linalg.norm(v)


# --- the Kuhn triangulation ---------------------------------------------------------------------------------


@pytest.mark.parametrize("d", [2, 3])
def test_kuhn_simplices_tile_random_boxes_with_positive_orientation(d):
    rng = np.random.default_rng(d)
    lo = rng.uniform(-5, 5, size=(20, d))
    hi = lo + rng.uniform(0.01, 3, size=(20, d))
    vertices, owner = box_simplices(lo, hi)
    assert vertices.shape == (20 * factorial(d), d + 1, d) and owner.shape == (20 * factorial(d),)
    assert np.all(signed_volume(vertices) > 0)
    assert len(kuhn_simplices(d)) == factorial(d)
    volume = np.prod(hi - lo, axis=1)
    assert np.allclose(sums(owner, measure(vertices), 20), volume, rtol=1e-14, atol=0)
    # a tiling, not just the right total: the degree-2 moments of every box are exact too
    x, weight, point_owner = quadrature(vertices, owner, 2)
    for a in product(range(3), repeat=d):
        if sum(a) <= 2:
            exact = np.prod([(hi[:, i] ** (a[i] + 1) - lo[:, i] ** (a[i] + 1)) / (a[i] + 1) for i in range(d)], axis=0)
            got = sums(point_owner, weight * np.prod(x ** np.array(a), axis=1), 20)
            assert np.allclose(got, exact, rtol=1e-12, atol=1e-12 * np.max(np.abs(exact)))


# --- the Gauss rules ----------------------------------------------------------------------------------------


def monomial_error(k: int, t: np.ndarray, w: np.ndarray, a: tuple[int, ...]) -> float:
    exact = np.prod([factorial(i) for i in a]) / factorial(sum(a) + k)
    return abs(np.sum(w * np.prod(t ** np.array(a), axis=1)) - exact) / exact


@pytest.mark.parametrize("k", [2, 3])
def test_simplex_rule_integrates_every_monomial_up_to_its_degree_exactly(k):
    for p in range(11):
        t, w = simplex_rule(k, p)
        assert np.all(w > 0) and np.all(t >= 0) and np.all(t.sum(axis=1) <= 1)
        assert abs(w.sum() - 1 / factorial(k)) < 1e-15
        for a in product(range(p + 1), repeat=k):
            if sum(a) <= p:
                assert monomial_error(k, t, w, a) < 1e-13, (k, p, a)


@pytest.mark.parametrize("k", [2, 3])
def test_simplex_rule_fails_past_its_degree(k):
    # (p // 2 + 1) Gauss points per collapsed direction are exact to degree 2 (p // 2) + 1: p itself when p is
    # odd (the degree is tight), p + 1 when p is even; t1^(2 n) is not integrated exactly by n points
    for p in range(11):
        t, w = simplex_rule(k, p)
        tight = p if p % 2 else p + 1
        for a in product(range(tight + 1), repeat=k):
            if sum(a) == tight:
                assert monomial_error(k, t, w, a) < 1e-13, (k, p, a)
        first = (tight + 1,) + (0,) * (k - 1)
        assert monomial_error(k, t, w, first) > 1e-6, (k, p)


# --- one plane: the cases by hand ---------------------------------------------------------------------------


TRIANGLE = np.array([[0, 0], [1, 0], [0, 1]], float)
TETRAHEDRON = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)


@pytest.mark.parametrize("normal, c, exact", [
    ((1, 1), 0.3, 0.3 ** 2 / 2),                                  # 1 vertex in
    ((1, 0), 0.3, 0.5 - 0.7 ** 2 / 2),                            # 2 in
    ((1, 1, 1), 0.4, 0.4 ** 3 / 6),                               # 1 in
    ((1, 1, 0), 0.4, 0.4 ** 2 / 2 - 0.4 ** 3 / 3),                # 2 in: the integral of s (1 - s) over 0 .. c
    ((1, 0, 0), 0.4, 1 / 6 - 0.6 ** 3 / 6),                       # 3 in
])
def test_every_case_in_every_vertex_order_gives_the_closed_form_and_keeps_the_orientation(normal, c, exact):
    simplex = TRIANGLE if len(normal) == 2 else TETRAHEDRON
    orders = np.array(list(permutations(range(len(simplex)))))
    vertices = simplex[orders]                                    # every vertex order, both orientations
    pieces, owner = clip(vertices, np.arange(len(orders)), np.array(normal, float), c)
    assert np.allclose(sums(owner, measure(pieces), len(orders)), exact, rtol=1e-14, atol=0)
    assert np.all(np.sign(signed_volume(pieces)) == np.sign(signed_volume(vertices))[owner])
    assert np.all(np.diff(owner) >= 0)                            # pieces in the order of their simplices
    x, weight, point_owner = quadrature(pieces, owner, 2)
    inside = (x @ np.array(normal, float) <= c + 1e-14).all()
    assert inside and np.allclose(sums(point_owner, weight, len(orders)), exact, rtol=1e-14)


# --- random planes against Qhull ----------------------------------------------------------------------------


def cube_halfspaces() -> tuple[np.ndarray, np.ndarray]:
    return np.r_[-np.eye(3), np.eye(3)], np.r_[np.zeros(3), np.ones(3)]


def check_against_qhull(pieces, owner, A, b):
    hull = reference_polytope(A, b)
    assert hull is not None
    volume, centroid = volumes_and_centroids(pieces, owner, 1)
    assert volume[0] == pytest.approx(hull.volume, rel=1e-12, abs=0)
    assert np.allclose(centroid[0], hull_centroid(hull), rtol=0, atol=1e-12)
    x, weight, _ = quadrature(pieces, owner, 4)
    assert np.sum(weight * polynomial(x)) == pytest.approx(hull_integral(hull, polynomial, 4), rel=1e-12, abs=0)
    assert np.all(signed_volume(pieces) > 0)
    assert np.all(measure(pieces) > 1e-14 * 1 / 6)


@pytest.mark.parametrize("seed", range(60))
def test_a_cube_clipped_by_random_planes_matches_qhull(seed):
    rng = np.random.default_rng(seed)
    while True:
        p = rng.integers(1, 4)
        normals = np.array([random_unit(rng, 3) for _ in range(p)])
        offsets = np.einsum("pd,pd->p", normals, rng.uniform(0.15, 0.85, size=(p, 3)))
        A, b = cube_halfspaces()
        A, b = np.r_[A, normals], np.r_[b, offsets]
        if reference_polytope(A, b) is not None:
            break
    pieces, owner = clip_all(*box_simplices(*UNIT_CUBE), normals, offsets)
    check_against_qhull(pieces, owner, A, b)


def test_a_slab_between_parallel_planes_matches_qhull():
    rng = np.random.default_rng(7)
    for _ in range(5):
        n = random_unit(rng, 3)
        c = n @ np.array([0.5, 0.5, 0.5])
        normals, offsets = np.array([n, -n]), np.array([c + 0.1, -(c - 0.15)])
        pieces, owner = clip_all(*box_simplices(*UNIT_CUBE), normals, offsets)
        A, b = cube_halfspaces()
        check_against_qhull(pieces, owner, np.r_[A, normals], np.r_[b, offsets])


def rotated_box_planes(rng, centre, half) -> tuple[np.ndarray, np.ndarray]:
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    normals = np.r_[Q.T, -Q.T]                                    # rows: the box's outward face normals
    offsets = np.r_[Q.T @ centre + half, -(Q.T @ centre) + half]
    return normals, offsets


def test_a_rotated_box_inside_the_cube_keeps_its_volume_and_centre():
    rng = np.random.default_rng(11)
    centre, half = np.array([0.5, 0.45, 0.55]), 0.2             # half-diagonal 0.35: inside the cube
    normals, offsets = rotated_box_planes(rng, centre, half)
    pieces, owner = clip_all(*box_simplices(*UNIT_CUBE), normals, offsets)
    volume, centroid = volumes_and_centroids(pieces, owner, 1)
    assert volume[0] == pytest.approx(0.4 ** 3, rel=1e-13)
    assert np.allclose(centroid[0], centre, atol=1e-14)


def test_a_rotated_box_across_the_cube_matches_qhull():
    rng = np.random.default_rng(12)
    for _ in range(5):
        normals, offsets = rotated_box_planes(rng, rng.uniform(0.2, 0.8, 3), 0.4)
        pieces, owner = clip_all(*box_simplices(*UNIT_CUBE), normals, offsets)
        A, b = cube_halfspaces()
        check_against_qhull(pieces, owner, np.r_[A, normals], np.r_[b, offsets])


def test_squares_clipped_by_lines_match_shapely():
    rng = np.random.default_rng(3)
    h = 0.5
    i, j = np.meshgrid(np.arange(4), np.arange(4), indexing="ij")
    lo = np.stack([i.ravel(), j.ravel()], axis=1) * h + rng.uniform(-0.1, 0.1, 2)
    hi = lo + h
    for _ in range(10):
        normals = np.array([random_unit(rng, 2) for _ in range(3)])
        offsets = normals @ np.array([1.0, 1.0]) + rng.uniform(0.2, 0.8, 3)      # at 0.2 .. 0.8 from the middle
        pieces, owner = clip_all(*box_simplices(lo, hi), normals, offsets)
        area, centroid = volumes_and_centroids(pieces, owner, len(lo))
        region = half_plane(normals[0], offsets[0])
        for n, c in zip(normals[1:], offsets[1:]):
            region = region.intersection(half_plane(n, c))
        cells = shapely.intersection(shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1]), region)
        exact = shapely.area(cells)
        assert np.allclose(area, exact, rtol=0, atol=1e-13)
        assert np.sum(exact > 0.01 * h * h) >= 3                  # some cells are cut or whole
        full = exact > 1e-3 * h * h
        exact_centroid = shapely.get_coordinates(shapely.centroid(cells[full]))
        assert np.allclose(centroid[full], exact_centroid, rtol=0, atol=1e-11)
        assert np.all(signed_volume(pieces) > 0)


# --- triangles in 3D ----------------------------------------------------------------------------------------


def test_a_tilted_square_face_clipped_by_grid_cubes_matches_shapely_in_its_plane():
    rng = np.random.default_rng(5)
    normal = random_unit(rng, 3)
    e1 = np.cross(normal, random_unit(rng, 3))
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)                                     # e1 x e2 = normal
    origin = 1.5 + rng.uniform(-0.05, 0.05, 3)
    angle = rng.uniform(0, np.pi)
    turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) @ turn.T        # side 2, counter-clockwise
    corners = origin + square @ np.array([e1, e2])                                  # (4, 3)
    triangles = corners[[[0, 1, 2], [0, 2, 3]]]                                     # (2, 3, 3)
    cell = np.array(list(product(range(3), repeat=3)), float)                       # a 3 x 3 x 3 grid, h = 1
    n = len(cell)
    vertices = np.tile(triangles, (n, 1, 1))
    owner = np.repeat(np.arange(n), 2)
    normals = np.broadcast_to(np.r_[np.eye(3), -np.eye(3)], (n, 6, 3))
    offsets = np.c_[cell + 1, -cell]
    pieces, piece_owner = clip_all(vertices, owner, normals, offsets)
    area = sums(piece_owner, measure(pieces), n)
    # the cube in the plane's coordinates q: (origin + q1 e1 + q2 e2) . (+-e_i) <= offset
    frame = np.array([e1, e2]).T                                                     # (3, 2)
    exact = np.empty(n)
    for c in range(n):
        region = shapely.Polygon(square)
        for m, o in zip(normals[c], offsets[c]):
            region = region.intersection(half_plane(m @ frame, o - m @ origin))
        exact[c] = region.area
    assert exact.sum() == pytest.approx(4.0, rel=1e-14)
    assert np.sum(exact > 1e-3) >= 4
    assert np.allclose(area, exact, rtol=0, atol=1e-13)
    assert np.all(np.cross(pieces[:, 1] - pieces[:, 0], pieces[:, 2] - pieces[:, 0]) @ normal > 0)
    # a cubic over the pieces of all cells: the tensor Gauss rule over the square in its own coordinates
    f = lambda x: 1 + x[:, 0] ** 3 - x[:, 0] * x[:, 1] * x[:, 2] + 2 * x[:, 1] ** 2
    x, weight, _ = quadrature(pieces, piece_owner, 3)
    g, gw = np.polynomial.legendre.leggauss(3)
    a, b = np.meshgrid(g, g, indexing="ij")
    q = np.stack([a.ravel(), b.ravel()], axis=1) @ turn.T
    exact_integral = np.sum(np.outer(gw, gw).ravel() * f(origin + q @ np.array([e1, e2])))
    assert np.sum(weight * f(x)) == pytest.approx(exact_integral, rel=1e-13)


# --- vertices on the plane ----------------------------------------------------------------------------------


@pytest.mark.parametrize("normal, c, exact", [
    ((1, 0, 0), 1.0, 1.0),                 # the cube's own face: all kept
    ((-1, 0, 0), 0.0, 1.0),
    ((1, 0, 0), 0.0, 0.0),                 # only the face itself inside: nothing left
    ((1, 1, 1), 1.0, 1 / 6),               # through three vertices
    ((1, 1, 1), 2.0, 5 / 6),
    ((1, 1, 1), 0.0, 0.0),                 # through one vertex
    ((-1, -1, -1), -3.0, 0.0),
    ((1, -1, 0), 0.0, 0.5),                # along the Kuhn tetrahedra's faces
    ((1, 1, 0), 1.0, 0.5),                 # across them, through four vertices
])
def test_planes_through_vertices_leave_the_right_volume_and_no_slivers(normal, c, exact):
    vertices, owner = box_simplices(*UNIT_CUBE)
    pieces, piece_owner = clip(vertices, owner, np.array(normal, float), c)
    assert sums(piece_owner, measure(pieces), 1)[0] == pytest.approx(exact, rel=1e-14, abs=1e-16)
    assert np.all(measure(pieces) > 1e-3)
    assert np.all(signed_volume(pieces) > 0)
    if exact == 1.0:
        assert np.array_equal(pieces, vertices)


def test_a_square_clipped_by_its_diagonal_and_its_own_sides():
    vertices, owner = box_simplices(np.zeros((1, 2)), np.ones((1, 2)))
    for normal, c, exact in [((1, -1), 0.0, 0.5), ((1, 1), 1.0, 0.5), ((1, 0), 1.0, 1.0), ((0, 1), 0.0, 0.0)]:
        pieces, piece_owner = clip(vertices, owner, np.array(normal, float), c)
        assert sums(piece_owner, measure(pieces), 1)[0] == pytest.approx(exact, rel=1e-15, abs=1e-16)
        assert np.all(measure(pieces) > 1e-3)


# --- per-simplex planes and many simplices ------------------------------------------------------------------


def test_a_plane_per_simplex_splits_each_into_complementary_parts():
    rng = np.random.default_rng(9)
    vertices = rng.normal(size=(200, 4, 3))
    normals = rng.normal(size=(200, 3))
    offsets = np.einsum("md,md->m", normals, vertices.mean(axis=1) + 0.3 * rng.normal(size=(200, 3)))
    owner = np.arange(200)
    inside, inside_owner = clip(vertices, owner, normals, offsets)
    outside, outside_owner = clip(vertices, owner, -normals, -offsets)
    total = sums(inside_owner, measure(inside), 200) + sums(outside_owner, measure(outside), 200)
    assert np.allclose(total, measure(vertices), rtol=1e-12, atol=0)
    for i in (0, 17, 199):                                        # the same as the plane alone
        alone, _ = clip(vertices[i:i + 1], owner[i:i + 1], normals[i], offsets[i])
        assert np.array_equal(alone, inside[inside_owner == i])


def test_clipping_a_hundred_thousand_tetrahedra_at_once():
    rng = np.random.default_rng(1)
    m = 100_000
    vertices = rng.normal(size=(m, 4, 3))
    owner = np.arange(m)
    n = np.array([0.3, -0.5, 0.8])
    inside, inside_owner = clip(vertices, owner, n, 0.1)
    outside, outside_owner = clip(vertices, owner, -n, -0.1)
    cut = np.bincount(np.sum(vertices @ n <= 0.1, axis=1), minlength=5)
    assert np.all(cut > 1000)                                     # every case occurs many times
    total = sums(inside_owner, measure(inside), m) + sums(outside_owner, measure(outside), m)
    assert np.allclose(total, measure(vertices), rtol=1e-11, atol=0)
    assert np.all(np.sign(signed_volume(inside)) == np.sign(signed_volume(vertices))[inside_owner])


# --- bad input ----------------------------------------------------------------------------------------------


def test_bad_input_names_the_bad_value():
    vertices, owner = box_simplices(*UNIT_CUBE)
    with pytest.raises(InputError, match=r"normal shape \(2,\)"):
        clip(vertices, owner, np.ones(2), 0.0)
    with pytest.raises(InputError, match=r"offset shape \(5,\)"):
        clip(vertices, owner, np.ones(3), np.zeros(5))
    with pytest.raises(InputError, match=r"normals shape \(6, 2\)"):
        clip_all(vertices, owner, np.ones((6, 2)), np.zeros(6))
    with pytest.raises(InputError, match=r"owner of shape \(5,\)"):
        clip(vertices, owner[:5], np.ones(3), 0.0)
    with pytest.raises(InputError, match=r"owner 3 is not allowed"):
        clip_all(vertices, owner + 3, np.ones((2, 6, 3)), np.zeros((2, 6)))
    with pytest.raises(InputError, match="degree -1"):
        simplex_rule(3, -1)
    with pytest.raises(InputError, match="degree 2.5"):
        quadrature(vertices, owner, 2.5)
    with pytest.raises(InputError, match="k=4"):
        simplex_rule(4, 2)
    with pytest.raises(InputError, match=r"shape \(5, 4, 2\)"):
        measure(np.zeros((5, 4, 2)))                              # tetrahedra in 2D
    with pytest.raises(InputError, match=r"shape \(5, 5, 4\)"):
        measure(np.zeros((5, 5, 4)))
    with pytest.raises(InputError, match=r"shape \(5, 2, 3\)"):
        clip(np.zeros((5, 2, 3)), np.arange(5), np.ones(3), 0.0)  # segments
    with pytest.raises(InputError, match=r"lo \(2, 4\)"):
        box_simplices(np.zeros((2, 4)), np.ones((2, 4)))
    with pytest.raises(InputError, match=r"box 1 with lo \[0. 0.\]"):
        box_simplices(np.zeros((2, 2)), np.array([[1.0, 1.0], [1.0, 0.0]]))
    with pytest.raises(InputError, match="d=4"):
        kuhn_simplices(4)
    with pytest.raises(InputError, match="owner 7 is not allowed"):
        sums(np.array([0, 7]), np.ones(2), 3)
    assert issubclass(InputError, ValueError)
