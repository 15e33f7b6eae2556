"""The bands of essential arcs: annular sectors, integrated in polar coordinates.

An essential arc (ibm.geometry.walls.ArcWall, centre c, radius R, side sign) has the band
A = {phi < delta} = the annular sector between rho = R and rho = R - sign delta of its wedge.
Its edges are circles, so the polygon machinery of ibm.quadrature.bands meets them only through one
polygon that stands in for the body near the arc: the body with the arc replaced by a polyline
just beyond it, off the body (body_ring). A piece (a polygon within one cell, one region of the
straight walls, and the sector's hull) is then integrated over its part inside A (regions of the
arc's band) or over its part on the body's side of A (regions of straight walls near the arc:
rho < R - delta on a convex arc, rho > R + delta beside a hole) by slicing in polar coordinates
about c: between consecutive angles of the piece's vertices and of its edges' crossings with the
circles, a ray meets the same edges in the same order, so each slice is a union of sets
{theta0 < theta < theta1, rho_low(theta) < rho < rho_high(theta)} with rho_low, rho_high a
circle's radius or an edge's line p / cos(theta - alpha). Tensor Gauss-Legendre rules in
(theta, rho) with the Jacobian rho integrate the smooth band integrands there to rounding
(ORDER points per direction; shown by refinement in tests/ibm/quadrature/test_curved_bands.py).
"""
from __future__ import annotations

import numpy as np
import shapely

from ibm.geometry.arcs import Lines
from ibm.geometry.outline import Body
from ibm.geometry.walls import ArcWall

from ibm.exceptions import InputError

ORDER = 8          # Gauss points per direction of a polar slice
_STEP = np.radians(2.0)


def band_radii(wall: ArcWall, delta: float) -> tuple[float, float]:
    """The band's radii (low, high): [R - delta, R] on a convex arc, [R, R + delta] on a hole."""
    return (wall.radius - delta, wall.radius) if wall.sign > 0 else (wall.radius, wall.radius + delta)


def hull(wall: ArcWall, delta: float) -> np.ndarray:
    """(m, 2) a polygon holding the sector wall.radius -+ 1.5 delta of the wedge (both sides of the arc)."""
    return wall.sector(wall.radius - 1.5 * delta, wall.radius + 1.5 * delta)


def _polyline(wall: ArcWall, delta: float) -> np.ndarray:
    """(m, 2) a polyline beyond the arc, off the body, over the wedge, in the arc's sense of travel:
    tangent to the circle R + delta / 2 (convex) or its chords at R - delta / 2 (a hole)."""
    count = int(np.ceil(wall.sweep / _STEP))
    theta = wall.theta0 + np.linspace(0.0, wall.sweep, count + 1)
    radius = wall.radius + wall.sign * delta / 2
    ends = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    if wall.sign > 0:   # corners of the tangents at theta: at the mid angles, radius / cos(step / 2)
        mid = (theta[:-1] + theta[1:]) / 2
        inner = radius / np.cos(wall.sweep / count / 2) * np.stack([np.cos(mid), np.sin(mid)], axis=1)
        points = np.concatenate([radius * ends[:1], inner, radius * ends[-1:]])
    else:
        points = radius * ends
    points = wall.center + points
    return points if wall.sign > 0 else points[::-1]      # a hole's arc runs clockwise


def body_ring(body: Body, delta: float, lines: list[Lines] | None = None) -> np.ndarray:
    """(m, 2) the chord polygon of the body (ibm.geometry.outline.Body.chords) with each essential arc
    replaced by a polyline just off the body (_polyline); its neighbours are radial, so the
    polylines join them along their lines."""
    arcs = {wall.pieces[0]: wall for wall in body.walls if wall.curved}
    ring, _ = body.chords(lines=lines)
    # the chord ring lists each piece's start vertex, then an arc's inner chord points: rebuild it
    # piece by piece, the essential arcs (and their end vertices) replaced
    starts = [int(np.flatnonzero(np.all(ring == body.vertices[k], axis=1))[0]) for k in range(body.n_edges)]
    n = body.n_edges
    parts = []
    for k in range(n):
        if k in arcs:
            parts.append(_polyline(arcs[k], delta))
            continue
        end = starts[k + 1] if k + 1 < n else len(ring)
        piece = ring[starts[k]:end]
        if (k - 1) % n in arcs:       # its start vertex is the replaced arc's end
            piece = piece[1:]
        parts.append(piece)
    return np.concatenate(parts)


def check_arcs(body: Body, delta: float) -> None:
    """Essential arcs need their band clear of every other arc piece and of other arcs' bands, and
    a straight roller whose band overlaps a roller arc's must lie on a radius of the arc."""
    curved = [wall for wall in body.walls if wall.curved]
    if not curved:
        return
    outline, pieces = body.polyline(np.radians(1.0))
    segments = shapely.linestrings(np.stack([outline, np.roll(outline, -1, axis=0)], axis=1))
    for wall in curved:
        zone = shapely.Polygon(hull(wall, delta))
        k = wall.pieces[0]
        for j in np.unique(pieces[shapely.intersects(segments, zone)]):
            if body.arcs[j] is not None and j != k:
                raise InputError(f"arc pieces {k} and {j} come within the band width delta={delta:.6g} of each "
                                 "other; an essential arc's band must meet no other arc")
        for other in body.walls:
            if other is wall or not shapely.intersects(zone, shapely.Polygon(_box(other, delta))):
                continue
            if other.curved:
                raise InputError(f"the bands of essential arcs {k} and {other.pieces[0]} overlap "
                                 f"(delta={delta:.6g}); an essential arc's band must meet no other arc")
            if wall.kind == other.kind == "roller" and abs(float((wall.center - other.start) @ other.normal)) \
                    > 1e-9 * wall.radius:
                raise InputError(f"roller edge {other.pieces[0]} meets roller arc {k} inside the band width "
                                 "off a radius of the arc; a straight roller may overlap a roller arc's band "
                                 "only along a radius")


def _box(wall, delta: float) -> np.ndarray:
    return hull(wall, delta) if wall.curved else wall.box(delta)


def width_across(body: Body, wall: ArcWall) -> float:
    """The body's smallest width in front of the arc, along its inward normals (20 rays, off the
    wedge's sides, where a ray would run along the body's edge)."""
    shape = shapely.Polygon(body.ring())
    theta = wall.theta0 + (np.arange(20) + 0.5) / 20 * wall.sweep
    start = wall.center + wall.radius * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    inward = wall.normal_at(start)
    reach = 4 * np.ptp(body.vertices, axis=0).max() + 4 * wall.radius
    # step off the arc by a rounding error so the ray starts inside the body
    a = start + 1e-9 * wall.radius * inward
    rays = shapely.linestrings(np.stack([a, a + reach * inward], axis=1))
    crossed = shapely.intersection(rays, shape)
    first = [shapely.get_geometry(g, 0) if shapely.get_num_geometries(g) > 1 else g for g in crossed]
    return float(min(shapely.length(first)))


# --- polar slicing ---------------------------------------------------------------------------

def _edges(geometry) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points (E, 2) of every ring edge of a (multi)polygon."""
    rings = shapely.get_rings(shapely.get_parts(geometry))
    coordinates, index = shapely.get_coordinates(rings, return_index=True)
    same = index[1:] == index[:-1]
    return coordinates[:-1][same], coordinates[1:][same]


def _circle_crossings(a, b, center, radius) -> np.ndarray:
    """Points where segments a -> b (E, 2) cross the circle |x - center| = radius."""
    d, f = b - a, a - center
    A, Bh, C = np.sum(d * d, 1), np.sum(f * d, 1), np.sum(f * f, 1) - radius ** 2
    disc = Bh ** 2 - A * C
    ok = disc >= 0
    root = np.sqrt(np.where(ok, disc, 0.0))
    t = np.concatenate([(-Bh - root) / A, (-Bh + root) / A])
    edge = np.concatenate([np.arange(len(a))] * 2)
    keep = np.concatenate([ok, ok]) & (t > 0) & (t < 1)
    return a[edge[keep]] + t[keep, None] * d[edge[keep]]


def polar_pieces(pieces: np.ndarray, owners: np.ndarray, wall: ArcWall, delta: float, inside: bool,
                 order: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss points (m, 2), weights (m,) and owner (m,) (an entry of `owners`) over the parts of the
    shapely `pieces` (n,) inside the arc's band (inside=True) or on the body's side of it (see the
    module doc).
    Every piece must lie in the wall's hull (so away from the centre and within the wedge's angles)."""
    low, high = band_radii(wall, delta)
    mid_angle = wall.theta0 + wall.sweep / 2
    g, wg = np.polynomial.legendre.leggauss(order or ORDER)
    c = wall.center
    xs, ws, own = [], [], []
    for piece, owner in zip(pieces, owners):   # band cells only; vectorised within a piece
        if piece is None or shapely.is_empty(piece):
            continue
        a, b = _edges(piece)
        d = b - a
        vertices = np.concatenate([a, _circle_crossings(a, b, c, low), _circle_crossings(a, b, c, high)])

        def angle(x):
            return np.mod(np.arctan2(x[:, 1] - c[1], x[:, 0] - c[0]) - mid_angle + np.pi, 2 * np.pi) - np.pi

        if len(a) == 0:
            continue
        breaks = np.unique(angle(vertices))
        breaks = breaks[np.concatenate([[True], np.diff(breaks) > 1e-13])]
        if len(breaks) < 2:
            continue
        t0, t1 = breaks[:-1], breaks[1:]                                  # (K,) slices
        tm = (t0 + t1) / 2
        alpha_a, alpha_b = angle(a), angle(b)
        crosses = (np.minimum(alpha_a, alpha_b)[None] < tm[:, None]) & (np.maximum(alpha_a, alpha_b)[None] > tm[:, None])

        def rho(theta, e):             # radius where the ray at local angle theta meets edge e's line
            u = np.stack([np.cos(theta + mid_angle), np.sin(theta + mid_angle)], axis=-1)
            num = (a[e, 0] - c[0]) * d[e, 1] - (a[e, 1] - c[1]) * d[e, 0]
            return num / (u[..., 0] * d[e, 1] - u[..., 1] * d[e, 0])

        K, E = crosses.shape
        r_mid = np.where(crosses, rho(tm[:, None] + 0 * crosses, np.broadcast_to(np.arange(E), (K, E))), np.inf)
        order_e = np.argsort(r_mid, axis=1)
        count = crosses.sum(axis=1)                                        # even: enter, leave, ...
        for j in range(0, int(count.max(initial=0)), 2):
            has = count > j + 1
            k = np.flatnonzero(has)
            e_in, e_out = order_e[k, j], order_e[k, j + 1]
            r_in, r_out = r_mid[k, e_in], r_mid[k, e_out]
            # each interval against the band: inside gives [max(in, low), min(out, high)],
            # outside gives [in, min(out, low)] and [max(in, high), out]; -1 marks an end on a circle
            if inside:
                spans = [(np.maximum(r_in, low), np.minimum(r_out, high), np.where(r_in >= low, e_in, -1),
                          np.where(r_out <= high, e_out, -2))]
            elif wall.sign > 0:
                spans = [(r_in, np.minimum(r_out, low), e_in, np.where(r_out <= low, e_out, -1))]
            else:
                spans = [(np.maximum(r_in, high), r_out, np.where(r_in >= high, e_in, -2), e_out)]
            for lo_mid, hi_mid, e_lo, e_hi in spans:
                ok = hi_mid > lo_mid
                if not np.any(ok):
                    continue
                kk, e_lo, e_hi = k[ok], e_lo[ok], e_hi[ok]
                half = (t1[kk] - t0[kk]) / 2
                theta = (t0[kk] + t1[kk])[:, None] / 2 + half[:, None] * g[None]          # (s, q)
                r_lo, r_hi = (np.where((e == -1)[:, None], low, np.where((e == -2)[:, None], high,
                                                                        rho(theta, np.maximum(e, 0)[:, None])))
                              for e in (e_lo, e_hi))
                r = r_lo[..., None] + (r_hi - r_lo)[..., None] * (g[None, None] + 1) / 2           # (s, q, q)
                weight = (half[:, None, None] * wg[None, :, None]) * ((r_hi - r_lo)[..., None] / 2
                                                                     * wg[None, None]) * r
                angle_x = theta[..., None] + mid_angle
                x = c + r[..., None] * np.stack([np.cos(angle_x) + 0 * r, np.sin(angle_x) + 0 * r], axis=-1)
                xs.append(x.reshape(-1, 2))
                ws.append(weight.ravel())
                own.append(np.full(weight.size, owner))
    if not xs:
        return np.zeros((0, 2)), np.zeros(0), np.zeros(0, int)
    return np.concatenate(xs), np.concatenate(ws), np.concatenate(own)
