"""Exact quadrature of the band correction.

The bands {0 <= phi_k < delta} of the essential edges are split into disjoint convex
regions R_S = {phi_k < delta for k in S, phi_j >= delta for the other essential edges}
inside the body. On R_S cut by one grid cell the correction integrand
B~^T C B~ - B^T C B is one polynomial of total degree 4 |S| + 2, so a Gauss rule of that
degree on the piece's quadrilaterals (ibm.quadrature) integrates it exactly, whatever delta / h is.
"""
from __future__ import annotations

from itertools import combinations

import numpy as np
import shapely

from ibm.geometry import Body, InputError
from ibm.grid import Grid
from ibm.quadrature import (QuadraturePoints, clip_boxes, fan_quadrilaterals, order_for_degree, polygon,
                            segment_points, quadrilateral_points)


def _half_plane(body: Body, k: int, offset: float, inside: bool) -> shapely.Polygon:
    """The half-plane phi_k <= offset (inside=False) or phi_k >= offset (inside=True), as a big box."""
    size = 4 * float(np.ptp(body.vertices, axis=0).max()) + 4 * abs(offset) + 1.0
    n = body.normals[k]
    t = np.array([n[1], -n[0]])
    base = body.starts[k] + offset * n
    depth = size if inside else -size
    corners = [base - size * t, base + size * t, base + size * t + depth * n, base - size * t + depth * n]
    return shapely.Polygon(corners).normalize()


def check_delta(body: Body, delta: float) -> None:
    """delta must be positive and smaller than half the body's width across every essential edge."""
    if not (np.isfinite(delta) and delta > 0):
        raise InputError(f"band width delta={delta} is not allowed; it must be > 0")
    phi = body.signed_distance(body.vertices)
    for k in body.essential_edges:
        width = phi[:, k].max()
        if delta >= 0.5 * width:
            raise InputError(
                f"band width delta={delta:.6g} is not allowed; it must be < {0.5 * width:.6g} "
                f"(half the body's width across edge {k})")


def band_regions(body: Body, delta: float) -> list[tuple[tuple[int, ...], shapely.Polygon]]:
    """Disjoint convex regions R_S (see module doc) with positive area, keyed by S."""
    check_delta(body, delta)
    shape = polygon(body.vertices)
    essential = body.essential_edges
    near = {k: _half_plane(body, k, delta, inside=False) for k in essential}
    far = {k: _half_plane(body, k, delta, inside=True) for k in essential}
    regions = []
    frontier = [()]
    while frontier:   # grow S only from subsets whose bands meet
        grown = []
        for S in frontier:
            for k in [k for k in essential if not S or k > S[-1]]:
                T = S + (k,)
                meet = shape
                for j in T:
                    meet = shapely.intersection(meet, near[j])
                if meet.area <= 0:
                    continue
                grown.append(T)
                exact = meet
                for j in essential:
                    if j not in T:
                        exact = shapely.intersection(exact, far[j])
                if exact.area > 0:
                    regions.append((T, exact))
        frontier = grown
    _check_commuting(body, regions)
    return regions


def _check_commuting(body: Body, regions) -> None:
    """Reject overlapping bands of rollers whose normals are neither parallel nor orthogonal."""
    for S, _ in regions:
        for a, b in combinations(S, 2):
            if body.kinds[a] == body.kinds[b] == "roller":
                c = abs(float(body.normals[a] @ body.normals[b]))
                if 1e-9 < c < 1 - 1e-9:
                    angle = np.degrees(np.arccos(np.clip(body.normals[a] @ body.normals[b], -1, 1)))
                    raise InputError(
                        f"roller edges {a} and {b} meet at {180 - angle:.6g} degrees inside the band width; "
                        "overlapping roller bands are allowed only for parallel or right-angled rollers")


def _band_cells(body: Body, grid: Grid, delta: float):
    """Cells that may meet a band, and per essential edge k whether each may lie within phi_k < delta
    (`near`) and whether it may reach beyond it (`far`).

    phi_k is linear, so over a cell it ranges from its value at the lower-left corner plus
    h (min(0, n_x) + min(0, n_y)) to that plus h (max(0, n_x) + max(0, n_y)). The margin
    (1e-9 h, far above the rounding of these sums) keeps every cell that could meet a band.
    """
    nx, ny = grid.shape
    n = body.normals
    base = np.sum((grid.origin - body.starts) * n, axis=1)                # phi_k at the grid origin
    # phi_k at each cell's lower-left corner (cell id j nx + i), as an outer sum: (n_edges, n_cells)
    phi = (base[:, None, None] + grid.h * n[:, 0, None, None] * np.arange(nx)[None, None, :]
           + grid.h * n[:, 1, None, None] * np.arange(ny)[None, :, None]).reshape(body.n_edges, -1)
    low = phi + grid.h * (np.minimum(n[:, 0], 0) + np.minimum(n[:, 1], 0))[:, None]
    high = phi + grid.h * (np.maximum(n[:, 0], 0) + np.maximum(n[:, 1], 0))[:, None]
    margin = 1e-9 * grid.h
    inside = np.ones(grid.n_cells, bool)
    for k in range(body.n_edges):
        inside &= high[k] > -margin
    in_some_band = np.zeros(grid.n_cells, bool)
    for k in body.essential_edges:
        in_some_band |= low[k] < delta + margin
    cells = np.flatnonzero(inside & in_some_band)
    near = {k: low[k, cells] < delta + margin for k in body.essential_edges}
    far = {k: high[k, cells] > delta - margin for k in body.essential_edges}
    return cells, near, far


def _may_meet(body: Body, band_cells, S: tuple[int, ...]) -> np.ndarray:
    """Ids of the cells not entirely outside one of R_S's half-planes.

    A rotated band's bounding box holds ~all cells of the body; this keeps the clipping to
    the cells along the band.
    """
    cells, near, far = band_cells
    keep = np.ones(len(cells), bool)
    for k in body.essential_edges:
        keep &= near[k] if k in S else far[k]
    return cells[keep]


def band_quadrature(body: Body, grid: Grid, delta: float) -> QuadraturePoints:
    """Points and weights integrating the band correction exactly, cell by cell.

    Pieces of area below 1e-9 delta h are slivers of rounding (a band edge on a grid line
    computed a few ulps off) and are dropped: they would give nodes outside the body a
    support of ~1e-15 and make the system singular, while adding < 1e-9 of a cell's band.
    """
    x, w, cells = [], [], []
    regions = band_regions(body, delta)
    band_cells = _band_cells(body, grid, delta) if regions else None
    for S, region in regions:
        candidates = _may_meet(body, band_cells, S)
        corner = grid.cell_corners(candidates)
        pieces = clip_boxes(corner, corner + grid.h, region)
        pieces[shapely.area(pieces) < 1e-9 * delta * grid.h] = None
        quads, owner = fan_quadrilaterals(pieces)
        xq, wq, quad = quadrilateral_points(quads, order_for_degree(4 * len(S) + 2))
        x.append(xq)
        w.append(wq)
        cells.append(candidates[owner[quad]])
    if not x:
        return QuadraturePoints.empty()
    return QuadraturePoints(np.concatenate(x), np.concatenate(w), np.concatenate(cells))


def edge_quadrature(body: Body, grid: Grid, edge: int, delta: float | None, order: int = 6) -> QuadraturePoints:
    """Gauss points along one edge, split at grid lines and (if delta) at band boundaries phi_j = delta.

    Each piece lies in one cell and inside one band region, so polynomial integrands
    (N D^T t for polynomial t) of degree <= 2 order - 1 are integrated exactly.
    """
    a, b = body.starts[edge], body.ends[edge]
    d = b - a
    breaks = []
    for axis in range(2):
        if abs(d[axis]) > 0:
            lines = grid.h * np.arange(np.ceil(min(a[axis], b[axis]) / grid.h),
                                       np.floor(max(a[axis], b[axis]) / grid.h) + 1)
            breaks.append((lines - a[axis]) / d[axis])
    if delta is not None:
        phi_a, phi_b = body.signed_distance(np.array([a, b]))
        for j in body.essential_edges:
            if j != edge and abs(phi_b[j] - phi_a[j]) > 0:
                breaks.append(np.array([(delta - phi_a[j]) / (phi_b[j] - phi_a[j])]))
    x, w, mid, piece = segment_points(a, b, np.concatenate(breaks) if breaks else np.zeros(0), order)
    cells = grid.locate_towards(mid, body.normals[edge])   # an edge on a grid line: the body's side
    return QuadraturePoints(x, w, cells[piece])
