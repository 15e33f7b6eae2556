"""Convex polyhedral bodies in 3D, and the seed's pieces on them.

A body is the intersection of half-spaces n_k . x >= c_k (n_k the inward unit normal of
face k), with one boundary kind per face and each face's polygon for traction quadrature.
Every region integrated over (a grid cell, or one of the seed's cubic point domains,
intersected with the body, with the bands {s_k < delta} of the essential faces and with
their complements) is convex and the intersection of half-spaces, so it is a set of
simplices clipped plane by plane (ibm.geometry.polytope), integrated by Gauss rules of the
integrand's degree.

    s_k(x) = n_k . x - c_k          signed distance to face k's plane (> 0 inside)
    band regions R_S = {s_k < delta, k in S; s_j >= delta, j essential, not in S} ∩ body

On R_S inside one trilinear cell the band correction B~^T C B~ - B^T C B is a polynomial of
total degree 4 |S| + 4 (D is quadratic in each s_k, N trilinear), integrated exactly.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from itertools import combinations

import numpy as np

from ibm.quadrature import moment_fitting
from ibm.geometry import polytope
from ibm.geometry.outline import EDGE_KINDS, ESSENTIAL_KINDS
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid, lattice
from ibm.discretise.points import MaterialPoints
from ibm.quadrature.rules import QuadraturePoints
from ibm.discretise.simplex_domains import SimplexDomains

FACES = ("base", "right", "top", "left", "front", "back")   # a box's faces, in order
# outward local normals of a box's faces (local frame xi, eta, zeta)
BOX_OUTWARD = np.array([[0, -1, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, 0, -1], [0, 0, 1]], float)


@dataclass(frozen=True)
class Plane:
    """The plane of one essential face: the support of one Dirichlet function.

    point (3,) on the plane, normal (3,) inward unit; pieces: (face,)."""

    kind: str
    pieces: tuple[int, ...]
    point: np.ndarray
    normal: np.ndarray

    curved = False

    def signed(self, x: np.ndarray) -> np.ndarray:
        """Signed distance s (n,) of points x (n, 3) to the plane (> 0 on the body's side)."""
        d = x - self.point
        return d[:, 0] * self.normal[0] + d[:, 1] * self.normal[1] + d[:, 2] * self.normal[2]

    def distance(self, x: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
        """phi = |s| (n,) and its gradient (n, 3): the plane runs through the whole convex body."""
        s = self.signed(x)
        front = s >= -1e-9 * delta      # a rounding error behind the plane is on it
        return np.where(front, s, -s), np.where(front[:, None], self.normal, -self.normal)


@dataclass(frozen=True, eq=False)
class Polyhedron:
    """A convex body: faces (polygons (m_k, 3)), inward unit normals (k, 3), a kind per face.

    frame (3, 3): columns e_xi, e_eta, e_zeta of the body's local frame.
    """

    faces: tuple[np.ndarray, ...]
    normals: np.ndarray
    kinds: tuple[str, ...]
    frame: np.ndarray

    dim = 3
    arcs = ()
    convex = True
    tracked = False

    def __post_init__(self):
        if len(self.kinds) != len(self.faces):
            raise InputError(f"body has {len(self.faces)} faces but {len(self.kinds)} face kinds")
        for k, kind in enumerate(self.kinds):
            if kind not in EDGE_KINDS:
                raise InputError(f"face {k}: kind {kind!r} is not one of {', '.join(EDGE_KINDS)}")

    @property
    def n_edges(self) -> int:
        """Number of faces (the boundary pieces, as a 2D body's edges)."""
        return len(self.faces)

    @cached_property
    def offsets(self) -> np.ndarray:
        """(k,) c_k = n_k . x on face k."""
        return np.array([n @ f[0] for n, f in zip(self.normals, self.faces)])

    @cached_property
    def vertices(self) -> np.ndarray:
        return np.unique(np.concatenate(self.faces), axis=0)

    @cached_property
    def walls(self) -> tuple[Plane, ...]:
        """One plane per essential face, in face order."""
        return tuple(Plane(kind, (k,), self.faces[k][0], self.normals[k])
                     for k, kind in enumerate(self.kinds) if kind in ESSENTIAL_KINDS)

    @cached_property
    def ridges(self) -> tuple[tuple[int, int, np.ndarray, np.ndarray], ...]:
        """(a, b, start (3,), end (3,)) of every ridge: the segment where faces a < b meet."""
        return ridges(self.faces)

    def wall_of_edge(self, edge: int) -> int:
        for w, wall in enumerate(self.walls):
            if edge in wall.pieces:
                return w
        raise ValueError(f"face {edge} is not essential")

    @property
    def essential_edges(self) -> list[int]:
        return [k for k, kind in enumerate(self.kinds) if kind in ESSENTIAL_KINDS]

    def edges_of_kind(self, kind: str) -> list[int]:
        return [k for k, other in enumerate(self.kinds) if other == kind]

    def outward(self, k: int, x: np.ndarray) -> np.ndarray:
        """(n, 3) outward unit normals of face k at points x (n, 3)."""
        return np.broadcast_to(-self.normals[k], (len(x), 3)).copy()

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        """(n, k) signed distance of points x (n, 3) to each face's plane, > 0 inside."""
        return x @ self.normals.T - self.offsets[None, :]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    @property
    def volume(self) -> float:
        """By the divergence theorem: (1/3) sum_k area_k (x_k . outward n_k)."""
        total = 0.0
        for face, n in zip(self.faces, self.normals):
            triangles = fan(face)
            total += float(np.sum(polytope.measure(triangles))) * float(-n @ face[0]) / 3
        return total

    def clip(self, vertices: np.ndarray, owner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The parts of simplices (m, k+1, 3) inside the body."""
        return polytope.clip_all(vertices, owner, -self.normals, -self.offsets)

    def material_points(self, grid: Grid, ppc: int, rule: bool = True, domains: bool = False):
        """The body's material points (material_points below)."""
        return material_points(self, grid, ppc, rule, domains)


def ridges(faces) -> tuple[tuple[int, int, np.ndarray, np.ndarray], ...]:
    """(a, b, start (3,), end (3,)) of every segment where two faces a < b of a convex polyhedron
    meet (faces: polygons (m_k, 3)); faces meeting at a single vertex have no ridge."""
    corners = np.concatenate(list(faces))
    scale = float(np.abs(corners).max(initial=1.0))
    result = []
    for a, b in combinations(range(len(faces)), 2):
        shared = [p for p in faces[a] if np.min(np.linalg.norm(faces[b] - p, axis=1)) <= 1e-12 * scale]
        if len(shared) == 2:
            result.append((a, b, shared[0], shared[1]))
    return tuple(result)


def fan(polygon: np.ndarray) -> np.ndarray:
    """(m - 2, 3, 3) triangles fanning a convex planar polygon (m, 3) from its first vertex."""
    m = len(polygon)
    return np.stack([np.repeat(polygon[:1], m - 2, axis=0), polygon[1:-1], polygon[2:]], axis=1)


def box(size, kinds: tuple[str, ...], frame: np.ndarray, corner) -> Polyhedron:
    """A box L x H x W (along xi, eta, zeta) with its base corner at `corner`, faces in FACES order."""
    size = np.asarray(size, float)
    if size.shape != (3,) or not np.all(np.isfinite(size)) or np.any(size <= 0):
        raise InputError(f"box sides must be three positive numbers, got {size.tolist()}")
    if len(kinds) != 6:
        raise InputError(f"a box has six faces ({', '.join(FACES)}); {len(kinds)} kinds given")
    L, H, W = size
    c = np.array([[0, 0, 0], [L, 0, 0], [L, H, 0], [0, H, 0],
                  [0, 0, W], [L, 0, W], [L, H, W], [0, H, W]], float)       # local corners
    local_faces = ([0, 1, 5, 4], [1, 2, 6, 5], [3, 7, 6, 2], [0, 4, 7, 3], [0, 3, 2, 1], [4, 5, 6, 7])
    corner = np.asarray(corner, float)
    placed = corner + c @ frame.T
    faces = tuple(placed[list(f)] for f in local_faces)
    return Polyhedron(faces, -BOX_OUTWARD @ frame.T, tuple(kinds), frame)


# --- pieces of cells --------------------------------------------------------------------------

def plane_ranges(corner: np.ndarray, normal: np.ndarray, offset: float, size: float):
    """Lowest and highest (n,) of n . x - offset over the boxes of side `size` with lowest corners (n, 3)."""
    base = corner @ normal - offset
    return base + size * np.minimum(normal, 0).sum(), base + size * np.maximum(normal, 0).sum()


def classify(body: Polyhedron, corner: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """(inside, cut) booleans (n,) of boxes of side `size` at corners (n, 3): wholly inside, or met by a face."""
    inside = np.ones(len(corner), bool)
    outside = np.zeros(len(corner), bool)
    for n, c in zip(body.normals, body.offsets):        # s_k is linear: its range over a box from one corner
        low, high = plane_ranges(corner, n, c, size)
        inside &= low >= 0
        outside |= high <= 0
    return inside, ~inside & ~outside


def _lattice_boxes(body: Polyhedron, origin: np.ndarray, size: float):
    """Integer lattice indices (n, 3) and lowest corners (n, 3) of the boxes of side `size` from
    `origin` that cover the body's bounding box."""
    lo, hi = body.bounds()
    k0 = np.floor((lo - origin) / size).astype(int)
    k1 = np.ceil((hi - origin) / size).astype(int)
    k = lattice([np.arange(a, b) for a, b in zip(k0, k1)])
    return k, origin + size * k


def material_points(body: Polyhedron, grid: Grid, ppc: int, rule: bool = True, domains: bool = False):
    """The seed's points in 3D: ppc^3 cubes of side h/ppc per cell, clipped by the body; each
    point at its clipped cube's centroid, with its volume. With `rule`, the exact cell rule the
    small-strain forms integrate with (cell_rule); load steps integrate with the points themselves.
    With `domains`, the clipped cubes as tetrahedra (ibm.discretise.simplex_domains), for the GIMP basis."""
    if isinstance(ppc, bool) or not isinstance(ppc, (int, np.integer)) or ppc < 1:
        raise InputError(f"points per cell ppc={ppc!r} is not allowed; it must be an integer >= 1")
    s = grid.h / ppc
    k, corner = _lattice_boxes(body, grid.origin, s)
    inside, cut = classify(body, corner, s)
    vertices, owner = body.clip(*polytope.box_simplices(corner[cut], corner[cut] + s))
    volume, centroid = polytope.volumes_and_centroids(vertices, owner, int(cut.sum()))
    keep = volume > 1e-12 * s ** 3
    x = np.concatenate([corner[inside] + s / 2, centroid[keep]])
    volumes = np.concatenate([np.full(int(inside.sum()), s ** 3), volume[keep]])
    cell_ij = np.concatenate([k[inside], k[cut][keep]]) // ppc
    if np.any((cell_ij < 0) | (cell_ij >= np.array(grid.shape))):
        raise InputError("the body leaves the grid; use a grid that covers it (Grid.covering)")
    point_domains = None
    if domains:             # whole cubes first, then the kept cut ones, as the points
        n_inside = int(inside.sum())
        whole, whole_owner = polytope.box_simplices(corner[inside], corner[inside] + s)
        renumbered = n_inside + np.cumsum(keep) - 1                          # cut box -> point
        kept = keep[owner]
        point_domains = SimplexDomains(np.concatenate([whole, vertices[kept]]),
                                       np.concatenate([whole_owner, renumbered[owner[kept]]]), len(x))
    return MaterialPoints(x=x, volume=volumes, cells=grid.cell_index(cell_ij), domains=point_domains,
                          rule=cell_rule(body, grid) if rule else None)


def cell_rule(body: Polyhedron, grid: Grid) -> QuadraturePoints:
    """Quadrature of body ∩ cell exact for the ordinary trilinear forms (B^T C B: degree 2 per
    axis, 4 in all): 2 x 2 x 2 Gauss points in cells wholly inside, a moment-fitted rule of
    degree 4 (35 nodes, ibm.quadrature.moment_fitting) in cut cells.

    Why not the points themselves, as in 2D: a trilinear gradient has bilinear terms (b c in
    dN/da), which one point at a clipped domain's centroid does not integrate (only linear
    ones), so sum_p V_p dN(x_p) != int dN and a uniform stress leaves forces on the nodes of
    cut cells: the patch test fails on any face oblique to two grid axes. Points stay the
    seed's (positions, volumes: output and state); forms use this rule.
    """
    cells = _body_cells(body, grid)
    low, _ = _cell_ranges(body, grid, cells)
    whole = cells[np.all(low >= 0, axis=0)]
    cut = cells[~np.all(low >= 0, axis=0)]
    g = (1 + np.array([-1.0, 1.0]) / np.sqrt(3)) / 2
    reference = g[lattice([np.arange(2)] * 3)]                               # (8, 3)
    x = [(grid.cell_corners(whole)[:, None, :] + grid.h * reference[None]).reshape(-1, 3)]
    weight = [np.full(8 * len(whole), grid.h ** 3 / 8)]
    owner = [np.repeat(whole, 8)]
    if len(cut):
        corner = grid.cell_corners(cut)
        vertices, which = body.clip(*polytope.box_simplices(corner, corner + grid.h))
        xq, wq, cq, _, _ = moment_fitting.fitted(vertices, cut[which], np.eye(3), 4)
        x.append(xq)
        weight.append(wq)
        owner.append(cq)
    return QuadraturePoints(np.concatenate(x), np.concatenate(weight), np.concatenate(owner))


def _cell_ranges(body: Polyhedron, grid: Grid, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(faces, n) lowest and highest s_k over each cell."""
    corner = grid.cell_corners(cells)
    ranges = [plane_ranges(corner, n, c, grid.h) for n, c in zip(body.normals, body.offsets)]
    return np.array([r[0] for r in ranges]), np.array([r[1] for r in ranges])


def _body_cells(body: Polyhedron, grid: Grid) -> np.ndarray:
    """Cells meeting the body's interior."""
    lo, hi = body.bounds()
    cells = grid.cells_overlapping(lo, hi)
    _, high = _cell_ranges(body, grid, cells)
    return cells[np.all(high > 0, axis=0)]


def check_delta(body: Polyhedron, delta: float) -> None:
    """delta > 0 and below half the body's width across every essential face."""
    if not (np.isfinite(delta) and delta > 0):
        raise InputError(f"band width delta={delta} is not allowed; it must be > 0")
    for wall in body.walls:
        width = float(wall.signed(body.vertices).max())
        if delta >= 0.5 * width:
            raise InputError(f"band width delta={delta:.6g} is not allowed; it must be < {0.5 * width:.6g} "
                             f"(half the body's width across face {wall.pieces[0]})")


def region_pieces(body: Polyhedron, grid: Grid, delta: float, cells: np.ndarray, S: tuple[int, ...]):
    """Tetrahedra of R_S (module doc) in each of `cells`, and the cell of each: the slabs
    0 <= s_k <= delta of the walls in S (one cut each, ibm.geometry.polytope.slab), then the other faces'
    half-spaces and s_j >= delta for the other walls."""
    corner = grid.cell_corners(cells)
    vertices, owner = polytope.box_simplices(corner, corner + grid.h)
    owner = cells[owner]
    in_slab = set()
    for w in S:
        wall = body.walls[w]
        c = wall.normal @ wall.point
        vertices, owner = polytope.slab(vertices, owner, wall.normal, c, c + delta)
        in_slab.add(wall.pieces[0])
    for k, (n, c) in enumerate(zip(body.normals, body.offsets)):
        if k not in in_slab:
            vertices, owner = polytope.clip(vertices, owner, -n, -c)
    for w, wall in enumerate(body.walls):
        if w not in S:            # s_w >= delta
            vertices, owner = polytope.clip(vertices, owner, -wall.normal, -(delta + wall.normal @ wall.point))
    return vertices, owner


def band_frame(body: Polyhedron, S: tuple[int, ...]) -> np.ndarray:
    """(3, 3) rows: the normals of the walls in S, then unit tangents completing them (band coordinates)."""
    normals = np.array([body.walls[w].normal for w in S])
    if len(S) == 3:
        return normals
    if len(S) == 2:
        t = np.cross(normals[0], normals[1])
        return np.vstack([normals, t / np.linalg.norm(t)])
    q, _ = np.linalg.qr(np.column_stack([normals[0], np.eye(3)]))      # q[:, 0] = +-n
    return np.vstack([normals, q[:, 1:3].T])


def band_quadrature(body: Polyhedron, grid: Grid, delta: float, rule: str = "fitted",
                    degree: int | None = None) -> QuadraturePoints:
    """A moment-fitted rule (ibm.quadrature.moment_fitting) per band region R_S and cell, exact for the
    band correction (degree 4 |S| + 4); each point carries S as a bit mask (QuadraturePoints.region).
    rule "simplex": the Gauss points of the region's tetrahedra instead (degree `degree`, default
    4 |S| + 4): positive weights and points inside the region, for integrands that are not
    polynomials (the band at finite strain), at many more points.

    Pieces below 1e-9 delta h^2 are slivers of rounding (a band plane on a cell face computed a
    few ulps off) and are dropped: they would give nodes outside the body a support of ~1e-15.
    """
    if rule not in ("fitted", "simplex"):
        raise InputError(f"band rule {rule!r} is not allowed; allowed: 'fitted', 'simplex'")
    check_delta(body, delta)
    cells = _body_cells(body, grid)
    low, high = _cell_ranges(body, grid, cells)
    walls = body.walls
    face = [wall.pieces[0] for wall in walls]
    x, weight, owner_cells, region = [], [], [], []
    for size in range(1, min(3, len(walls)) + 1):
        for S in combinations(range(len(walls)), size):
            # cells where every band of S may reach (s_k < delta somewhere) and the others may end
            meet = np.all(low[[face[w] for w in S]] < delta, axis=0)
            others = [face[w] for w in range(len(walls)) if w not in S]
            if others:
                meet &= np.all(high[others] > delta, axis=0)
            if not np.any(meet):
                continue
            vertices, owner = region_pieces(body, grid, delta, cells[meet], S)
            volume = polytope.sums(owner, polytope.measure(vertices), grid.n_cells)
            keep = volume[owner] >= 1e-9 * delta * grid.h ** 2
            if not np.any(keep):
                continue
            frame = band_frame(body, S)
            if abs(np.linalg.det(frame)) < 1e-9:
                raise InputError(f"the bands of faces {[face[w] for w in S]} meet along no edge or corner "
                                 "(parallel faces closer than two band widths)")
            if rule == "simplex":
                xq, wq, which = polytope.quadrature(vertices[keep], owner[keep], degree or 4 * size + 4)
            else:
                xq, wq, which, _, _ = moment_fitting.fitted(vertices[keep], owner[keep], frame, 4 * size + 4)
            x.append(xq)
            weight.append(wq)
            owner_cells.append(which)
            region.append(np.full(len(wq), sum(1 << w for w in S)))
    if not x:
        return QuadraturePoints(np.zeros((0, 3)), np.zeros(0), np.zeros(0, int), np.zeros(0, int))
    return QuadraturePoints(np.concatenate(x), np.concatenate(weight), np.concatenate(owner_cells),
                            np.concatenate(region))


def face_quadrature(body: Polyhedron, grid: Grid, face: int, delta: float | None, degree: int = 9) -> QuadraturePoints:
    """Points on face `face` in every cell it crosses, split at the planes s_k = delta of the
    essential faces (where D has a kink), with a triangle rule of `degree` (trilinear N times
    the Dirichlet factors of at most two bands meeting on a face: degree 7, and the traction's)."""
    polygon = body.faces[face]
    cells = grid.cells_overlapping(*[f(polygon, axis=0) for f in (np.min, np.max)])
    triangles = fan(polygon)
    vertices = np.repeat(triangles[None], len(cells), axis=0).reshape(-1, 3, 3)
    owner = np.repeat(cells, len(triangles))
    for a in range(3):        # the cell's six planes, one normal per simplex
        corner = grid.cell_corners(owner)[:, a]
        normal = np.zeros((len(owner), 3))
        normal[:, a] = 1.0
        vertices, owner = polytope.clip(vertices, owner, -normal, -corner)
        corner = grid.cell_corners(owner)[:, a]
        normal = np.zeros((len(owner), 3))
        normal[:, a] = 1.0
        vertices, owner = polytope.clip(vertices, owner, normal, corner + grid.h)
    if delta is not None and delta > 0:
        for wall in body.walls:
            if wall.pieces[0] == face:
                continue
            level = delta + wall.normal @ wall.point
            near = polytope.clip(vertices, owner, wall.normal, level)
            far = polytope.clip(vertices, owner, -wall.normal, -level)
            vertices, owner = np.concatenate([near[0], far[0]]), np.concatenate([near[1], far[1]])
    x, weight, which = polytope.quadrature(vertices, owner, degree)
    return QuadraturePoints(x, weight, which)


def body_quadrature(body: Polyhedron, grid: Grid, order: int = 4, delta: float | None = None,
                    rule: str = "fitted") -> QuadraturePoints:
    """Quadrature over the body, exact for polynomials of degree 2 order - 2 on every piece:
    cells wholly inside (and clear of the bands) by an order^3 Gauss rule; in the others each
    band region R_S (S empty too, with delta) and cell gets a moment-fitted rule (rule "fitted",
    ibm.quadrature.moment_fitting: few nodes, in the piece's box, weights of either sign), or the Gauss points
    of its tetrahedra (rule "simplex": positive weights, points inside, many more). Points carry S
    (QuadraturePoints.region), so that an IBM field is evaluated there with R_S's Dirichlet
    functions; region 0: plain (D = I).

    Error norms integrate functions that are not polynomials, on which a fitted rule errs by an
    amount that depends on its nodes (fixed, ibm.quadrature.moment_fitting.NODES_FILE). Measured on
    `manufactured` at (30, 20) with the IBM, fitted against simplex: err_energy 0.05494 / 0.05491
    at h = 6.25 (0.05 %; 38 s and 0.6 GB against 66 s and 4.6 GB for the whole command); at h = 25
    two equally good node sets gave err_energy 2 % apart, the simplex points none."""
    if rule not in ("fitted", "simplex"):
        raise InputError(f"body rule {rule!r} is not allowed; allowed: 'fitted', 'simplex'")
    cells = _body_cells(body, grid)
    low, high = _cell_ranges(body, grid, cells)
    clear = np.all(low >= 0, axis=0)
    walls = body.walls if delta is not None and delta > 0 else ()
    face = [wall.pieces[0] for wall in walls]
    if face:
        clear &= np.all(low[face] >= delta, axis=0)
    g, w = np.polynomial.legendre.leggauss(order)
    g, w = (g + 1) / 2, w / 2
    index = lattice([np.arange(order)] * 3)                             # (order^3, 3)
    reference, reference_weight = g[index], np.prod(w[index], axis=1)
    whole = cells[clear]
    x = [(grid.cell_corners(whole)[:, None, :] + grid.h * reference[None]).reshape(-1, 3)]
    weight = [np.tile(reference_weight * grid.h ** 3, len(whole))]
    owner_cells = [np.repeat(whole, len(reference_weight))]
    region = [np.zeros(len(weight[0]), int)]
    rest, low, high = cells[~clear], low[:, ~clear], high[:, ~clear]
    for size in range(0, min(3, len(walls)) + 1):
        for S in combinations(range(len(walls)), size):
            meet = np.ones(len(rest), bool)
            if S:
                meet &= np.all(low[[face[w] for w in S]] < delta, axis=0)
            others = [face[w] for w in range(len(walls)) if w not in S]
            if others:
                meet &= np.all(high[others] > delta, axis=0)
            if not np.any(meet):
                continue
            vertices, owner = region_pieces(body, grid, delta, rest[meet], S) if walls else \
                body.clip(*polytope.box_simplices(grid.cell_corners(rest), grid.cell_corners(rest) + grid.h))
            if not walls:
                owner = rest[owner]
            if len(vertices) == 0:
                continue
            frame = band_frame(body, S) if S else np.eye(3)
            if rule == "simplex":
                xq, wq, which = polytope.quadrature(vertices, owner, 2 * order - 2)
            else:
                xq, wq, which, _, _ = moment_fitting.fitted(vertices, owner, frame, 2 * order - 2)
            x.append(xq)
            weight.append(wq)
            owner_cells.append(which)
            region.append(np.full(len(wq), sum(1 << w for w in S)))
    return QuadraturePoints(np.concatenate(x), np.concatenate(weight), np.concatenate(owner_cells),
                            np.concatenate(region) if walls else None)
