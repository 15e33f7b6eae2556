"""Material points by the seed's procedure.

Square point domains of side h/ppc on a lattice aligned with the grid (ppc x ppc per cell)
are clipped by the body; each point sits at the centroid of its clipped domain and carries
the clipped area as its volume. Every domain lies inside one cell, so the centroid rule
integrates the (cell-wise linear) shape-function gradients exactly over it. A domain clipped
at a re-entrant corner is not convex, and its centroid may lie just outside the body (inside
the domain's square): it is still the exact one-point rule for linear integrands over it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from scipy.spatial import cKDTree

from ibm.discretise.grid import Grid
from ibm.exceptions import InputError
from ibm.geometry.arcs import grid_lines
from ibm.geometry.outline import Body
from ibm.quadrature.rules import QuadraturePoints, clip_boxes, polygon


@dataclass(frozen=True, eq=False)
class MaterialPoints:
    """A body's material points: each the centroid of its domain, the body clipped by a cell and by
    the ppc x ppc lattice inside it, carrying that domain's volume (material_points makes them)."""

    x: np.ndarray        # (n_points, d) positions
    volume: np.ndarray   # (n_points,) volumes (areas in 2D)
    cells: np.ndarray    # (n_points,) grid cell holding each point's domain
    # the clipped domains, if asked for: (n_points,) shapely polygons in 2D, ibm.discretise.simplex_domains.SimplexDomains in 3D
    domains: object = None
    # 3D: the rule the points' forms are integrated with (ibm.geometry.polyhedron.cell_rule), else the points
    rule: QuadraturePoints | None = None

    def __len__(self) -> int:
        return len(self.volume)

    def quadrature(self) -> QuadraturePoints:
        """The points as a quadrature rule over the body (weights = volumes), or the exact cell rule
        of 3D bodies (see ibm.geometry.polyhedron.cell_rule)."""
        if self.rule is not None:
            return self.rule
        return QuadraturePoints(self.x, self.volume, self.cells)


def material_points(body: Body, grid: Grid, ppc: int, domains: bool = False) -> MaterialPoints:
    """Points of `ppc` x `ppc` clipped square domains per grid cell (with their polygons if `domains`)."""
    if body.dim == 3:
        return body.material_points(grid, ppc)          # a Polyhedron (ibm.geometry.polyhedron)
    if isinstance(ppc, bool) or not isinstance(ppc, (int, np.integer)) or ppc < 1:
        raise InputError(f"points per cell ppc={ppc!r} is not allowed; it must be an integer >= 1")
    s = grid.h / ppc
    lo, hi = body.bounds()
    k0 = np.floor((lo - grid.origin) / s).astype(int)
    k1 = np.ceil((hi - grid.origin) / s).astype(int)
    ki, kj = np.meshgrid(np.arange(k0[0], k1[0]), np.arange(k0[1], k1[1]), indexing="ij")
    k = np.stack([ki.ravel(), kj.ravel()], axis=1)
    box_lo = grid.origin + s * k                                              # (n_boxes, 2)
    # arcs cut into chords at every lattice line (the same chords for classifying and clipping)
    chords = body.chords(lines=grid_lines(grid.origin, s)) if body.arcs else None
    inside, cut = classify_boxes(body, box_lo, s, ki.shape, chords)
    x = [box_lo[inside] + s / 2]
    volume = [np.full(inside.sum(), s * s)]
    geoms = clip_boxes(box_lo[cut], box_lo[cut] + s, polygon(chords[0] if body.arcs else body.vertices))
    area = shapely.area(geoms)
    centroid = np.zeros((len(geoms), 2))
    filled = ~shapely.is_empty(geoms)
    centroid[filled] = shapely.get_coordinates(shapely.centroid(geoms[filled]))
    if body.arcs:
        # chords at every lattice crossing: each circular segment lies in one box, whose area
        # and first moment it corrects exactly (closed forms)
        segments = chords[1]
        box = np.floor((segments.centroid - grid.origin) / s).astype(int) - k0           # lattice (i, j) - k0
        index = np.full(ki.shape, -1)
        index.ravel()[np.flatnonzero(cut)] = np.arange(int(cut.sum()))
        at = index[box[:, 0], box[:, 1]]
        if np.any(at < 0):
            raise InputError("a circular segment lies in a box not cut by the outline (the chords are too coarse)")
        moment = centroid * np.where(area > 0, area, 0.0)[:, None]
        area = area + np.bincount(at, segments.area, minlength=len(area))
        moment = moment + np.stack([np.bincount(at, segments.area * segments.centroid[:, j], minlength=len(area))
                                    for j in range(2)], axis=1)
        centroid = moment / np.where(area > 0, area, 1.0)[:, None]
    keep = area > 1e-12 * s * s
    x.append(centroid[keep])
    volume.append(area[keep])
    cell_ij = np.concatenate([k[inside], k[cut][keep]]) // ppc
    if np.any((cell_ij < 0) | (cell_ij >= np.array(grid.shape))):
        raise InputError("the body leaves the grid; use a grid that covers it (Grid.covering)")
    cells = grid.cell_index(cell_ij)
    polygons = None
    if domains:
        whole = box_lo[inside]
        polygons = np.concatenate([shapely.box(whole[:, 0], whole[:, 1], whole[:, 0] + s, whole[:, 1] + s),
                                   geoms[keep]])
    return MaterialPoints(x=np.concatenate(x), volume=np.concatenate(volume), cells=cells, domains=polygons)


def classify_boxes(body: Body, box_lo: np.ndarray, s: float, lattice: tuple[int, int], chords=None):
    """(inside, cut): boolean (n_boxes,) for the boxes of side s at box_lo (n_boxes, 2), a
    lattice of shape `lattice` in meshgrid "ij" order: wholly inside the body, or cut by its outline.

    Convex body: s_k is linear, so over a box it ranges from its value at the lower-left
    corner plus s (min(0, n_x) + min(0, n_y)) to that plus s (max(0, n_x) + max(0, n_y)); the
    corner values as an outer sum over the lattice. Otherwise a box is cut when its centre
    lies within half a diagonal of some piece, and inside when, not cut, its centre is inside.
    """
    if body.convex:
        n = body.normals
        base = np.sum((box_lo[0] - body.starts) * n, axis=1)
        phi = (base[:, None, None] + s * n[:, 0, None, None] * np.arange(lattice[0])[None, :, None]
               + s * n[:, 1, None, None] * np.arange(lattice[1])[None, None, :]).reshape(body.n_edges, -1)
        low = phi + s * (np.minimum(n[:, 0], 0) + np.minimum(n[:, 1], 0))[:, None]
        high = phi + s * (np.maximum(n[:, 0], 0) + np.maximum(n[:, 1], 0))[:, None]
        inside, outside = np.all(low >= 0, axis=0), np.any(high <= 0, axis=0)
        return inside, ~inside & ~outside
    centre = box_lo + s / 2
    near = np.zeros(len(centre), bool)
    reach = s * np.sqrt(0.5) * (1 + 1e-9)
    if body.arcs:   # the arcs bulge beyond their chords by at most the largest sagitta
        ring, segments = chords if chords is not None else body.chords()
        reach += float(np.max(segments.radius * (1 - np.cos((segments.theta1 - segments.theta0) / 2))))
    else:
        ring = body.vertices
    starts, ends = ring, np.roll(ring, -1, axis=0)
    for k in range(len(ring)):             # the pieces (and chords), vectorised over boxes
        near |= segment_distance(centre, starts[k], ends[k]) <= reach
    inside = ~near & shapely.contains_xy(polygon(ring), centre[:, 0], centre[:, 1])
    return inside, near


def segment_distance(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n,) Euclidean distance of points x (n, 2) to the segment a -> b."""
    d = b - a
    t = np.clip(((x[:, 0] - a[0]) * d[0] + (x[:, 1] - a[1]) * d[1]) / (d @ d), 0.0, 1.0)
    return np.hypot(x[:, 0] - a[0] - t * d[0], x[:, 1] - a[1] - t * d[1])


def merge_slivers(points: MaterialPoints, grid: Grid, ppc: int, fraction: float) -> MaterialPoints:
    """Points whose clipped domain is smaller than `fraction` of the lattice square joined to the
    nearest whole-enough point: its domain becomes the union, its position the union's centroid.

    A sliver cut off by an inclined edge is a point of almost no volume whose deformation
    gradient the grid barely controls; at large deformation such points fold (det F <= 0) long
    before the body does. The union of the domains still tiles the body exactly, so the
    finite-strain patch test is untouched. Needs the points' domains.
    """
    if points.domains is None:
        raise InputError("merging slivers needs the points' domains (material_points(..., domains=True))")
    if not (0 <= fraction < 1):
        raise InputError(f"sliver fraction {fraction} is not allowed; it must be in [0, 1)")
    full = (grid.h / ppc) ** 2
    small = points.volume < fraction * full
    if not np.any(small) or np.all(small):
        return points
    large = np.flatnonzero(~small)
    target = large[cKDTree(points.x[large]).query(points.x[small])[1]]           # (n_small,)
    domains = np.array(points.domains, dtype=object).copy()
    children = np.flatnonzero(small)
    # one union per round, so a point that takes several slivers takes them one at a time
    order = np.argsort(target, kind="stable")
    rank = np.arange(len(order)) - np.searchsorted(target[order], target[order])
    for r in range(int(rank.max(initial=-1)) + 1):
        pick = order[rank == r]
        # simplified by a rounding-level tolerance: no near-collinear corner for F to fold later
        merged = shapely.simplify(shapely.union(domains[target[pick]], domains[children[pick]]), 1e-9 * grid.h)
        single = shapely.get_type_id(merged) == 3                                 # touching: one polygon
        domains[target[pick[single]]] = merged[single]
        small[children[pick[~single]]] = False                                    # not touching: kept apart
    keep = ~small
    domains = domains[keep]
    x = shapely.get_coordinates(shapely.centroid(domains))
    return MaterialPoints(x=x, volume=shapely.area(domains), cells=grid.locate(x), domains=domains)
