"""Point bases of a load step: standard MPM and domain-integrated GIMP on polygon domains.

- `mpm`: S_v = N_v(x_p), dS_v = grad N_v(x_p) of the cell holding the point.
- `gimp`: S_v = (1/|O_p|) int_(O_p) N_v dx, dS_v = (1/|O_p|) int_(O_p) grad N_v dx over the
  point's current domain O_p. The initial domains are the seed's clipped squares (ibm.points);
  a point's domain follows its deformation gradient, vertex X_c -> x_p + F_p (X_c - X_p), and is
  clipped by the current body (so it never reaches through a wall). Under a homogeneous F the
  mapped domains tile the body exactly, so sum_p V_p dS_p sigma integrates grad N sigma exactly
  and a uniform stress leaves no force on interior nodes: the finite-strain patch test holds to
  round-off. Each domain is clipped by the grid cells and N (bilinear) is integrated exactly on
  the pieces (fans of quadrilaterals, 2 x 2 Gauss points).

A basis lists, per point, the nodes of a (w + 1) x (w + 1) window of grid nodes whose lowest
corner is the lowest cell the domain meets (w = 1 for mpm): nodes (n, k), S (n, k), dS (n, k, d).
Unused window nodes carry S = 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from ibm.geometry import InputError
from ibm.grid import Grid
from ibm.solve import SolveError
from ibm.quadrature import fan_quadrilaterals, quadrilateral_points

BASES = ("mpm", "gimp")


@dataclass(frozen=True, eq=False)
class PointBasis:
    nodes: np.ndarray   # (n, k) grid node ids
    S: np.ndarray       # (n, k)
    dS: np.ndarray      # (n, k, d) gradients with respect to x_n

    @property
    def dofs(self) -> np.ndarray:
        """(n, k d) DOF ids [d v + a], node-major like the operators of ibm.kinematics."""
        d = self.dS.shape[2]
        return (d * self.nodes[:, :, None] + np.arange(d)).reshape(len(self.nodes), -1)

    def interpolate(self, U: np.ndarray) -> np.ndarray:
        """(n, d) values sum_v S_v U_v of the nodal field U (n_dofs,)."""
        d = self.dS.shape[2]
        return np.einsum("pv,pva->pa", self.S, U[self.dofs].reshape(*self.S.shape, d))


def _check_inside(grid: Grid, x: np.ndarray) -> None:
    ij = np.floor((x - grid.origin) / grid.h)
    outside = np.any((ij < 0) | (ij >= np.array(grid.shape)), axis=1)
    if np.any(outside):
        bad = x[np.argmax(outside)]
        raise GridExit(f"a material point at ({bad[0]:.6g}, {bad[1]:.6g}) has left the grid "
                       f"[{grid.origin[0]:.6g}, {grid.origin[0] + grid.h * grid.shape[0]:.6g}] x "
                       f"[{grid.origin[1]:.6g}, {grid.origin[1] + grid.h * grid.shape[1]:.6g}]")


class GridExit(SolveError):
    """A material point (or its domain) left the background grid (the grid does not grow: the run
    stops, naming the point; give the body more room with Setup.margin)."""


class DomainLost(SolveError):
    """A point's domain no longer meets the tracked outline (the run stops: exit 3)."""


def mpm_basis(grid: Grid, x: np.ndarray) -> PointBasis:
    _check_inside(grid, x)
    cells = grid.locate(x)
    N, dN = grid.shape_functions(x, cells)
    return PointBasis(grid.cell_nodes(cells), N, dN)


def mapped_domains(initial: np.ndarray, X: np.ndarray, x: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Initial domain polygons (n,) mapped affinely: vertex X_c -> x_p + F_p (X_c - X_p); F (n, 3, 3)."""
    coords, owner = shapely.get_coordinates(initial, return_index=True)
    moved = x[owner] + np.einsum("pij,pj->pi", F[owner, :2, :2], coords - X[owner])
    return shapely.set_coordinates(np.array(initial, dtype=object).copy(), moved)


def gimp_basis(grid: Grid, x: np.ndarray, domains: np.ndarray) -> PointBasis:
    """GIMP basis of points x (n, 2) with current domain polygons (n,) (already clipped by the body)."""
    _check_inside(grid, x)
    n = len(x)
    lost = shapely.is_empty(domains) | ~(shapely.area(domains) > 0)
    if np.any(lost):
        i = int(np.argmax(lost))
        raise DomainLost(f"material point {i} at ({x[i, 0]:.6g}, {x[i, 1]:.6g}) has no domain left inside the body's "
                         f"outline (the points and the outline have parted)")
    bounds = shapely.bounds(domains)                                              # (n, 4)
    lo, hi = bounds.reshape(n, 2, 2).transpose(1, 0, 2)
    _check_inside(grid, np.concatenate([lo, hi - 1e-12 * grid.h]))
    first = np.floor((lo - grid.origin) / grid.h).astype(int)                     # lowest cell (i, j)
    last = np.floor((hi - grid.origin) / grid.h - 1e-12).astype(int)
    span = np.maximum(last - first, 0)
    width = int(span.max(initial=0)) + 1                                          # cells per window side
    # every (point, cell) pair of the point's window; empty intersections drop out
    di, dj = np.meshgrid(np.arange(width), np.arange(width), indexing="ij")
    di, dj = di.ravel(), dj.ravel()
    point = np.repeat(np.arange(n), width * width)
    ci, cj = first[point, 0] + np.tile(di, n), first[point, 1] + np.tile(dj, n)
    keep = (ci <= last[point, 0]) & (cj <= last[point, 1])
    point, ci, cj = point[keep], ci[keep], cj[keep]
    corner = grid.origin + grid.h * np.stack([ci, cj], axis=1)
    quads, owner = _cell_pieces(domains, bounds, point, corner, grid.h)
    xq, wq, quad = quadrilateral_points(quads, 2)
    pair = owner[quad]
    cells = grid.cell_index(np.stack([ci[pair], cj[pair]], axis=1))
    N, dN = grid.shape_functions(xq, cells)
    # local node l of cell (ci, cj) sits at window node (ci - first_i + ox, cj - first_j + oy)
    offsets = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])
    p = point[pair]
    wi = (ci[pair] - first[p, 0])[:, None] + offsets[None, :, 0]
    wj = (cj[pair] - first[p, 1])[:, None] + offsets[None, :, 1]
    slot = p[:, None] * (width + 1) ** 2 + wj * (width + 1) + wi                  # (m, 4)
    k = (width + 1) ** 2
    S = np.bincount(slot.ravel(), (N * wq[:, None]).ravel(), minlength=n * k).reshape(n, k)
    dS = np.stack([np.bincount(slot.ravel(), (dN[:, :, a] * wq[:, None]).ravel(), minlength=n * k).reshape(n, k)
                   for a in range(2)], axis=2)
    area = np.bincount(p, wq, minlength=n)
    if np.any(area <= 0):
        raise DomainLost(f"material point {int(np.argmin(area))}'s domain has no area inside the grid")
    S /= area[:, None]
    dS /= area[:, None, None]
    wi_all, wj_all = np.meshgrid(np.arange(width + 1), np.arange(width + 1), indexing="xy")
    node_i = first[:, 0, None] + wi_all.ravel()[None, :]
    node_j = first[:, 1, None] + wj_all.ravel()[None, :]
    nx = grid.shape[0]
    nodes = np.minimum(node_j, grid.shape[1]) * (nx + 1) + np.minimum(node_i, nx)
    return PointBasis(nodes, S, dS)


def _axis_aligned(domains: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """(n,) True where a domain is an axis-aligned rectangle (4 corners filling its bounds (n, 4))."""
    counts = shapely.get_num_coordinates(domains)
    box_area = (bounds[:, 2] - bounds[:, 0]) * (bounds[:, 3] - bounds[:, 1])
    return (counts == 5) & (np.abs(shapely.area(domains) - box_area) <= 1e-12 * box_area)


def _cell_pieces(domains: np.ndarray, bounds: np.ndarray, point: np.ndarray, corner: np.ndarray, h: float):
    """Quadrilaterals (m, 4, 2) of each (point, cell) pair's domain ∩ cell, and the pair of each.

    Axis-aligned rectangular domains (every domain of an undistorted or stretched lattice) are
    clipped by bounds alone; the others by shapely, then fanned into quadrilaterals."""
    rectangle = _axis_aligned(domains, bounds)[point]
    box = bounds[point[rectangle]]
    lo = np.maximum(box[:, :2], corner[rectangle])
    hi = np.minimum(box[:, 2:], corner[rectangle] + h)
    nonempty = np.all(hi > lo, axis=1)
    lo, hi = lo[nonempty], hi[nonempty]
    boxes = np.stack([lo, np.stack([hi[:, 0], lo[:, 1]], 1), hi, np.stack([lo[:, 0], hi[:, 1]], 1)], axis=1)
    box_pair = np.flatnonzero(rectangle)[nonempty]
    general = np.flatnonzero(~rectangle)
    if len(general) == 0:
        return boxes, box_pair
    c = corner[general]
    pieces = shapely.intersection(shapely.box(c[:, 0], c[:, 1], c[:, 0] + h, c[:, 1] + h), domains[point[general]])
    quads, owner = fan_quadrilaterals(pieces)
    return np.concatenate([boxes, quads]), np.concatenate([box_pair, general[owner]])


def _repaired(domains: np.ndarray) -> np.ndarray:
    """Domains whose ring crosses itself by round-off (a near-collinear corner of a merged domain,
    mapped by F) replaced by their largest valid part."""
    invalid = np.flatnonzero(~shapely.is_valid(domains))
    if len(invalid) == 0:
        return domains
    parts, owner = shapely.get_parts(shapely.buffer(domains[invalid], 0), return_index=True)
    order = np.lexsort((shapely.area(parts), owner))          # by domain, then by area
    last = order[np.r_[np.flatnonzero(np.diff(owner[order])), len(order) - 1]] if len(order) else order
    repaired = np.array(domains, dtype=object).copy()
    repaired[invalid[owner[last]]] = parts[last]
    return repaired


def clip_to_body(domains: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Domains (n,) intersected with the body polygon `vertices` (k, 2, counter-clockwise).

    A domain whose corners all lie on the inner side of every edge (the polygon's kernel, which
    is convex and inside the polygon, so it holds the whole domain) is kept as it is; only the
    others are clipped. The test is exact, with no tolerance: a sliver across a wall would give
    grid nodes beyond it a vanishing support. Collinear outline vertices are dropped first; an
    outline with many true corners is clipped whole."""
    body = shapely.Polygon(vertices)
    domains = _repaired(domains)
    corners = shapely.get_coordinates(shapely.simplify(body, 0.0).exterior)[:-1]
    if not shapely.is_ccw(shapely.LinearRing(corners)) or len(corners) > 64:
        return shapely.intersection(domains, body)
    edges = np.roll(corners, -1, axis=0) - corners
    coordinates, owner = shapely.get_coordinates(domains, return_index=True)
    side = (edges[None, :, 0] * (coordinates[:, None, 1] - corners[None, :, 1])
            - edges[None, :, 1] * (coordinates[:, None, 0] - corners[None, :, 0]))   # (m, k) > 0 inside
    outside = np.bincount(owner, np.any(side < 0, axis=1), minlength=len(domains)) > 0
    clipped = np.array(domains, dtype=object).copy()
    if np.any(outside):
        clipped[outside] = shapely.intersection(domains[outside], body)
    return clipped


def point_basis(kind: str, grid: Grid, x: np.ndarray, domains: np.ndarray | None = None) -> PointBasis:
    if kind == "mpm":
        return mpm_basis(grid, x)
    if kind == "gimp":
        return gimp_basis(grid, x, domains)
    raise InputError(f"basis {kind!r} is not allowed; allowed: {', '.join(BASES)}")
