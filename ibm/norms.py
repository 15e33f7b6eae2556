"""Error measures, one definition for every method (docs/usage.md, "Errors").

err_u     = sqrt(sum_p V_p |u_h - u|^2 / sum_p V_p |u|^2)
err_sigma = the same for the problem's reported stress component (e.g. sigma_eta_eta)
*_max     = max_p |h - exact| / max_p |exact|
err_sigma_fro: the whole stress tensor (in-plane and zz) in the Frobenius norm.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from ibm.discretise.assembly import VOIGT
from ibm.quadrature import curved_bands
from ibm.geometry import polyhedron
from ibm.quadrature.bands import cutting_lines
from ibm.discretise.points import classify_boxes
from ibm.quadrature.rules import ARC_ORDER, QuadraturePoints, clip_boxes, fan_quadrilaterals, polygon, quadrilateral_points


def _relative(volume, error_sq, exact_sq):
    return _ratio(np.sum(volume * error_sq), np.sum(volume * exact_sq))


def _ratio(error: float, exact: float) -> float:
    """sqrt(error / exact) of two weighted sums. A moment-fitted 3D rule has negative weights: where
    the error is round-off its sum can come out a rounding error below zero (positive weights, as in
    2D, never do); it is zero."""
    error = max(float(error), 0.0)
    return float(np.sqrt(error / exact)) if exact > 0 else float(np.sqrt(error))


def _relative_max(error_abs, exact_abs):
    top = exact_abs.max(initial=0.0)
    return float(error_abs.max(initial=0.0) / top) if top > 0 else float(error_abs.max(initial=0.0))


def stress_component(sigma: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """d . sigma . d for sigma (n, 2, 2) and a unit direction d (2,)."""
    return np.einsum("i,pij,j->p", direction, sigma, direction)


def point_errors(volume, u_h, u, sigma_h, sigma, sigma_zz_h, sigma_zz, direction) -> dict:
    """The material-point errors of docs/usage.md, as a dict of floats."""
    du = np.sum((u_h - u) ** 2, axis=1)
    s_h, s = stress_component(sigma_h, direction), stress_component(sigma, direction)
    out_of_plane = sigma.shape[1] == 2          # in 3D sigma_zz is an entry of sigma already
    ds_full = np.sum((sigma_h - sigma) ** 2, axis=(1, 2)) + out_of_plane * (sigma_zz_h - sigma_zz) ** 2
    s_full = np.sum(sigma ** 2, axis=(1, 2)) + out_of_plane * sigma_zz ** 2
    return {
        "err_u": _relative(volume, du, np.sum(u ** 2, axis=1)),
        "err_sigma": _relative(volume, (s_h - s) ** 2, s ** 2),
        "err_sigma_fro": _relative(volume, ds_full, s_full),
        "err_u_max": _relative_max(np.sqrt(du), np.linalg.norm(u, axis=1)),
        "err_sigma_max": _relative_max(np.abs(s_h - s), np.abs(s)),
    }


def pointwise_relative(u_h, u, sigma_h, sigma, direction) -> tuple[np.ndarray, np.ndarray]:
    """Per-point errors |u_h - u| / max|u| and |s_h - s| / max|s| (for error maps)."""
    s_h, s = stress_component(sigma_h, direction), stress_component(sigma, direction)
    top_u = np.linalg.norm(u, axis=1).max(initial=0.0) or 1.0
    top_s = np.abs(s).max(initial=0.0) or 1.0
    return np.linalg.norm(u_h - u, axis=1) / top_u, np.abs(s_h - s) / top_s




@dataclass(frozen=True)
class BodyRule:
    """The error norms' quadrature over a body: whole cells (c,) that share one rule, its points at
    offsets (q, d) from each cell's lowest corner with weights (q,), and the rest (QuadraturePoints)."""

    whole: np.ndarray
    offsets: np.ndarray
    weight: np.ndarray
    rest: QuadraturePoints

    def points(self, grid) -> QuadraturePoints:
        """All points, the whole cells' first (cell by cell)."""
        if not len(self.whole):
            return self.rest
        return QuadraturePoints(np.concatenate([grid.points_in_cells(self.whole, self.offsets), self.rest.x]),
                                np.concatenate([np.tile(self.weight, len(self.whole)), self.rest.weight]),
                                np.concatenate([np.repeat(self.whole, len(self.weight)), self.rest.cells]))


def body_quadrature(body, grid, order: int = 4, delta: float | None = None) -> QuadraturePoints:
    """Quadrature over the body, exact for polynomials of degree 2 order - 2 on every piece
    (body_rule's points as one set)."""
    return body_rule(body, grid, order, delta).points(grid)


def body_rule(body, grid, order: int = 4, delta: float | None = None) -> BodyRule:
    """Quadrature over the body, exact for polynomials of degree 2 order - 2 on every piece.

    Cells wholly inside (and, with a band width delta, clear of the bands phi_k < delta of
    the essential edges) get an order x order Gauss rule; the others are clipped by the
    body, split at the lines phi_k = delta (where an IBM field has a kink, so each piece sees
    a smooth integrand), fanned into quadrilaterals and get a tensor Gauss rule. In 3D every
    point is in `rest` (ibm.geometry.polyhedron.body_quadrature).
    """
    if body.dim == 3:
        return BodyRule(np.zeros(0, int), np.zeros((0, 3)), np.zeros(0),
                        polyhedron.body_quadrature(body, grid, order, delta))
    lo, hi = body.bounds()
    cells = grid.cells_overlapping(lo, hi)
    corner = grid.cell_corners(cells)                                             # (n_cells, 2)
    # the cells form a lattice (cells_overlapping: rows of x); classify_boxes wants "ij" order
    ij = np.lexsort((corner[:, 1], corner[:, 0]))
    i_count = len(np.unique(corner[:, 0]))
    chords = body.chords(lines=cutting_lines(body, grid, delta)) if body.arcs else None
    inside_ij, cut_ij = classify_boxes(body, corner[ij], grid.h, (i_count, len(cells) // i_count), chords)
    whole = np.zeros(len(cells), bool)
    whole[ij] = inside_ij
    meets = np.zeros(len(cells), bool)          # cells that hold some of the body: inside or cut
    meets[ij] = inside_ij | cut_ij
    all_walls = body.walls if delta is not None and delta > 0 else ()
    walls = [wall for wall in all_walls if not wall.curved]
    arcs = [wall for wall in all_walls if wall.curved]
    hulls = [shapely.Polygon(curved_bands.hull(wall, delta)).normalize() for wall in arcs]
    for zone in hulls:   # cells meeting an essential arc's hull are split in polar slices below
        whole &= ~shapely.intersects(shapely.box(corner[:, 0], corner[:, 1], corner[:, 0] + grid.h,
                                                 corner[:, 1] + grid.h), zone)
    for wall in walls:   # clear of the band: the cell lies beyond its rectangle along n or along t
        s_low, s_high = _extent(corner, grid.h, wall.normal, wall.start)
        t_low, t_high = _extent(corner, grid.h, wall.tangent, wall.start)
        t0, t1 = -(1 + wall.extend[0]) * delta, wall.length + (1 + wall.extend[1]) * delta
        whole &= (s_low >= delta) | (s_high <= -delta) | (t_low >= t1) | (t_high <= t0)

    g, w = np.polynomial.legendre.leggauss(order)
    g, w = (g + 1) / 2 * grid.h, w / 2 * grid.h
    ref = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)      # (order^2, 2)
    ref_weight = np.outer(w, w).ravel()
    x, weight, owner_cells = [], [], []

    # only cells the outline cuts (or a band crosses) are clipped: the others lie outside
    clipped = meets & ~whole
    cut, cut_corner = cells[clipped], corner[clipped]
    # beside an essential arc the outline stands in with the arc moved off the body (its hull's
    # polar slices then cut the body exactly)
    outline = polygon(curved_bands.body_ring(body, delta, cutting_lines(body, grid, delta)) if arcs
                      else chords[0] if body.arcs else body.vertices)
    pieces = clip_boxes(cut_corner, cut_corner + grid.h, outline)                   # (n_cut,) shapely
    # mode per piece: -1 fanned; 2 a in the band of arc a, 2 a + 1 outside it (polar slices)
    mode = np.full(len(pieces), -1)
    for a, zone in enumerate(hulls):   # near an arc: its band and the rest, from the stand-in outline
        near = np.flatnonzero(shapely.intersects(pieces, zone))
        pieces[near] = shapely.difference(pieces[near], zone)
        stand_in = shapely.intersection(polygon(curved_bands.body_ring(body, delta)), zone)
        clipped = clip_boxes(cut_corner[near], cut_corner[near] + grid.h, stand_in)   # its band, then the rest
        pieces = np.concatenate([pieces, clipped, clipped])
        cut = np.concatenate([cut, cut[near], cut[near]])
        mode = np.concatenate([mode, np.full(len(near), 2 * a), np.full(len(near), 2 * a + 1)])
    for wall in walls:   # split where phi changes branch or crosses delta: a smooth integrand per piece
        parts = [shapely.Polygon(p).normalize() for p in wall.branch_polygons(delta)]
        box = shapely.Polygon(wall.box(delta)).normalize()
        split = [shapely.intersection(pieces, part) for part in parts] + [shapely.difference(pieces, box)]
        pieces = np.concatenate(split)
        cut = np.concatenate([cut] * len(split))
        mode = np.concatenate([mode] * len(split))
        keep = ~shapely.is_empty(pieces)
        pieces, cut, mode = pieces[keep], cut[keep], mode[keep]
    for a, wall in enumerate(arcs):
        for flag, inside in ((2 * a, True), (2 * a + 1, False)):
            mine = np.flatnonzero(mode == flag)
            xp, wp, owner = curved_bands.polar_pieces(pieces[mine], mine, wall, delta, inside)
            x.append(xp)
            weight.append(wp)
            owner_cells.append(cut[owner])
    fanned = mode == -1
    quads, owner = fan_quadrilaterals(pieces[fanned])
    xt, wt, quad = quadrilateral_points(quads, order)
    x.append(xt)
    weight.append(wt)
    owner_cells.append(cut[fanned][owner[quad]])
    if body.arcs:   # circular segments beyond the chords, signed; each inside one cell and one band region
        segments = chords[1]
        if arcs:     # an essential arc's segments lie in its hull, integrated above
            segments = segments.subset(np.flatnonzero(~np.isin(segments.piece, [wall.pieces[0] for wall in arcs])))
        xs, ws, which = segments.quadrature(max(order, ARC_ORDER), order)
        x.append(xs)
        weight.append(ws)
        owner_cells.append(grid.locate(segments.centroid)[which])
    rest = QuadraturePoints(np.concatenate(x), np.concatenate(weight), np.concatenate(owner_cells))
    return BodyRule(cells[whole], ref, ref_weight, rest)


def _extent(corner: np.ndarray, h: float, direction: np.ndarray, origin: np.ndarray):
    """Lowest and highest (n,) of (x - origin) . direction over the cells with lower-left corners (n, 2)."""
    base = (corner - origin) @ direction
    return base + h * (min(0, direction[0]) + min(0, direction[1])), base + h * (max(0, direction[0]) + max(0, direction[1]))


def norm_errors(body, grid, material, evaluate, exact, order: int = 4, delta: float | None = None,
                chunk: int = 65536) -> dict:
    """Relative L2 and energy-norm errors by quadrature over the body (not at material points)::

        err_l2     = ||u_h - u||_L2(body) / ||u||_L2(body)
        err_energy = sqrt(int (s_h - s) . C^-1 (s_h - s)) / sqrt(int s . C^-1 s)

    with s the in-plane Voigt stresses, i.e. the energy norm of the strain error (plane strain).
    evaluate(x, cells) -> (u_h (n, 2), sigma_h (n, 2, 2), ...) is the discrete field,
    exact(x) -> (u (n, 2), sigma (n, 2, 2), ...) the exact one; see body_rule for order and
    delta. An evaluator with in_clear_cells (ibm.small.forms.FieldEvaluator) takes the whole cells' shared
    rule through it: those cells lie clear of the bands of width delta.
    """
    rule = body_rule(body, grid, order, delta)
    d = grid.dim
    rows, columns = np.array(VOIGT[d]).T                  # tensor (not engineering) shears
    compliance = np.linalg.inv(material.stiffness(d))
    sums = np.zeros(4)                                    # weighted |u_h - u|^2, |u|^2, energy of error, of exact

    def add(x, weight, u_h, sigma_h):
        u, sigma = exact(x)[:2]
        ds, s = (sigma_h - sigma)[:, rows, columns], sigma[:, rows, columns]
        sums[:] += [weight @ np.sum((u_h - u) ** 2, axis=1), weight @ np.sum(u ** 2, axis=1),
                    weight @ np.einsum("pk,kl,pl->p", ds, compliance, ds),
                    weight @ np.einsum("pk,kl,pl->p", s, compliance, s)]

    # a chunk of neighbouring points at a time, evaluated and summed while its arrays are in cache
    # (whole-array passes over millions of points were bound by memory traffic), with bounded memory
    points = rule.rest
    # whole cells are clear of the bands only when body_rule knew their width
    clear = hasattr(evaluate, "in_clear_cells") and (delta is not None or evaluate.dirichlet is None)
    if clear and len(rule.whole):
        step = max(1, chunk // len(rule.weight))
        for start in range(0, len(rule.whole), step):
            cells = rule.whole[start:start + step]
            x = grid.points_in_cells(cells, rule.offsets)
            add(x, np.tile(rule.weight, len(cells)), *evaluate.in_clear_cells(cells, rule.offsets, x)[:2])
    else:
        points = rule.points(grid)
    for start in range(0, len(points), chunk):
        part = slice(start, start + chunk)
        x, cells = points.x[part], points.cells[part]
        # moment-fitted 3D rules carry their band regions (their nodes may lie outside them)
        fields = evaluate(x, cells) if points.region is None else evaluate(x, cells, region=points.region[part])
        add(x, points.weight[part], *fields[:2])
    return {"err_l2": _ratio(sums[0], sums[1]), "err_energy": _ratio(sums[2], sums[3])}

