"""Point bases of a load step: standard MPM and domain-integrated GIMP on polygon or polyhedral domains.

- `mpm`: S_v = N_v(x_p), dS_v = grad N_v(x_p) of the cell holding the point.
- `gimp`: S_v = (1/|O_p|) int_(O_p) N_v dx, dS_v = (1/|O_p|) int_(O_p) grad N_v dx over the
  point's current domain O_p. The initial domains are the seed's clipped squares (ibm.discretise.points) or
  cubes (ibm.geometry.polyhedron, as tetrahedra: ibm.discretise.simplex_domains); a point's domain follows its
  deformation gradient, vertex X_c -> x_p + F_p (X_c - X_p), and is clipped by the current body
  (so it never reaches through a wall). Under a homogeneous F the mapped domains tile the body
  exactly, so sum_p V_p dS_p sigma integrates grad N sigma exactly and a uniform stress leaves no
  force on interior nodes: the finite-strain patch test holds to round-off. Each domain is
  clipped by the grid cells and N (bilinear, trilinear) is integrated exactly on the pieces:
  fans of quadrilaterals with 2 x 2 Gauss points in 2D, tetrahedra with the degree-3 rule in 3D.

A basis lists, per point, the nodes of a (w + 1)^d window of grid nodes whose lowest corner is
the lowest cell the domain meets (w = 1 for mpm): nodes (n, k), S (n, k), dS (n, k, d).
Unused window nodes carry S = 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from ibm.geometry import polytope
from ibm.exceptions import DomainLost, GridExit, InputError
from ibm.discretise.grid import LOCAL_NODES, Grid, lattice
from ibm.quadrature.rules import fan_quadrilaterals, quadrilateral_points
from ibm.discretise.simplex_domains import SimplexDomains

BASES = ("mpm", "gimp")


@dataclass(frozen=True, eq=False)
class PointBasis:
    nodes: np.ndarray   # (n, k) grid node ids
    S: np.ndarray       # (n, k)
    dS: np.ndarray      # (n, k, d) gradients with respect to x_n

    @property
    def dofs(self) -> np.ndarray:
        """(n, k d) DOF ids [d v + a], node-major like the operators of ibm.large.kinematics."""
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
        box = " x ".join(f"[{o:.6g}, {o + grid.h * n:.6g}]" for o, n in zip(grid.origin, grid.shape))
        raise GridExit(f"a material point at ({', '.join(f'{v:.6g}' for v in bad)}) has left the grid {box}")




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


def gimp_basis(grid: Grid, x: np.ndarray, domains) -> PointBasis:
    """GIMP basis of points x (n, d) with their current domains (already clipped by the body):
    shapely polygons (n,) in 2D, SimplexDomains in 3D."""
    _check_inside(grid, x)
    if isinstance(domains, SimplexDomains):
        return _window_basis(grid, x, *_tetrahedron_pieces(grid, x, domains))
    n = len(x)
    lost = shapely.is_empty(domains) | ~(shapely.area(domains) > 0)
    if np.any(lost):
        _lost(x, int(np.argmax(lost)))
    bounds = shapely.bounds(domains)                                              # (n, 4)
    lo, hi = bounds.reshape(n, 2, 2).transpose(1, 0, 2)
    _check_inside(grid, np.concatenate([lo, hi - 1e-12 * grid.h]))
    first = np.floor((lo - grid.origin) / grid.h).astype(int)                     # lowest cell (i, j)
    last = np.floor((hi - grid.origin) / grid.h - 1e-12).astype(int)
    width = int(np.maximum(last - first, 0).max(initial=0)) + 1                   # cells per window side
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
    cell = np.stack([ci[pair], cj[pair]], axis=1)
    N, dN = grid.shape_functions(xq, grid.cell_index(cell))
    return _window_basis(grid, x, first, width, [(point[pair], cell, N * wq[:, None], dN * wq[:, None, None], wq)])


def _lost(x: np.ndarray, i: int):
    raise DomainLost(f"material point {i} at ({', '.join(f'{v:.6g}' for v in x[i])}) has no domain left inside "
                     f"the body's outline (the points and the outline have parted)")


def _window_basis(grid: Grid, x: np.ndarray, first: np.ndarray, width: int, parts) -> PointBasis:
    """The basis from the integrals of N and grad N over the pieces of the domains in the grid cells.

    first (n, d): each point's lowest cell; width: cells per window side; parts: chunks
    (point (r,), cell (r, d) integer cell coordinates, int N (r, 2^d), int grad N (r, 2^d, d),
    measure (r,)) over pieces r of the points' domains, each in one cell.
    Local node l of cell c sits at window node c - first_p + LOCAL_NODES[l]; window node
    (w_1, .., w_d) is slot sum_a w_a (width + 1)^a (first axis fastest, as node ids)."""
    n, d = x.shape
    k = (width + 1) ** d
    stride = (width + 1) ** np.arange(d)
    S, dS, volume = np.zeros(n * k), np.zeros((d, n * k)), np.zeros(n)
    for point, cell, N, dN, measure in parts:
        window = (cell - first[point])[:, None, :] + grid.local_nodes[None]           # (r, 2^d, d)
        slot = (point[:, None] * k + window @ stride).ravel()                           # (r 2^d,)
        S += np.bincount(slot, N.ravel(), minlength=n * k)
        for a in range(d):
            dS[a] += np.bincount(slot, dN[:, :, a].ravel(), minlength=n * k)
        volume += np.bincount(point, measure, minlength=n)
    if np.any(volume <= 0):
        raise DomainLost(f"material point {int(np.argmin(volume))}'s domain has no volume inside the grid")
    S = S.reshape(n, k) / volume[:, None]
    dS = np.ascontiguousarray(dS.reshape(d, n, k).transpose(1, 2, 0)) / volume[:, None, None]
    window_nodes = lattice([np.arange(width + 1)] * d)                                 # (k, d), slot order
    nodes = np.minimum(first[:, None, :] + window_nodes[None], np.array(grid.shape)) @ grid._strides(1)
    return PointBasis(nodes, S, dS)


CHUNK = 4096        # points per chunk of 3D pieces (bounds the memory of their quadrature points)


def _tetrahedron_pieces(grid: Grid, x: np.ndarray, domains: SimplexDomains):
    """first (n, 3), width and the quadrature chunks (see _window_basis) of 3D domains: each
    tetrahedron is clipped by the six planes of every cell its bounding box meets, and the
    trilinear N (degree 3) is integrated exactly on the pieces (degree-3 simplex rule)."""
    n, vertices, owner = domains.n, domains.vertices, domains.owner
    present = np.zeros(n, bool)
    present[owner] = True
    volume = domains.volumes()
    if not np.all(present & (volume > 0)):
        _lost(x, int(np.argmin(present & (volume > 0))))
    lo, hi = vertices.min(axis=1), vertices.max(axis=1)                              # (m, 3)
    _check_inside(grid, np.concatenate([lo, hi - 1e-12 * grid.h]))
    low = np.floor((lo - grid.origin) / grid.h).astype(int)                         # each tetrahedron's cells
    high = np.maximum(np.floor((hi - grid.origin) / grid.h - 1e-12).astype(int), low)
    first = np.full((n, 3), np.iinfo(int).max)
    np.minimum.at(first, owner, low)
    last = np.full((n, 3), np.iinfo(int).min)
    np.maximum.at(last, owner, high)
    width = int((last - first).max(initial=0)) + 1
    starts = np.searchsorted(owner, np.arange(0, n, CHUNK))
    ends = np.append(starts[1:], len(owner))
    return first, width, (_cell_pieces_3d(grid, vertices[a:b], owner[a:b], low[a:b], high[a:b])
                          for a, b in zip(starts, ends))


def _monomial_coefficients() -> tuple[np.ndarray, np.ndarray]:
    """C (8, 8) and D (3, 8, 8): N_l(t) = sum_e C[l, e] t^e and h dN_l/dx_a = sum_e D[a, l, e] t^e on
    a trilinear cell, t in [0, 1]^3 its local coordinates, t^e = prod_a t_a^e_a over e in LOCAL_NODES[3]
    order. Per axis N factors into 1 - t (node offset 0: coefficients 1, -1 of t^0, t^1) or t (0, 1)."""
    offsets = LOCAL_NODES[3]
    factor = np.array([[1.0, -1.0], [0.0, 1.0]])                     # [offset, power]
    slope = np.array([-1.0, 1.0])                                    # d(factor)/dt by offset
    C = np.prod(factor[offsets[:, None, :], offsets[None, :, :]], axis=2)
    D = np.zeros((3, 8, 8))
    for a in range(3):
        others = [b for b in range(3) if b != a]
        D[a] = (slope[offsets[:, a]][:, None] * (offsets[None, :, a] == 0)
                * np.prod(factor[offsets[:, None, others], offsets[None, :, others]], axis=2))
    return C, D


MONOMIALS = _monomial_coefficients()


def _cell_pieces_3d(grid: Grid, vertices: np.ndarray, owner: np.ndarray, low: np.ndarray, high: np.ndarray):
    """Integrals (see _window_basis) over tetrahedra (m, 4, 3) of points `owner` clipped by the cells
    low .. high (m, 3) their bounding boxes meet (a tetrahedron in one cell is not clipped). The
    degree-3 rule gives each (tetrahedron, cell) row the 8 moments of t^e (t the cell's local
    coordinates); N and grad N are their fixed combinations (MONOMIALS), so N is never evaluated
    point by point."""
    span = high - low + 1                                                             # (m, 3)
    count = np.prod(span, axis=1)
    tetrahedron = np.repeat(np.arange(len(vertices)), count)                          # one row per (tet, cell)
    r = np.arange(len(tetrahedron)) - np.repeat(np.cumsum(count) - count, count)
    s = span[tetrahedron]
    cell = low[tetrahedron] + np.stack([r % s[:, 0], (r // s[:, 0]) % s[:, 1], r // (s[:, 0] * s[:, 1])], axis=1)
    corner = grid.origin + grid.h * cell                                              # (rows, 3)
    whole = count[tetrahedron] == 1
    cut = np.flatnonzero(~whole)
    normals = np.broadcast_to(np.concatenate([np.eye(3), -np.eye(3)]), (len(cut), 6, 3))
    offsets = np.concatenate([corner[cut] + grid.h, -corner[cut]], axis=1)            # x_a <= c_a + h, x_a >= c_a
    pieces, pair = polytope.clip_all(vertices[tetrahedron[cut]], np.arange(len(cut)), normals, offsets)
    whole = np.flatnonzero(whole)
    xq, wq, row = polytope.quadrature(np.concatenate([vertices[tetrahedron[whole]], pieces]),
                                      np.concatenate([whole, cut[pair]]), 3)
    t = (xq - corner[row]) / grid.h                                                   # (q, 3) local coordinates
    power = np.stack([np.ones(len(t)), t[:, 0], t[:, 0] * t[:, 1], t[:, 1], t[:, 2], t[:, 0] * t[:, 2],
                      t[:, 0] * t[:, 1] * t[:, 2], t[:, 1] * t[:, 2]], axis=1)         # t^e, e in LOCAL_NODES order
    moments = np.stack([np.bincount(row, wq * power[:, e], minlength=len(cell)) for e in range(8)], axis=1)
    C, D = MONOMIALS
    dN = np.stack([moments @ D[a].T for a in range(3)], axis=2) / grid.h              # (rows, 8, 3)
    return owner[tetrahedron], cell, moments @ C.T, dN, moments[:, 0]


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


def current_domains(initial, X: np.ndarray, x: np.ndarray, F: np.ndarray, body):
    """The initial domains mapped by F (vertex X_c -> x_p + F_p (X_c - X_p)) and clipped: polygons
    (n,) by the whole current body (2D), SimplexDomains by the half-spaces of its walls (3D: see
    ibm.discretise.simplex_domains for why free faces do not clip)."""
    if isinstance(initial, SimplexDomains):
        walls = body.essential_edges
        return initial.mapped(X, x, F).clipped(body.normals[walls], body.offsets[walls])
    return clip_to_body(mapped_domains(initial, X, x, F), body.vertices)


def point_basis(kind: str, grid: Grid, x: np.ndarray, domains: np.ndarray | None = None) -> PointBasis:
    if kind == "mpm":
        return mpm_basis(grid, x)
    if kind == "gimp":
        return gimp_basis(grid, x, domains)
    raise InputError(f"basis {kind!r} is not allowed; allowed: {', '.join(BASES)}")
