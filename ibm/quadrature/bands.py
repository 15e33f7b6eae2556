"""Exact quadrature of the band correction.

The bands {0 <= phi_k < delta} of the essential edges are split into disjoint convex
regions R_S = {phi_k < delta for k in S, phi_j >= delta for the other essential edges}
inside the body. On R_S cut by one grid cell the correction integrand
B~^T C B~ - B^T C B is one polynomial of total degree 4 |S| + 2, so a Gauss rule of that
degree on the piece's quadrilaterals (ibm.quadrature.rules) integrates it exactly, whatever delta / h is.
"""
from __future__ import annotations

from itertools import combinations

import numpy as np
import shapely

from ibm.quadrature import curved_bands
from ibm.geometry import polyhedron
from ibm.geometry.arcs import Lines, grid_lines
from ibm.geometry.outline import Body
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid
from ibm.quadrature.rules import (ARC_ORDER, QuadraturePoints, clip_boxes, fan_quadrilaterals, grid_crossings, order_for_degree,
                            polygon, segment_points, quadrilateral_points)


def cutting_lines(body: Body, grid: Grid, delta: float | None) -> list[Lines]:
    """Where a body's arcs are cut into chords so that each circular segment lies in one grid cell
    and in one region of every wall's band: the grid lines and the lines of the walls' branch
    polygons (band edges, ends, branch switches)."""
    lines = grid_lines(grid.origin, grid.h)
    if delta is None or delta <= 0:
        return lines
    for wall in body.walls:
        if wall.curved:       # the radial sides of its wedge
            for side in wall.sides():
                n = np.array([-side[1], side[0]])
                lines.append(Lines(n, float(n @ wall.center)))
            continue
        for corners in wall.branch_polygons(delta):
            for a, b in zip(corners, np.roll(corners, -1, axis=0)):
                t = (b - a) / np.linalg.norm(b - a)
                n = np.array([-t[1], t[0]])
                lines.append(Lines(n, float(n @ a)))
    return lines


def _polygon(vertices: np.ndarray) -> shapely.Polygon:
    return shapely.Polygon(vertices).normalize()


def check_delta(body: Body, delta: float) -> None:
    """delta must be positive and smaller than half the body's width across every wall."""
    if not (np.isfinite(delta) and delta > 0):
        raise InputError(f"band width delta={delta} is not allowed; it must be > 0")
    shape = polygon(body.ring() if body.arcs else body.vertices)
    curved_bands.check_arcs(body, delta)
    for w, wall in enumerate(body.walls):
        if wall.curved:
            width = curved_bands.width_across(body, wall)
            if delta >= 0.5 * width:
                raise InputError(f"band width delta={delta:.6g} is not allowed; it must be < {0.5 * width:.6g} "
                                 f"(half the body's width across arc {wall.pieces[0]})")
            continue
        # the body's extent in front of the wall, over the wall's own stretch of its line; the strip
        # reaches behind the line too, so that no side of it lies on the wall (GEOS 3.14 intersects
        # a rectangle sharing a side with the body to a point at some placements)
        size = np.ptp(body.vertices, axis=0).max()
        strip = wall.start + np.array([0.0, wall.length, wall.length, 0.0])[:, None] * wall.tangent \
            + np.array([-1.0, -1.0, 4.0, 4.0])[:, None] * size * wall.normal
        across = shapely.intersection(shape, _polygon(strip))
        width = float(wall.local(shapely.get_coordinates(across))[0].max(initial=0.0))
        if delta >= 0.5 * width:
            raise InputError(
                f"band width delta={delta:.6g} is not allowed; it must be < {0.5 * width:.6g} "
                f"(half the body's width across edge {wall.pieces[0]})")


Key = tuple[tuple[int, int], ...]      # ((wall, branch), ...) sorted by wall


def band_regions(body: Body, delta: float, lines: list[Lines] | None = None) -> list[tuple[Key, shapely.Geometry]]:
    """Disjoint regions R_S (see module doc) with positive area, keyed by the walls in S and the
    branch of each wall's distance (Wall.branch_polygons) that holds there. A body with arcs
    enters by its chord polygon (cut at `lines`); band_quadrature adds the circular segments."""
    check_delta(body, delta)
    walls = body.walls
    straight = [w for w, wall in enumerate(walls) if not wall.curved]
    branches = {w: [_polygon(walls[w].branch_polygons(delta)[b]) for b in range(4)] for w in straight}
    boxes = {w: _polygon(walls[w].box(delta)) for w in straight}
    # essential arcs: the body stands in with each arc moved just off it (ibm.quadrature.curved_bands); an arc's
    # regions start from that outline within the sector's hull
    starts: list[tuple[Key, shapely.Geometry]] = []
    if len(straight) < len(walls):
        shape = polygon(curved_bands.body_ring(body, delta, lines))
        for w, wall in enumerate(walls):
            if wall.curved:
                starts.append((((w, 0),), shapely.intersection(shape, _polygon(curved_bands.hull(wall, delta)))))
    else:
        shape = polygon(body.ring(lines=lines) if body.arcs else body.vertices)
    regions = [(S, shapely.simplify(_beyond(part, S, boxes, straight), 1e-9 * delta)) for S, part in starts]
    # where two branch polygons only touch, rounding leaves slivers of ~1e-20 delta^2
    sliver = 1e-9 * delta * delta
    regions = [(S, part) for S, part in regions if part.area > sliver]
    frontier: list[tuple[Key, shapely.Geometry]] = [((), shape)] + starts
    while frontier:   # grow S only from subsets whose bands meet
        grown = []
        for S, meet in frontier:
            for w in [w for w in straight if not S or w > S[-1][0]]:
                for b, branch in enumerate(branches[w]):
                    part = shapely.intersection(meet, branch)
                    if part.area <= sliver:
                        continue
                    T = S + ((w, b),)
                    grown.append((T, part))
                    exact = _beyond(part, T, boxes, straight)
                    if exact.area > sliver:
                        # the branch polygons leave corners on straight sides: drop them (the
                        # fans then match the regions' true corners)
                        regions.append((T, shapely.simplify(exact, 1e-9 * delta)))
        frontier = grown
    _check_commuting(body, regions)
    return regions


def _beyond(part, S: Key, boxes: dict, straight: list[int]):
    """part minus the band rectangles of the straight walls not in S."""
    for j in straight:
        if j not in [v for v, _ in S]:
            part = shapely.difference(part, boxes[j])
    return part


def _check_commuting(body: Body, regions) -> None:
    """Reject overlapping bands of rollers whose normals are neither parallel nor orthogonal."""
    walls = body.walls
    for S, _ in regions:
        for (a, _), (b, _) in combinations(S, 2):
            if walls[a].curved or walls[b].curved:      # curved_bands.check_arcs
                continue
            if walls[a].kind == walls[b].kind == "roller":
                c = abs(float(walls[a].normal @ walls[b].normal))
                if 1e-9 < c < 1 - 1e-9:
                    angle = np.degrees(np.arccos(np.clip(walls[a].normal @ walls[b].normal, -1, 1)))
                    raise InputError(
                        f"roller edges {walls[a].pieces[0]} and {walls[b].pieces[0]} meet at {180 - angle:.6g} "
                        "degrees inside the band width; "
                        "overlapping roller bands are allowed only for parallel or right-angled rollers")


def _ranges(grid: Grid, direction: np.ndarray, base: float) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest value (n_cells,) over each cell of the linear function base + direction . (x - origin)."""
    nx, ny = grid.shape
    at_corner = (base + grid.h * direction[0] * np.arange(nx)[None, :]
                 + grid.h * direction[1] * np.arange(ny)[:, None]).ravel()      # cell id j nx + i
    return (at_corner + grid.h * (min(0, direction[0]) + min(0, direction[1])),
            at_corner + grid.h * (max(0, direction[0]) + max(0, direction[1])))


def _band_cells(body: Body, grid: Grid, delta: float):
    """Cells that may meet a band, and per wall w whether each may lie in its band rectangle
    (`near`) and whether it may reach beyond it (`far`).

    s and t of a wall are linear, so over a cell they range between the values read off
    its lower-left corner (_ranges). The margin (1e-9 h, far above the rounding of these
    sums) keeps every cell that could meet a band. For a convex body, cells wholly outside
    one edge's half-plane are dropped too.
    """
    margin = 1e-9 * grid.h
    inside = np.ones(grid.n_cells, bool)
    if body.convex:
        for k in range(body.n_edges):
            inside &= _ranges(grid, body.normals[k], float((grid.origin - body.starts[k]) @ body.normals[k]))[1] > -margin
    within, beyond = {}, {}
    corners = grid.cell_corners(np.arange(grid.n_cells)) if any(wall.curved for wall in body.walls) else None
    for w, wall in enumerate(body.walls):
        if wall.curved:       # cells within reach of the sector's hull; any may reach beyond it
            nearest = np.clip(wall.center, corners, corners + grid.h)
            far_corner = np.where(np.abs(corners - wall.center) > np.abs(corners + grid.h - wall.center),
                                  corners, corners + grid.h)
            low, high = np.linalg.norm(nearest - wall.center, axis=1), np.linalg.norm(far_corner - wall.center, axis=1)
            within[w] = (low < wall.radius + 1.5 * delta + margin) & (high > wall.radius - 1.5 * delta - margin)
            beyond[w] = np.ones(grid.n_cells, bool)
            continue
        s_low, s_high = _ranges(grid, wall.normal, float((grid.origin - wall.start) @ wall.normal))
        t_low, t_high = _ranges(grid, wall.tangent, float((grid.origin - wall.start) @ wall.tangent))
        t0, t1 = -wall.extend[0] * delta - delta, wall.length + wall.extend[1] * delta + delta
        within[w] = (s_low < delta + margin) & (s_high > -delta - margin) & (t_low < t1 + margin) & (t_high > t0 - margin)
        beyond[w] = ~((s_low > -delta + margin) & (s_high < delta - margin) & (t_low > t0 + margin) & (t_high < t1 - margin))
    in_some_band = np.zeros(grid.n_cells, bool)
    for w in within:
        in_some_band |= within[w]
    cells = np.flatnonzero(inside & in_some_band)
    return cells, {w: v[cells] for w, v in within.items()}, {w: v[cells] for w, v in beyond.items()}


def _may_meet(body: Body, band_cells, S: Key) -> np.ndarray:
    """Ids of the cells that may meet R_S: within the band of every wall of S, beyond the others.

    A rotated band's bounding box holds ~all cells of the body; this keeps the clipping to
    the cells along the band.
    """
    cells, near, far = band_cells
    keep = np.ones(len(cells), bool)
    members = [w for w, _ in S]
    for w in range(len(body.walls)):
        keep &= near[w] if w in members else far[w]
    return cells[keep]


def band_quadrature(body: Body, grid: Grid, delta: float) -> QuadraturePoints:
    """Points and weights integrating the band correction exactly, cell by cell.

    Pieces of area below 1e-9 delta h are slivers of rounding (a band edge on a grid line
    computed a few ulps off) and are dropped: they would give nodes outside the body a
    support of ~1e-15 and make the system singular, while adding < 1e-9 of a cell's band.
    """
    if body.dim == 3:
        return polyhedron.band_quadrature(body, grid, delta)
    x, w, cells = [], [], []
    lines = cutting_lines(body, grid, delta) if body.arcs else None
    regions = band_regions(body, delta, lines)
    band_cells = _band_cells(body, grid, delta) if regions else None
    hulls = {w: _polygon(curved_bands.hull(wall, delta)) for w, wall in enumerate(body.walls) if wall.curved}
    for S, region in regions:
        candidates = _may_meet(body, band_cells, S)
        corner = grid.cell_corners(candidates)
        pieces = clip_boxes(corner, corner + grid.h, region)
        pieces[shapely.area(pieces) < 1e-9 * delta * grid.h] = None
        first = body.walls[S[0][0]]
        if first.curved:      # a region of an arc's band: polar slices of its part inside the band
            xp, wp, owner = curved_bands.polar_pieces(pieces, np.arange(len(pieces)), first, delta, True)
            x.append(xp)
            w.append(wp)
            cells.append(candidates[owner])
            continue
        for wall_id, zone in hulls.items():   # near an arc: polar slices of the part outside its band
            near = np.flatnonzero(~shapely.is_empty(pieces) & shapely.intersects(pieces, zone)) \
                if len(pieces) else np.zeros(0, int)
            if len(near):
                xp, wp, owner = curved_bands.polar_pieces(shapely.intersection(pieces[near], zone), near,
                                                          body.walls[wall_id], delta, False)
                x.append(xp)
                w.append(wp)
                cells.append(candidates[owner])
                pieces[near] = shapely.difference(pieces[near], zone)
        quads, owner = fan_quadrilaterals(pieces)
        xq, wq, quad = quadrilateral_points(quads, order_for_degree(4 * len(S) + 2))
        x.append(xq)
        w.append(wq)
        cells.append(candidates[owner[quad]])
    if body.arcs and body.walls:
        # circular segments beyond the chords (signed): each lies in one cell and in one band
        # region, the walls whose phi < delta at its centroid; Gauss in rho exact for the degree
        segments = body.segments(lines=lines)
        essential_arcs = [wall.pieces[0] for wall in body.walls if wall.curved]
        if essential_arcs:      # theirs lie in their hulls, integrated in polar slices above
            segments = segments.subset(np.flatnonzero(~np.isin(segments.piece, essential_arcs)))
        centre = segments.centroid
        size = np.sum([wall.distance(centre, delta)[0] < delta for wall in body.walls], axis=0)
        for count in np.unique(size[size > 0]):
            mine = np.flatnonzero(size == count)
            xs, ws, which = segments.subset(mine).quadrature(ARC_ORDER, order_for_degree(4 * int(count) + 3))
            x.append(xs)
            w.append(ws)
            cells.append(grid.locate(centre[mine])[which])
    if not x:
        return QuadraturePoints.empty()
    return QuadraturePoints(np.concatenate(x), np.concatenate(w), np.concatenate(cells))


def _kinks(wall, a: np.ndarray, b: np.ndarray, delta: float) -> np.ndarray:
    """Parameters along a -> b where the wall's phi changes branch or crosses delta.

    Along the segment s, t and the branches |s|, -t - e0, t - L - e1 are linear, so every
    candidate is the root of a linear function; extra breaks only split pieces further.
    """
    if wall.curved:
        return _arc_kinks(wall, a, b, delta)
    (s_a, s_b), (t_a, t_b) = wall.local(np.array([a, b]))
    s = np.array([s_a, s_b])
    start = -np.array([t_a, t_b]) - wall.extend[0] * delta
    end = np.array([t_a, t_b]) - wall.length - wall.extend[1] * delta
    functions = [s, s - delta, s + delta, start - delta, end - delta,
                 s - start, s + start, s - end, s + end]                # (f(a), f(b)) pairs
    return np.array([f[0] / (f[0] - f[1]) for f in functions if f[0] != f[1]])


def _arc_kinks(wall, a: np.ndarray, b: np.ndarray, delta: float) -> np.ndarray:
    """Parameters along a -> b where it crosses an arc wall's circles R, R -+ delta or its wedge's sides."""
    d, f = b - a, a - wall.center
    roots = []
    for radius in (wall.radius - delta, wall.radius, wall.radius + delta):
        A, half, C = d @ d, f @ d, f @ f - radius ** 2
        disc = half * half - A * C
        if disc >= 0:
            roots += [(-half - np.sqrt(disc)) / A, (-half + np.sqrt(disc)) / A]
    for side in wall.sides():
        n = np.array([-side[1], side[0]])
        if abs(n @ d) > 0:
            roots.append(-(n @ f) / (n @ d))
    return np.array(roots)


def _arc_quadrature(body: Body, grid: Grid, edge: int, delta: float | None) -> QuadraturePoints:
    """Gauss points along arc piece `edge`, over the sub-arcs of the body's chords cut at the grid
    lines and the walls' band lines (cutting_lines): every sub-arc lies in one cell and one band
    region, where the integrand is analytic in the angle."""
    sub = body.segments(lines=cutting_lines(body, grid, delta))
    sub = sub.subset(np.flatnonzero(sub.piece == edge))
    g, wg = np.polynomial.legendre.leggauss(ARC_ORDER)
    middle = (sub.theta0 + sub.theta1) / 2
    half = (sub.theta1 - sub.theta0) / 2
    theta = (middle[:, None] + half[:, None] * g[None, :]).ravel()
    c = np.repeat(sub.center, ARC_ORDER, axis=0)
    radius = np.repeat(sub.radius, ARC_ORDER)
    x = c + radius[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    weight = (half[:, None] * wg[None, :] * sub.radius[:, None]).ravel()
    mid = sub.center + sub.radius[:, None] * np.stack([np.cos(middle), np.sin(middle)], axis=1)
    cells = grid.locate_towards(mid, -body.outward(edge, mid))     # on a grid line: the body's side
    return QuadraturePoints(x, weight, np.repeat(cells, ARC_ORDER))


def edge_quadrature(body: Body, grid: Grid, edge: int, delta: float | None, order: int = 6) -> QuadraturePoints:
    """Gauss points along one edge, split at grid lines and (if delta) at band boundaries phi_j = delta.

    Each piece lies in one cell and inside one band region, so polynomial integrands
    (N D^T t for polynomial t) of degree <= 2 order - 1 are integrated exactly.
    """
    if body.dim == 3:
        return polyhedron.face_quadrature(body, grid, edge, delta)
    if body.arcs and body.arcs[edge] is not None:
        return _arc_quadrature(body, grid, edge, delta)
    a, b = body.starts[edge], body.ends[edge]
    breaks = [grid_crossings(grid.h, a, b)]
    if delta is not None:
        for wall in body.walls:
            if edge not in wall.pieces:
                breaks.append(_kinks(wall, a, b, delta))
    x, w, mid, piece = segment_points(a, b, np.concatenate(breaks), order)
    cells = grid.locate_towards(mid, body.normals[edge])   # an edge on a grid line: the body's side
    return QuadraturePoints(x, w, cells[piece])
