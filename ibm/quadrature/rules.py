"""Quadrature on polygons and segments: clipping, fans of quadrilaterals, tensor Gauss rules.

Every region the core integrates over is convex (a convex body, a straight band, a grid
cell, and intersections of those), so a polygon is split into a fan of quadrilaterals
(a triangle is a collapsed one) and each gets a tensor Gauss-Legendre rule through its
bilinear map.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import shapely

ARC_ORDER = 10   # Gauss points along a sub-arc (at most 10 degrees): converged far below 1e-12


@dataclass(frozen=True, eq=False)
class QuadraturePoints:
    """Points x (n, d), weights (n,) and the grid cell (n,) each point belongs to.

    region (n,) or None: for a moment-fitted band rule (ibm.quadrature.moment_fitting), whose nodes may
    lie outside their band region R_S, the bit mask of S per point: the Dirichlet functions
    are then the polynomials of R_S there (ibm.dirichlet.matrix)."""

    x: np.ndarray
    weight: np.ndarray
    cells: np.ndarray
    region: np.ndarray | None = None

    def subset(self, part) -> "QuadraturePoints":
        return QuadraturePoints(self.x[part], self.weight[part], self.cells[part],
                                None if self.region is None else self.region[part])

    @classmethod
    def empty(cls) -> "QuadraturePoints":
        return cls(np.zeros((0, 2)), np.zeros(0), np.zeros(0, int))

    def __len__(self) -> int:
        return len(self.weight)


@lru_cache(maxsize=None)
def square_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """order x order Gauss-Legendre points (m, 2) and weights (m,) on the unit square [0, 1]^2."""
    g, w = np.polynomial.legendre.leggauss(order)
    g, w = (g + 1) / 2, w / 2
    a, b = np.meshgrid(g, g, indexing="ij")
    return np.stack([a.ravel(), b.ravel()], axis=1), np.outer(w, w).ravel()


def order_for_degree(degree: int) -> int:
    """Smallest Gauss order (per direction of a quadrilateral piece) exact for polynomials of the given total degree."""
    return max(1, int(np.ceil((degree + 2) / 2)))


def polygon(vertices: np.ndarray) -> shapely.Polygon:
    return shapely.Polygon(np.asarray(vertices, float))


def clip_boxes(lo: np.ndarray, hi: np.ndarray, region) -> np.ndarray:
    """Shapely polygons of the boxes [lo_i, hi_i] (n, 2) intersected with `region`."""
    return shapely.intersection(shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1]), region)


def fan_quadrilaterals(geoms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadrilaterals (m, 4, 2) fanning each convex polygon, and the index (m,) of its polygon.

    A k-gon v0 ... v(k-1) gives the quadrilaterals (v0, v_i, v_i+1, v_i+2), i = 1, 3, ...,
    and for odd k a last triangle (v0, v_k-2, v_k-1) as a quadrilateral with its last two
    corners equal (the collapsed, Duffy, map). A rectangle of a cut cell is one piece, not two.
    Polygons inside collections (a multipolygon, a polygon with a line beside it) are taken
    part by part; anything else (points, lines, empties) is dropped; a
    polygon that is not convex (a domain clipped by a deformed outline that bends inwards) is
    split into triangles first (constrained Delaunay), each a collapsed quadrilateral.
    """
    geoms = np.asarray(geoms, dtype=object)
    types = shapely.get_type_id(geoms)
    if np.any((types == 6) | (types == 7)):
        # a clip can return polygons with lines or points beside them (a domain edge lying on a
        # cell side): every polygon part counts, for the geometry it came from
        parts, index = shapely.get_parts(geoms, return_index=True)
        quads, owner = fan_quadrilaterals(parts)
        return quads, index[owner]
    keep = np.flatnonzero((types == 3) & (shapely.area(geoms) > 0))
    if len(keep) == 0:
        return np.zeros((0, 4, 2)), np.zeros(0, int)
    bent = _not_convex(geoms[keep])
    if np.any(bent):
        convex_quads, convex_owner = fan_quadrilaterals(geoms[keep[~bent]])
        parts = shapely.get_parts(shapely.constrained_delaunay_triangles(geoms[keep[bent]]), return_index=True)
        triangles = shapely.get_coordinates(parts[0]).reshape(-1, 4, 2)[:, [0, 1, 2, 2]]
        return (np.concatenate([convex_quads, triangles]),
                np.concatenate([keep[~bent][convex_owner], keep[bent][parts[1]]]))
    rings = shapely.get_exterior_ring(geoms[keep])
    coords, owner = shapely.get_coordinates(rings, return_index=True)
    counts = np.bincount(owner, minlength=len(keep)) - 1      # closed rings: k + 1 coordinates
    first = np.concatenate([[0], np.cumsum(counts + 1)[:-1]])
    n_quad = np.maximum(counts - 1, 0) // 2                   # k = 3, 4 -> 1; 5, 6 -> 2; ...
    quad_owner = np.repeat(np.arange(len(keep)), n_quad)
    local = 2 * (np.arange(len(quad_owner)) - np.repeat(np.cumsum(n_quad) - n_quad, n_quad)) + 1
    base = first[quad_owner]
    last = base + counts[quad_owner] - 1                      # v_(k-1)
    corners = [base, base + local, base + local + 1, np.minimum(base + local + 2, last)]
    return np.stack([coords[c] for c in corners], axis=1), keep[quad_owner]


def _not_convex(polygons: np.ndarray) -> np.ndarray:
    """(n,) True where a polygon has a reflex corner (beyond round-off) or a hole."""
    rings = shapely.get_exterior_ring(polygons)
    coords, owner = shapely.get_coordinates(rings, return_index=True)
    edge = np.diff(coords, axis=0)                         # the last edge of one ring runs into the next ring
    same = owner[1:] == owner[:-1]
    edge, edge_owner = edge[same], owner[1:][same]
    following = np.roll(edge, -1, axis=0)
    first = np.concatenate([[0], np.flatnonzero(np.diff(edge_owner)) + 1])
    last = np.concatenate([first[1:] - 1, [len(edge) - 1]])
    following[last] = edge[first]                           # each ring's last edge turns into its first
    cross = edge[:, 0] * following[:, 1] - edge[:, 1] * following[:, 0]
    size = np.bincount(edge_owner, np.sum(edge ** 2, axis=1), minlength=len(polygons))
    orientation = np.where(shapely.is_ccw(rings), 1.0, -1.0)
    reflex = np.bincount(edge_owner, orientation[edge_owner] * cross < -1e-12 * size[edge_owner],
                         minlength=len(polygons)) > 0
    return reflex | (shapely.get_num_interior_rings(polygons) > 0)


def quadrilateral_points(quads: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quadrature points (m*q, 2), weights (m*q,) and quadrilateral index (m*q,) for quads (m, 4, 2).

    The bilinear map x(a, b) of a convex quadrilateral (or a collapsed one, a triangle) has
    a Jacobian linear in a and b, so a polynomial of total degree p in x becomes one of
    degree <= p + 1 in each of a and b: order x order Gauss points integrate it exactly
    when p <= 2 order - 2 (see order_for_degree).
    """
    ref, w = square_rule(order)
    a, b = ref[:, 0][None, :, None], ref[:, 1][None, :, None]               # (1, q, 1)
    P0, P1, P2, P3 = (quads[:, None, k] for k in range(4))                 # (m, 1, 2)
    x = (1 - a) * (1 - b) * P0 + a * (1 - b) * P1 + a * b * P2 + (1 - a) * b * P3
    da = (1 - b) * (P1 - P0) + b * (P2 - P3)                                 # (m, q, 2)
    db = (1 - a) * (P3 - P0) + a * (P2 - P1)
    det = np.abs(da[..., 0] * db[..., 1] - da[..., 1] * db[..., 0])           # one sign on a convex piece
    owner = np.repeat(np.arange(len(quads)), len(w))
    return x.reshape(-1, 2), (det * w[None, :]).ravel(), owner


def grid_crossings(h: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Parameters t of segment a -> b (points (d,)) where it crosses the grid lines (planes) x_i = k h."""
    d = b - a
    breaks = [(h * np.arange(np.ceil(min(a[i], b[i]) / h), np.floor(max(a[i], b[i]) / h) + 1) - a[i]) / d[i]
              for i in range(len(a)) if abs(d[i]) > 0]
    return np.concatenate(breaks) if breaks else np.zeros(0)


def segment_points(a: np.ndarray, b: np.ndarray, breaks: np.ndarray, order: int):
    """Gauss points on segment a -> b split at parameters `breaks` in (0, 1).

    Returns points (m, 2), weights (m,) (length measure) and the midpoint (k, 2) of each
    piece together with the piece index (m,) of each point.
    """
    t = np.unique(np.concatenate([[0.0, 1.0], breaks[(breaks > 0) & (breaks < 1)]]))
    t0, t1 = t[:-1], t[1:]
    keep = t1 - t0 > 1e-14
    t0, t1 = t0[keep], t1[keep]
    g, w = np.polynomial.legendre.leggauss(order)
    s = t0[:, None] + (t1 - t0)[:, None] * (g[None, :] + 1) / 2
    length = np.linalg.norm(b - a)
    weights = (t1 - t0)[:, None] * w[None, :] / 2 * length
    x = a + s.reshape(-1, 1) * (b - a)
    mid = a + ((t0 + t1) / 2)[:, None] * (b - a)
    return x, weights.ravel(), mid, np.repeat(np.arange(len(t0)), order)
