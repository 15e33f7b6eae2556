"""Quadrature on polygons and segments: clipping, fan triangulation, collapsed Gauss rules.

Every region the core integrates over is convex (a convex body, a straight band, a grid
cell, and intersections of those), so a polygon is split into a fan of triangles and
each triangle gets a collapsed (Duffy) Gauss-Legendre rule.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import shapely


@dataclass(frozen=True, eq=False)
class QuadraturePoints:
    """Points x (n, 2), weights (n,) and the grid cell (n,) each point belongs to."""

    x: np.ndarray
    weight: np.ndarray
    cells: np.ndarray

    @classmethod
    def empty(cls) -> "QuadraturePoints":
        return cls(np.zeros((0, 2)), np.zeros(0), np.zeros(0, int))

    def __len__(self) -> int:
        return len(self.weight)


@lru_cache(maxsize=None)
def triangle_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (m, 2) and weights (m,) on the unit triangle (0,0), (1,0), (0,1).

    order x order collapsed Gauss-Legendre points: exact for polynomials of total degree
    <= 2 order - 2. Weights sum to 1/2.
    """
    g, w = np.polynomial.legendre.leggauss(order)
    g, w = (g + 1) / 2, w / 2
    a, b = np.meshgrid(g, g, indexing="ij")
    wa, wb = np.meshgrid(w, w, indexing="ij")
    u, v = a.ravel(), (b * (1 - a)).ravel()
    return np.stack([u, v], axis=1), (wa * wb).ravel() * (1 - a.ravel())


def order_for_degree(degree: int) -> int:
    """Smallest collapsed-Gauss order exact for polynomials of the given total degree."""
    return max(1, int(np.ceil((degree + 2) / 2)))


def polygon(vertices: np.ndarray) -> shapely.Polygon:
    return shapely.Polygon(np.asarray(vertices, float))


def clip_boxes(lo: np.ndarray, hi: np.ndarray, region) -> np.ndarray:
    """Shapely polygons of the boxes [lo_i, hi_i] (n, 2) intersected with `region`."""
    return shapely.intersection(shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1]), region)


def fan_triangles(geoms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles (m, 3, 2) fanning each convex polygon, and the index (m,) of its polygon.

    Anything that is not a polygon of positive area (points, lines, empties) is dropped.
    """
    geoms = np.asarray(geoms, dtype=object)
    keep = np.flatnonzero((shapely.get_type_id(geoms) == 3) & (shapely.area(geoms) > 0))
    if len(keep) == 0:
        return np.zeros((0, 3, 2)), np.zeros(0, int)
    rings = shapely.get_exterior_ring(geoms[keep])
    coords, owner = shapely.get_coordinates(rings, return_index=True)
    counts = np.bincount(owner, minlength=len(keep))          # closed rings: k + 1 coordinates
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    n_tri = np.maximum(counts - 3, 0)
    tri_owner = np.repeat(np.arange(len(keep)), n_tri)
    local = np.arange(len(tri_owner)) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
    base = first[tri_owner]
    tris = np.stack([coords[base], coords[base + local], coords[base + local + 1]], axis=1)
    return tris, keep[tri_owner]


def triangle_points(tris: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quadrature points (m*q, 2), weights (m*q,) and triangle index (m*q,) for triangles (m, 3, 2)."""
    ref, w = triangle_rule(order)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    det = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    x = tris[:, None, 0] + ref[None, :, :1] * e1[:, None] + ref[None, :, 1:] * e2[:, None]
    weights = det[:, None] * w[None, :]
    owner = np.repeat(np.arange(len(tris)), len(w))
    return x.reshape(-1, 2), weights.ravel(), owner


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
