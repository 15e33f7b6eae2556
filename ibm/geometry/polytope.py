"""Convex polytopes as sets of simplices: clipping by half-spaces and exact Gauss quadrature.

A region (a grid cell, a cell cut by a convex body and by slabs {phi < delta}, a planar face
piece) is a set of k-simplices in d-space: triangles (k = 2) in 2D or 3D, tetrahedra (k = 3)
in 3D, each an array (k + 1, d) of vertices, with an `owner` index (the cell, say) per simplex.

Clipping by the half-space {x . n <= c} uses the signed distances s_i = x_i . n - c of the
vertices (s_i <= 0 counts as inside) and splits the inside part by the number of inside
vertices, all simplices of one case at once. Edge i -> j of a cut simplex meets the plane at
p_ij = (s_j x_i - s_i x_j) / (s_j - s_i). With the inside vertices ordered first:

    triangle      1 in: (x0, p01, p02)              2 in: (x0, x1, p12), (x0, p12, p02)
    tetrahedron   1 in: (x0, p01, p02, p03)
                  2 in: the prism (x0, p02, p03 | x1, p12, p13) -> 3 tetrahedra
                  3 in: the prism (x0, x1, x2 | p03, p13, p23) -> 3 tetrahedra

a prism (a0, a1, a2 | b0, b1, b2) being (a0, a1, a2, b0), (a1, a2, b0, b1), (a2, b0, b1, b2):
its quadrilateral faces are planar (each lies in a face of the simplex or on the plane), so
the split is exact. Pieces keep the orientation of their simplex; pieces of measure below
1e-14 of their simplex's (zero up to round-off: a vertex on the plane) are dropped.

Quadrature maps a rule on the unit k-simplex {t_i >= 0, sum t_i <= 1} affinely:
x(t) = x0 + sum_i t_i (x_i - x0), weight k! |simplex| w. The rule is Stroud's conical product
(the collapsed, Duffy, map) t1 = u1, t2 = (1 - u1) u2, t3 = (1 - u1)(1 - u2) u3 with Jacobian
(1 - u1)^(k-1) (1 - u2)^(k-2): Gauss-Jacobi points for the weight (1 - u)^(k-i) in u_i. A monomial
of total degree p in t has degree <= p in each u_i, so n = p // 2 + 1 points per direction
(exact to degree 2n - 1 >= p) integrate it exactly.
"""
from __future__ import annotations

import math
import operator
from functools import lru_cache
from itertools import permutations

import numpy as np
from scipy.special import roots_jacobi

from ibm.exceptions import InputError

RELATIVE_DROP = 1e-14          # pieces below this fraction of their simplex's measure are dropped


def _shape(vertices) -> tuple[np.ndarray, int, int]:
    """Float vertices (m, k + 1, d) with their k and d; InputError unless k, d in {2, 3}, k <= d."""
    vertices = np.asarray(vertices, dtype=float)
    if vertices.ndim != 3 or vertices.shape[1] - 1 not in (2, 3) or vertices.shape[2] not in (2, 3) \
            or vertices.shape[1] - 1 > vertices.shape[2]:
        raise InputError(f"vertices of shape {vertices.shape} are not allowed; allowed: (m, k + 1, d) "
                         f"with k = 2 or 3 and d = 2 or 3, k <= d")
    return vertices, vertices.shape[1] - 1, vertices.shape[2]


def _owner(owner, m: int) -> np.ndarray:
    owner = np.asarray(owner)
    if owner.shape != (m,) or (m and not np.issubdtype(owner.dtype, np.integer)):
        raise InputError(f"owner of shape {owner.shape} and dtype {owner.dtype} is not allowed; "
                         f"allowed: integers of shape ({m},), one per simplex")
    return owner.astype(int, copy=False)


def _degree(degree) -> int:
    try:
        if isinstance(degree, bool):
            raise TypeError
        degree = operator.index(degree)
    except TypeError:
        raise InputError(f"degree {degree!r} is not allowed; allowed: an integer >= 0") from None
    if degree < 0:
        raise InputError(f"degree {degree} is not allowed; allowed: an integer >= 0")
    return degree


def kuhn_simplices(d: int) -> np.ndarray:
    """The Kuhn (Freudenthal) triangulation of the unit d-cube: (d!, d + 1, d) positive simplices.

    Simplex pi runs 0 -> e_pi(1) -> e_pi(1) + e_pi(2) -> ... -> (1, ..., 1) for each permutation
    pi; its orientation is the sign of pi, so odd ones have their last two vertices swapped.
    """
    if d not in (2, 3):
        raise InputError(f"dimension d={d} is not allowed; allowed: 2 or 3")
    simplices = []
    for pi in permutations(range(d)):
        corners = np.cumsum(np.concatenate([np.zeros((1, d)), np.eye(d)[list(pi)]]), axis=0)
        inversions = sum(pi[i] > pi[j] for i in range(d) for j in range(i + 1, d))
        if inversions % 2:
            corners[[-2, -1]] = corners[[-1, -2]]
        simplices.append(corners)
    return np.array(simplices)


def box_simplices(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Kuhn simplices of the boxes [lo_i, hi_i]: lo, hi (n, d), d = 2 or 3.

    Returns vertices (n k, d + 1, d), k = d! (2 triangles a square, 6 tetrahedra a cube), all of
    positive orientation, and owner (n k,): the box of each simplex (box-major order).
    """
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    if lo.ndim != 2 or lo.shape != hi.shape or lo.shape[1] not in (2, 3):
        raise InputError(f"box corners of shapes lo {lo.shape}, hi {hi.shape} are not allowed; "
                         f"allowed: both (n, d) with d = 2 or 3")
    if not np.all(hi > lo):
        bad = np.argwhere(~(hi > lo))[0, 0]
        raise InputError(f"box {bad} with lo {lo[bad]} and hi {hi[bad]} is not allowed; allowed: hi > lo")
    reference = kuhn_simplices(lo.shape[1])                                   # (k, d + 1, d)
    vertices = lo[:, None, None, :] + (hi - lo)[:, None, None, :] * reference[None]   # (n, k, d + 1, d)
    owner = np.repeat(np.arange(len(lo)), len(reference))
    return vertices.reshape(-1, lo.shape[1] + 1, lo.shape[1]), owner


def measure(vertices) -> np.ndarray:
    """(m,) length, area or volume of k-simplices (m, k + 1, d): |det E| / k! for k = d, else the
    Gram determinant sqrt(det(E E^T)) / k! (|cross| / 2 for triangles in 3D); E = (x_i - x0)."""
    vertices, k, d = _shape(vertices)
    edges = vertices[:, 1:] - vertices[:, :1]                                 # (m, k, d)
    if k == d:
        return np.abs(np.linalg.det(edges)) / math.factorial(k)
    return np.linalg.norm(np.cross(edges[:, 0], edges[:, 1]), axis=1) / 2


def _plane(normal, offset, m: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """normal (d,) with a float offset, or (m, d) with (m,) offsets -> (m or 1, d), (m or 1,)."""
    normal, offset = np.asarray(normal, dtype=float), np.asarray(offset, dtype=float)
    if normal.shape == (d,) and offset.shape == ():
        return normal[None], offset[None]
    if normal.shape == (m, d) and offset.shape == (m,):
        return normal, offset
    raise InputError(f"a plane of normal shape {normal.shape} and offset shape {offset.shape} is not allowed; "
                     f"allowed: normal ({d},) with a float offset, or normal ({m}, {d}) with offset ({m},)")


def _parity(order: np.ndarray) -> np.ndarray:
    """(m,) True where the permutations order (m, j) are odd (inversion count; j <= 4)."""
    j = order.shape[1]
    inversions = sum((order[:, a] > order[:, b]).astype(int) for a in range(j) for b in range(a + 1, j))
    return inversions % 2 == 1


def _prism(a: list[np.ndarray], b: list[np.ndarray]) -> np.ndarray:
    """(3 m, 4, d) tetrahedra of the prisms a0 a1 a2 | b0 b1 b2 (each (m, d)), prism-major."""
    tetrahedra = np.stack([np.stack(t, axis=1) for t in
                           ((a[0], a[1], a[2], b[0]), (a[1], a[2], b[0], b[1]), (a[2], b[0], b[1], b[2]))],
                          axis=1)                                             # (m, 3, 4, d)
    return tetrahedra.reshape(-1, 4, a[0].shape[1])


def _pieces(w: np.ndarray, s: np.ndarray, inside: int) -> tuple[np.ndarray, int]:
    """Pieces (m p, k + 1, d) of the simplices w (m, k + 1, d) with the `inside` first vertices
    inside (distances s (m, k + 1)), simplex-major with p pieces each, oriented as w."""
    k = w.shape[1] - 1

    def cut(i: int, j: int) -> np.ndarray:                                    # (m, d) p_ij
        si, sj = s[:, i, None], s[:, j, None]
        return (sj * w[:, i] - si * w[:, j]) / (sj - si)

    if k == 2:
        if inside == 1:
            return np.stack([w[:, 0], cut(0, 1), cut(0, 2)], axis=1), 1
        p12, p02 = cut(1, 2), cut(0, 2)
        return np.stack([np.stack([w[:, 0], w[:, 1], p12], axis=1),
                         np.stack([w[:, 0], p12, p02], axis=1)], axis=1).reshape(-1, 3, w.shape[2]), 2
    if inside == 1:
        return np.stack([w[:, 0], cut(0, 1), cut(0, 2), cut(0, 3)], axis=1), 1
    if inside == 2:
        return _prism([w[:, 0], cut(0, 2), cut(0, 3)], [w[:, 1], cut(1, 2), cut(1, 3)]), 3
    return _prism([w[:, 0], w[:, 1], w[:, 2]], [cut(0, 3), cut(1, 3), cut(2, 3)]), 3


def clip(vertices, owner, normal, offset) -> tuple[np.ndarray, np.ndarray]:
    """The parts of the simplices where x . normal <= offset.

    vertices (m, k + 1, d), k = 2 (triangles in 2D or 3D) or 3 (tetrahedra in 3D); owner (m,);
    normal (d,) with a float offset (one plane), or normal (m, d) with offset (m,) (a plane per
    simplex). Returns the pieces' vertices (m', k + 1, d) and owner (m',), pieces in the order
    of their simplices, each oriented as its simplex; a vertex on the plane counts as inside.
    When every simplex is wholly inside, the input arrays themselves come back (not copies).
    """
    vertices, k, d = _shape(vertices)
    owner = _owner(owner, len(vertices))
    normal, offset = _plane(normal, offset, len(vertices), d)
    s = np.einsum("mvd,md->mv", vertices, np.broadcast_to(normal, (len(vertices), d))) - offset[:, None]
    inside = s <= 0                                                           # (m, k + 1)
    count = inside.sum(axis=1)
    if np.all(count == k + 1):
        return vertices, owner
    kept = np.flatnonzero(count == k + 1)
    parts, parents = [vertices[kept]], [kept]
    for n_in in range(1, k + 1):
        which = np.flatnonzero(count == n_in)
        if len(which) == 0:
            continue
        order = np.argsort(~inside[which], axis=1, kind="stable")             # inside vertices first
        w = np.take_along_axis(vertices[which], order[:, :, None], axis=1)
        pieces, p = _pieces(w, np.take_along_axis(s[which], order, axis=1), n_in)
        odd = np.repeat(_parity(order), p)
        pieces[odd] = pieces[odd][:, [*range(k - 1), k, k - 1]]              # keep the orientation
        parent = np.repeat(which, p)
        big = measure(pieces) > RELATIVE_DROP * np.repeat(measure(vertices[which]), p)
        parts.append(pieces[big])
        parents.append(parent[big])
    parent = np.concatenate(parents)
    order = np.argsort(parent, kind="stable")
    return np.concatenate(parts)[order], owner[parent[order]]


def clip_all(vertices, owner, normals, offsets) -> tuple[np.ndarray, np.ndarray]:
    """The parts of the simplices where x . normals[j] <= offsets[j] for every plane j.

    vertices (m, k + 1, d), owner (m,); planes shared by all, normals (p, d) with offsets (p,),
    or per owner, normals (n, p, d) with offsets (n, p) (row owner[i] for simplex i). Clips by
    one plane after another; simplices wholly inside a plane pass it untouched.
    """
    vertices, _, d = _shape(vertices)
    owner = _owner(owner, len(vertices))
    normals, offsets = np.asarray(normals, dtype=float), np.asarray(offsets, dtype=float)
    shared = normals.ndim == 2 and normals.shape[1] == d and offsets.shape == normals.shape[:1]
    per_owner = normals.ndim == 3 and normals.shape[2] == d and offsets.shape == normals.shape[:2]
    if not (shared or per_owner):
        raise InputError(f"planes of normals shape {normals.shape} and offsets shape {offsets.shape} are not "
                         f"allowed; allowed: normals (p, {d}) with offsets (p,), or (n, p, {d}) with (n, p)")
    if per_owner and len(owner) and not (0 <= owner.min() and owner.max() < len(normals)):
        raise InputError(f"owner {owner.max() if owner.min() >= 0 else owner.min()} is not allowed with planes "
                         f"for {len(normals)} owners; allowed: 0 <= owner < {len(normals)}")
    for j in range(normals.shape[-2]):
        if len(vertices) == 0:
            break
        if shared:
            vertices, owner = clip(vertices, owner, normals[j], offsets[j])
        else:
            vertices, owner = clip(vertices, owner, normals[owner, j], offsets[owner, j])
    return vertices, owner


@lru_cache(maxsize=None)
def _collapsed_rule(k: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The conical product rule with n points per direction on the unit k-simplex (read only)."""
    u, w = [], []
    for i in range(k):                                                        # weight (1 - u)^(k - 1 - i)
        x, wx = roots_jacobi(n, k - 1 - i, 0)
        u.append((x + 1) / 2)
        w.append(wx / 2 ** (k - i))
    grids = np.meshgrid(*u, indexing="ij")
    weight = np.prod(np.meshgrid(*w, indexing="ij"), axis=0).ravel()
    points = np.empty((n ** k, k))
    rest = np.ones(n ** k)                                                   # prod_j<i (1 - u_j)
    for i in range(k):
        points[:, i] = rest * grids[i].ravel()
        rest = rest * (1 - grids[i].ravel())
    points.flags.writeable = False
    weight.flags.writeable = False
    return points, weight


def simplex_rule(k: int, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (q, k) on the unit k-simplex {t_i >= 0, sum t_i <= 1} and weights (q,) summing to
    1 / k!, exact for polynomials of total degree <= degree: (degree // 2 + 1)^k points, so an
    even degree's rule is exact to degree + 1 too. Cached; the arrays are read-only."""
    if k not in (2, 3):
        raise InputError(f"simplex dimension k={k!r} is not allowed; allowed: 2 or 3")
    return _collapsed_rule(k, _degree(degree) // 2 + 1)


def quadrature(vertices, owner, degree: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss points x (m q, d), weights (m q,) and owner (m q,) on the simplices (m, k + 1, d),
    exact for polynomials of total degree <= degree; the weights sum to the total measure
    (area for triangles in 3D). Simplex-major: the q points of simplex i are rows i q .. i q + q - 1."""
    vertices, k, d = _shape(vertices)
    owner = _owner(owner, len(vertices))
    t, w = simplex_rule(k, degree)                                            # (q, k), (q,)
    edges = vertices[:, 1:] - vertices[:, :1]                                 # (m, k, d)
    x = vertices[:, None, 0] + np.einsum("qk,mkd->mqd", t, edges)             # (m, q, d)
    weight = math.factorial(k) * measure(vertices)[:, None] * w[None]         # (m, q)
    return x.reshape(-1, d), weight.ravel(), np.repeat(owner, len(w))


def sums(owner, values, n: int) -> np.ndarray:
    """Per-owner sums of values (m,) or (m, c) -> (n,) or (n, c), owner (m,) in 0 .. n - 1."""
    values = np.asarray(values, dtype=float)
    if values.ndim not in (1, 2):
        raise InputError(f"values of shape {values.shape} are not allowed; allowed: (m,) or (m, c)")
    owner = _owner(owner, len(values))
    if len(owner) and not (0 <= owner.min() and owner.max() < n):
        raise InputError(f"owner {owner.max() if owner.min() >= 0 else owner.min()} is not allowed; "
                         f"allowed: 0 <= owner < n = {n}")
    if values.ndim == 1:
        return np.bincount(owner, values, minlength=n).astype(float, copy=False)
    c = values.shape[1]
    slot = owner[:, None] * c + np.arange(c)                                  # (m, c)
    return np.bincount(slot.ravel(), values.ravel(), minlength=n * c).astype(float, copy=False).reshape(n, c)


def volumes_and_centroids(vertices, owner, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-owner measure (n,) and centroid (n, d) of the simplices (m, k + 1, d), exactly: the
    measure-weighted mean of the simplices' vertex means; centroid 0 where an owner has none."""
    vertices = _shape(vertices)[0]
    size = measure(vertices)
    volume = sums(owner, size, n)
    moment = sums(owner, size[:, None] * vertices.mean(axis=1), n)
    return volume, moment / np.where(volume > 0, volume, 1.0)[:, None]


# edges (sorted-vertex pairs) a plane between the levels of a tetrahedron's vertices crosses,
# in cyclic order around the cross-section, by the number of vertices below the plane
LAYER_EDGES = {1: ((0, 1), (0, 2), (0, 3)), 2: ((0, 2), (0, 3), (1, 3), (1, 2)), 3: ((0, 3), (1, 3), (2, 3))}


def slab(vertices, owner, normal, low: float, high: float) -> tuple[np.ndarray, np.ndarray]:
    """The parts of tetrahedra (m, 4, 3) where low <= x . normal <= high, as tetrahedra.

    Clipping by the two planes one after the other splits a tetrahedron into up to nine
    pieces; here the slab is cut at the levels of the vertices inside it into layers, and
    each layer's part is the prism between two cross-sections whose corners lie on the same
    edges (a triangle, or a quadrilateral split into two): three tetrahedra per triangle.
    The prisms' side faces lie in the tetrahedron's faces; a quadrilateral's diagonal face is
    split the same way by both of its prisms, so the pieces tile the part exactly.
    """
    vertices, k, d = _shape(vertices)
    if k != 3:
        raise InputError(f"slab takes tetrahedra (k = 3); got k={k}")
    owner = _owner(owner, len(vertices))
    normal = np.asarray(normal, dtype=float)
    s = vertices @ normal                                                     # (m, 4)
    order = np.argsort(s, axis=1)
    s = np.take_along_axis(s, order, axis=1)
    x = np.take_along_axis(vertices, order[:, :, None], axis=1)               # sorted by level
    levels = np.sort(np.concatenate([np.full((len(s), 1), low), np.clip(s, low, high),
                                     np.full((len(s), 1), high)], axis=1), axis=1)   # (m, 6)
    span = s[:, 3] - s[:, 0]
    pieces, owners = [], []
    for j in range(5):
        a, b = levels[:, j], levels[:, j + 1]
        middle = (a + b) / 2
        layer = np.sum(s < middle[:, None], axis=1)
        thick = b - a > 1e-14 * span
        for count, edges in LAYER_EDGES.items():
            chosen = np.flatnonzero(thick & (layer == count))
            if len(chosen) == 0:
                continue

            def corners(level):                                              # (c, edges, 3)
                points = []
                for i, e in edges:
                    si, se = s[chosen, i], s[chosen, e]
                    t = ((level[chosen] - si) / (se - si))[:, None]
                    points.append(x[chosen, i] + t * (x[chosen, e] - x[chosen, i]))
                return np.stack(points, axis=1)

            bottom, top = corners(a), corners(b)
            for triangle in ((0, 1, 2),) if len(edges) == 3 else ((0, 1, 2), (0, 2, 3)):
                A, B = bottom[:, list(triangle)], top[:, list(triangle)]
                pieces.append(np.stack([np.stack([A[:, 0], A[:, 1], A[:, 2], B[:, 0]], axis=1),
                                        np.stack([A[:, 1], A[:, 2], B[:, 0], B[:, 1]], axis=1),
                                        np.stack([A[:, 2], B[:, 0], B[:, 1], B[:, 2]], axis=1)], axis=1).reshape(-1, 4, 3))
                owners.append(np.repeat(chosen, 3))
    if not pieces:
        return np.zeros((0, 4, 3)), np.zeros(0, owner.dtype)
    parent = np.concatenate(owners)
    order = np.argsort(parent, kind="stable")                                 # pieces in their parents' order
    pieces, parent = np.concatenate(pieces)[order], parent[order]
    keep = measure(pieces) > RELATIVE_DROP * measure(vertices)[parent]
    return pieces[keep], owner[parent[keep]]
