"""Bodies: closed counter-clockwise outlines of straight pieces, one boundary kind per piece.

Piece (edge) k runs from vertex k to vertex k+1; non-convex outlines are allowed, and a
straight side may be split into collinear pieces of different kinds. Its inward unit
normal n_k and the signed distance s_k(x) = (x - x_k) . n_k to its line are the geometry
every method uses.

The Dirichlet functions of the implicit boundary method belong to walls: maximal runs of
collinear essential pieces of one kind (ibm.walls_of). A wall's distance is the largest of
|s|, the distance past its start and the distance past its end, measured in the wall's own
frame (a box distance, piecewise linear, so that bands stay polygons and their quadrature
exact): where a wall meets another at a convex corner its band runs on along its line far
enough to cover the corner region inside the body, as the seed's line distance does; where
it ends inside a straight side or at a re-entrant corner the band ends there.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely

from ibm.exceptions import InputError

EDGE_KINDS = ("roller", "fixed", "traction", "free")
ESSENTIAL_KINDS = ("roller", "fixed")



@dataclass(frozen=True)
class Arc:
    """A circular piece about `center`: counter-clockwise about it (the body on the centre's side,
    a convex bulge) unless `clockwise` (the body away from the centre: a hole or a fillet)."""

    center: np.ndarray
    clockwise: bool = False


@dataclass(frozen=True, eq=False)
class Segments:
    """Circular segments between sub-arcs and their chords: the body is the chord polygon plus
    (sign +1) or minus (sign -1) these. Sub-arc j runs over angles theta0[j] .. theta1[j]
    (increasing) about center[j] (n, 2) with radius[j]; piece[j] is the piece it belongs to."""

    center: np.ndarray
    radius: np.ndarray
    theta0: np.ndarray
    theta1: np.ndarray
    sign: np.ndarray
    piece: np.ndarray

    def __len__(self) -> int:
        return len(self.radius)

    def subset(self, index: np.ndarray) -> "Segments":
        return Segments(self.center[index], self.radius[index], self.theta0[index], self.theta1[index],
                        self.sign[index], self.piece[index])

    @property
    def _excess(self) -> np.ndarray:
        """(n,) d - sin d for the sub-arcs' angles d (a series for small d: no cancellation)."""
        d = self.theta1 - self.theta0
        return np.where(d < 1e-2, d ** 3 / 6 - d ** 5 / 120 + d ** 7 / 5040 - d ** 9 / 362880, d - np.sin(d))

    @property
    def area(self) -> np.ndarray:
        """(n,) signed areas R^2 (d - sin d) / 2, d = theta1 - theta0."""
        return self.sign * self.radius ** 2 * self._excess / 2

    @property
    def centroid(self) -> np.ndarray:
        """(n, 2) centroids: at 4 R sin^3(d / 2) / (3 (d - sin d)) from the centre, on the bisector."""
        d = self.theta1 - self.theta0
        distance = 4 * self.radius * np.sin(d / 2) ** 3 / (3 * self._excess)
        mid = (self.theta0 + self.theta1) / 2
        return self.center + distance[:, None] * np.stack([np.cos(mid), np.sin(mid)], axis=1)

    def quadrature(self, order: int, radial: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points (n q, 2), signed weights (n q,) and segment index (n q,) over the segments.

        Polar about each centre: psi over the sub-arc, rho from the chord, R cos(d/2) / cos(psi - mid),
        to R; a polynomial of degree p in x is one of degree p + 1 in rho (`radial` points exact for
        p <= 2 radial - 2), and analytic in psi over an interval far inside its poles at +-pi/2.
        """
        g, w = np.polynomial.legendre.leggauss(order)
        gr, wr = np.polynomial.legendre.leggauss(radial)
        d = (self.theta1 - self.theta0)[:, None, None]
        mid = ((self.theta0 + self.theta1) / 2)[:, None, None]
        psi = mid + d / 2 * g[None, :, None]                                  # (n, q, 1)
        inner = self.radius[:, None, None] * np.cos(d / 2) / np.cos(psi - mid)
        outer = self.radius[:, None, None]
        rho = inner + (outer - inner) * (gr[None, None, :] + 1) / 2           # (n, q, r)
        weight = (d / 2 * w[None, :, None]) * ((outer - inner) / 2 * wr[None, None, :]) * rho
        x = self.center[:, None, None, :] + rho[..., None] * np.stack([np.cos(psi), np.sin(psi)], axis=-1)
        count = order * radial
        return (x.reshape(-1, 2), (weight * self.sign[:, None, None]).ravel(),
                np.repeat(np.arange(len(self)), count))


@dataclass(frozen=True)
class Wall:
    """A run of collinear essential pieces of one kind: the support of one Dirichlet function.

    start (2,), tangent and normal (2,) unit vectors (normal inward), length L; the band runs
    on past the start by extend[0] delta and past the end by extend[1] delta (0: it ends there).
    """

    kind: str
    pieces: tuple[int, ...]
    start: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    length: float
    extend: tuple[float, float]

    curved = False

    def signed(self, x: np.ndarray) -> np.ndarray:
        """Signed distance s (n,) to the wall's line (> 0 on the body's side)."""
        return self.local(x)[0]

    def local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance s (n,) to the wall's line and coordinate t (n,) along it, of points x (n, 2)."""
        d0, d1 = x[:, 0] - self.start[0], x[:, 1] - self.start[1]
        return d0 * self.normal[0] + d1 * self.normal[1], d0 * self.tangent[0] + d1 * self.tangent[1]

    def distance(self, x: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
        """phi (n,) = max(|s|, -t - e0, t - L - e1) and its gradient (n, 2) (see the module doc)."""
        s, t = self.local(x)
        # a point a rounding error behind the line is on it: the front branch, gradient +n
        front = s >= -1e-9 * delta
        branches = np.stack([np.where(front, s, -s), -t - self.extend[0] * delta,
                             t - self.length - self.extend[1] * delta])
        branch = np.argmax(branches, axis=0)
        gradients = np.stack([np.where(front[:, None], self.normal, -self.normal),
                              np.broadcast_to(-self.tangent, (len(t), 2)),
                              np.broadcast_to(self.tangent, (len(t), 2))])
        return branches[branch, np.arange(len(t))], gradients[branch, np.arange(len(t))]

    def branch_polygons(self, delta: float) -> list[np.ndarray]:
        """Vertices (m, 2) of the four regions of {phi < delta} where phi is one linear function:
        in front of the line, behind it, past the start, past the end."""
        e0, e1 = self.extend[0] * delta, self.extend[1] * delta
        L, d = self.length, delta
        local = [np.array([[-e0, 0], [L + e1, 0], [L + e1 + d, d], [-e0 - d, d]]),
                 np.array([[-e0, 0], [-e0 - d, -d], [L + e1 + d, -d], [L + e1, 0]]),
                 np.array([[-e0, 0], [-e0 - d, d], [-e0 - d, -d]]),
                 np.array([[L + e1, 0], [L + e1 + d, -d], [L + e1 + d, d]])]
        return [self.start + p[:, :1] * self.tangent + p[:, 1:] * self.normal for p in local]

    def box(self, delta: float) -> np.ndarray:
        """Vertices (4, 2) of the band's rectangle {phi < delta}, counter-clockwise."""
        e0, e1 = self.extend[0] * delta, self.extend[1] * delta
        t0, t1 = -e0 - delta, self.length + e1 + delta
        local = np.array([[t0, -delta], [t1, -delta], [t1, delta], [t0, delta]])
        return self.start + local[:, :1] * self.tangent + local[:, 1:] * self.normal


@dataclass(frozen=True)
class ArcWall:
    """An essential circular piece: the support of one Dirichlet function with a varying normal.

    The body lies inside the circle (sign +1, a convex arc) or outside it (sign -1, a hole) near
    the arc; phi = sign (R - rho) (rho = |x - center|) inside the wedge of angles theta0 ..
    theta0 + sweep (sweep > 0) that the arc spans, and infinite outside it, so the band
    {phi < delta} is the annular sector beside the arc. The arc meets its neighbours at right
    angles (walls_of checks), so the body within delta of the arc lies in the wedge.
    The inward normal n = -sign e_r equals grad phi.
    """

    kind: str
    pieces: tuple[int, ...]
    center: np.ndarray
    radius: float
    sign: float
    theta0: float
    sweep: float

    curved = True

    def polar(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """rho (n,) and the angle past theta0 in [0, 2 pi) (n,) of points x (n, 2)."""
        d = x - self.center
        return np.hypot(d[:, 0], d[:, 1]), np.mod(np.arctan2(d[:, 1], d[:, 0]) - self.theta0, 2 * np.pi)

    def in_wedge(self, angle: np.ndarray) -> np.ndarray:
        # a point a rounding error outside a radial side of the wedge is on it
        return (angle <= self.sweep + 1e-12) | (angle >= 2 * np.pi - 1e-12)

    def signed(self, x: np.ndarray) -> np.ndarray:
        """phi (n,) with its sign (> 0 on the body's side), inf outside the wedge."""
        rho, angle = self.polar(x)
        return np.where(self.in_wedge(angle), self.sign * (self.radius - rho), np.inf)

    def normal_at(self, x: np.ndarray) -> np.ndarray:
        """(n, 2) inward unit normals -sign e_r at points x (n, 2)."""
        d = x - self.center
        return -self.sign * d / np.hypot(d[:, 0], d[:, 1])[:, None]

    def distance(self, x: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
        """phi = |sign (R - rho)| (n,) (inf outside the wedge) and its gradient (n, 2)."""
        s = self.signed(x)
        n = self.normal_at(x)
        front = s >= -1e-9 * delta
        return np.where(front, s, -s), np.where(front[:, None], n, -n)

    def sides(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit directions (2,) of the wedge's two radial sides, at theta0 and theta0 + sweep."""
        a, b = self.theta0, self.theta0 + self.sweep
        return np.array([np.cos(a), np.sin(a)]), np.array([np.cos(b), np.sin(b)])

    def sector(self, inner: float, outer: float, max_angle: float = np.radians(2.0)) -> np.ndarray:
        """(m, 2) a polygon holding the annular sector inner <= rho <= outer of the wedge (its outer
        arc by tangent-chords pushed out so that the polygon contains the arc)."""
        count = int(np.ceil(self.sweep / max_angle))
        theta = self.theta0 + np.linspace(0, self.sweep, count + 1)
        push = outer / np.cos(self.sweep / count / 2)
        mid = self.theta0 + (np.arange(count) + 0.5) * self.sweep / count
        ring = [self.center + inner * np.stack([np.cos(theta), np.sin(theta)], 1)[::-1],
                self.center + outer * np.array([[np.cos(self.theta0), np.sin(self.theta0)]]),
                self.center + push * np.stack([np.cos(mid), np.sin(mid)], 1),
                self.center + outer * np.array([[np.cos(theta[-1]), np.sin(theta[-1])]])]
        return np.concatenate(ring)


@dataclass(frozen=True, eq=False)
class Body:
    """A closed outline of straight pieces with one boundary kind per piece.

    vertices: (n_edges, 2), counter-clockwise; edge (piece) k joins vertex k and vertex k+1.
    kinds: one of EDGE_KINDS per edge.
    frame: (2, 2) columns e_xi, e_eta of the body's local frame (for reporting).
    tracked: the outline a large deformation carries along (ibm.large.walls.Outline) is not checked
    for self-intersection (a body folding onto itself is the load-step loop's to report).
    """

    vertices: np.ndarray
    kinds: tuple[str, ...]
    frame: np.ndarray = None  # type: ignore[assignment]
    tracked: bool = False
    arcs: tuple = ()          # per piece an Arc or None; () for straight pieces only

    dim = 2

    def __post_init__(self):
        v = np.asarray(self.vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
            raise InputError(f"body vertices must be an (n >= 3, 2) array, got shape {v.shape}")
        if not np.all(np.isfinite(v)):
            raise InputError("body vertices must be finite numbers")
        if len(self.kinds) != len(v):
            raise InputError(f"body has {len(v)} edges but {len(self.kinds)} edge kinds")
        for k, kind in enumerate(self.kinds):
            if kind not in EDGE_KINDS:
                raise InputError(f"piece {k}: kind {kind!r} is not one of {', '.join(EDGE_KINDS)}")
        # Coordinates below the rounding unit of the body's extent carry no information, and
        # subnormal ones (~1e-308) make the polygon clipping lose area: snap them to zero.
        v = np.where(np.abs(v) < 1e-15 * np.abs(v).max(), 0.0, v)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "kinds", tuple(self.kinds))
        if self.frame is None:
            object.__setattr__(self, "frame", np.eye(2))
        lengths = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
        short = np.flatnonzero(lengths <= 1e-12 * lengths.max())
        if len(short):
            k = int(short[0])
            raise InputError(f"piece {k} from {_point(v[k])} to {_point(v[(k + 1) % len(v)])} has zero length")
        arcs = tuple(self.arcs) if self.arcs else ()
        if arcs and len(arcs) != len(v):
            raise InputError(f"body has {len(v)} pieces but {len(arcs)} arc entries")
        if all(arc is None for arc in arcs):
            arcs = ()
        object.__setattr__(self, "arcs", arcs)
        for k, arc in enumerate(arcs):
            if arc is not None:
                _check_arc(k, v[k], v[(k + 1) % len(v)], arc, self.kinds[k])
        if not self.tracked:
            _check_simple(self.ring(_CHECK_ANGLE) if arcs else v)
        if self.area <= 0:
            raise InputError(f"the outline runs clockwise (signed area {self.area:.6g}); "
                             "pieces must run counter-clockwise, with the body on their left")

    @property
    def convex(self) -> bool:
        """No re-entrant corner (a straight angle between collinear pieces counts as convex); a body
        with arcs counts as not convex (its pieces are not the lines of its straight edges)."""
        return not self.arcs and bool(np.all(self.turns >= -1e-12))

    @property
    def turns(self) -> np.ndarray:
        """(n_edges,) signed turning angle at the end of each edge (> 0 at a convex corner), between
        the pieces' own tangents there (an arc's, not its chord's)."""
        if self.arcs:
            t = np.array([self.end_tangent(k, 0) for k in range(self.n_edges)])
            t_next = np.roll([self.end_tangent(k, 1) for k in range(self.n_edges)], -1, axis=0)
        else:
            t, t_next = self.tangents, np.roll(self.tangents, -1, axis=0)
        cross = t[:, 0] * t_next[:, 1] - t[:, 1] * t_next[:, 0]
        return np.arctan2(cross, np.sum(t * t_next, axis=1))

    @cached_property
    def walls(self) -> tuple["Wall | ArcWall", ...]:
        """The walls of the essential pieces (see the module doc): arcs first, then straight walls
        in the order of their first piece."""
        return walls_of(self)

    def wall_of_edge(self, edge: int) -> int:
        """Index into `walls` of the wall holding essential edge `edge`."""
        for w, wall in enumerate(self.walls):
            if edge in wall.pieces:
                return w
        raise ValueError(f"edge {edge} is not essential")

    @property
    def n_edges(self) -> int:
        return len(self.vertices)

    @property
    def starts(self) -> np.ndarray:
        """(n_edges, 2) first vertex of each edge."""
        return self.vertices

    @property
    def ends(self) -> np.ndarray:
        """(n_edges, 2) second vertex of each edge."""
        return np.roll(self.vertices, -1, axis=0)

    @property
    def tangents(self) -> np.ndarray:
        """(n_edges, 2) edge vectors end - start (not normalised)."""
        return self.ends - self.starts

    @property
    def lengths(self) -> np.ndarray:
        return np.linalg.norm(self.tangents, axis=1)

    @property
    def normals(self) -> np.ndarray:
        """(n_edges, 2) inward unit normals (tangent turned by +90 degrees)."""
        t = self.tangents / self.lengths[:, None]
        return np.stack([-t[:, 1], t[:, 0]], axis=1)

    @property
    def area(self) -> float:
        """Signed area (> 0 counter-clockwise), arcs included exactly."""
        ring, segments = self.chords(np.radians(10.0), None) if self.arcs else (self.vertices, None)
        x, y = ring.T
        chords = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
        return chords + float(np.sum(segments.area)) if self.arcs else chords

    def end_tangent(self, k: int, start: int) -> np.ndarray:
        """(2,) unit direction of travel of piece k at its start (start=1) or its end (start=0)."""
        arc = self.arcs[k] if self.arcs else None
        if arc is None:
            return self.tangents[k] / self.lengths[k]
        radius, theta, sweep = self.arc_angles(k)
        angle = theta if start else theta + sweep
        # d/dtheta (cos, sin) = (-sin, cos), run in the sweep's sense
        return np.sign(sweep) * np.array([-np.sin(angle), np.cos(angle)])

    def arc_angles(self, k: int) -> tuple[float, float, float]:
        """Radius, start angle and signed sweep (> 0 counter-clockwise) of arc piece k."""
        return _arc_angles(self.vertices[k], self.vertices[(k + 1) % self.n_edges], self.arcs[k])

    def ring(self, max_angle: float = np.radians(10.0), lines: list | None = None) -> np.ndarray:
        """(m, 2) the chord polygon (see chords)."""
        return self.chords(max_angle, lines)[0]

    def segments(self, max_angle: float = np.radians(10.0), lines: list | None = None) -> Segments:
        """The circular segments beyond the chords (see chords)."""
        return self.chords(max_angle, lines)[1]

    def chords(self, max_angle: float = np.radians(10.0), lines: list | None = None) -> tuple[np.ndarray, Segments]:
        """The chord polygon (m, 2): the vertices, and on each arc the points where it crosses `lines`
        (ibm.geometry.outline.Lines: families of parallel lines), subdivided to at most max_angle; and the
        circular segments between those chords and the arcs."""
        ring, parts = [], []
        for k in range(self.n_edges):
            ring.append(self.vertices[k][None])
            arc = self.arcs[k] if self.arcs else None
            if arc is None:
                continue
            radius, start, sweep = self.arc_angles(k)
            c = np.asarray(arc.center, float)
            theta = arc_cuts(c, radius, start, sweep, max_angle, lines)
            inner = c + radius * np.stack([np.cos(theta[1:-1]), np.sin(theta[1:-1])], axis=1)
            ring.append(inner)
            low, high = np.minimum(theta[:-1], theta[1:]), np.maximum(theta[:-1], theta[1:])
            n = len(low)
            parts.append((np.tile(c, (n, 1)), np.full(n, radius), low, high,
                          np.full(n, -1.0 if arc.clockwise else 1.0), np.full(n, k)))
        if not parts:
            empty = np.zeros(0)
            return np.concatenate(ring), Segments(np.zeros((0, 2)), empty, empty, empty, empty, np.zeros(0, int))
        return np.concatenate(ring), Segments(*(np.concatenate(column) for column in zip(*parts)))

    def polyline(self, max_angle: float = np.radians(2.0)) -> tuple[np.ndarray, np.ndarray]:
        """The outline for drawing: points (m, 2) (arcs as chords of at most max_angle) and the
        piece (m,) each segment from point i to point i + 1 (cyclically) belongs to."""
        if not self.arcs:
            return self.vertices, np.arange(self.n_edges)
        points, pieces = [], []
        for k in range(self.n_edges):
            if self.arcs[k] is None:
                points.append(self.vertices[k][None])
                pieces.append([k])
                continue
            radius, start, sweep = self.arc_angles(k)
            theta = start + np.linspace(0, sweep, int(np.ceil(abs(sweep) / max_angle)) + 1)[:-1]
            c = np.asarray(self.arcs[k].center, float)
            points.append(c + radius * np.stack([np.cos(theta), np.sin(theta)], axis=1))
            pieces.append([k] * len(theta))
        return np.concatenate(points), np.concatenate(pieces)

    def outward(self, k: int, x: np.ndarray) -> np.ndarray:
        """(n, 2) outward unit normals of piece k at points x (n, 2) on it."""
        arc = self.arcs[k] if self.arcs else None
        if arc is None:
            return np.broadcast_to(-self.normals[k], (len(x), 2)).copy()
        radial = x - np.asarray(arc.center, float)
        radial = radial / np.linalg.norm(radial, axis=1, keepdims=True)
        return -radial if arc.clockwise else radial

    @property
    def essential_edges(self) -> list[int]:
        return [k for k, kind in enumerate(self.kinds) if kind in ESSENTIAL_KINDS]

    def edges_of_kind(self, kind: str) -> list[int]:
        return [k for k, other in enumerate(self.kinds) if other == kind]

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        """(n, n_edges) signed distance of points x (n, 2) to each edge's line, > 0 inside."""
        s, n = self.starts, self.normals   # written out: twice as fast as einsum, same rounding
        return (x[:, 0, None] - s[None, :, 0]) * n[None, :, 0] + (x[:, 1, None] - s[None, :, 1]) * n[None, :, 1]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        points = self.ring(np.radians(1.0)) if self.arcs else self.vertices
        lo, hi = points.min(axis=0), points.max(axis=0)
        if self.arcs:   # a bulge between two ring points reaches at most its sagitta beyond them
            pad = max((self.arc_angles(k)[0] * (1 - np.cos(np.radians(0.5))) for k, arc in enumerate(self.arcs)
                       if arc is not None), default=0.0)
            lo, hi = lo - pad, hi + pad
        return lo, hi


_CHECK_ANGLE = np.radians(2.0)   # arcs as chords of at most 2 degrees when checking for crossings


@dataclass(frozen=True)
class Lines:
    """A family of parallel lines n . x = offset + k spacing (all integers k), or the single line
    n . x = offset when spacing is 0: where arcs are cut into chords."""

    normal: np.ndarray
    offset: float
    spacing: float = 0.0

    def crossings(self, center: np.ndarray, radius: float, start: float, sweep: float) -> np.ndarray:
        """Fractions in (0, 1) of the sweep at which the arc crosses the family's lines."""
        n = np.asarray(self.normal, float)
        base = float(n @ center)
        if self.spacing > 0:
            k = np.arange(np.floor((base - radius - self.offset) / self.spacing),
                          np.ceil((base + radius - self.offset) / self.spacing) + 1)
            values = self.offset + k * self.spacing
        else:
            values = np.array([self.offset])
        ratio = (values - base) / (radius * np.linalg.norm(n))
        ratio = ratio[np.abs(ratio) <= 1]
        alpha = np.arctan2(n[1], n[0])
        theta = np.concatenate([alpha + np.arccos(ratio), alpha - np.arccos(ratio)])
        fraction = np.mod((theta - start) * np.sign(sweep), 2 * np.pi) / abs(sweep)
        return fraction[(fraction > 0) & (fraction < 1)]


def arc_cuts(center: np.ndarray, radius: float, start: float, sweep: float, max_angle: float,
             lines: list | None) -> np.ndarray:
    """Angles from start to start + sweep at which an arc is cut into chords: where it crosses `lines`
    (Lines families), subdivided to at most max_angle."""
    fractions = [np.linspace(0, 1, int(np.ceil(abs(sweep) / max_angle)) + 1)]
    for family in lines or ():
        fractions.append(family.crossings(center, radius, start, sweep))
    f = np.unique(np.concatenate(fractions))
    f = f[np.concatenate([[True], np.diff(f) > 1e-12])]
    f[-1] = 1.0
    return start + f * sweep


def grid_lines(origin: np.ndarray, spacing: float) -> list[Lines]:
    """The lines x = origin_x + k spacing and y = origin_y + k spacing."""
    return [Lines(np.array([1.0, 0.0]), float(origin[0]), spacing), Lines(np.array([0.0, 1.0]), float(origin[1]), spacing)]


def _arc_angles(a: np.ndarray, b: np.ndarray, arc: Arc) -> tuple[float, float, float]:
    c = np.asarray(arc.center, float)
    radius = float(np.linalg.norm(a - c))
    start, end = np.arctan2(*(a - c)[::-1]), np.arctan2(*(b - c)[::-1])
    sweep = np.mod(end - start, 2 * np.pi) if not arc.clockwise else -np.mod(start - end, 2 * np.pi)
    return radius, float(start), float(sweep)


def _check_arc(k: int, a: np.ndarray, b: np.ndarray, arc: Arc, kind: str) -> None:
    c = np.asarray(arc.center, float)
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise InputError(f"piece {k}: the arc's center {arc.center!r} is not a point")
    ra, rb = np.linalg.norm(a - c), np.linalg.norm(b - c)
    if abs(ra - rb) > 1e-9 * max(ra, rb):
        raise InputError(f"piece {k}: the arc's center {_point(c)} is not equidistant from its ends "
                         f"{_point(a)} and {_point(b)} (distances {ra:.9g} and {rb:.9g})")
    sweep = abs(_arc_angles(a, b, arc)[2])
    if sweep > np.pi * (1 + 1e-12):
        raise InputError(f"piece {k}: the arc turns through {np.degrees(sweep):.6g} degrees about its center; "
                         "at most 180 are allowed (split it into two pieces)")


def _point(p: np.ndarray) -> str:
    return f"({p[0]:.6g}, {p[1]:.6g})"


def _check_simple(v: np.ndarray) -> None:
    """InputError naming two pieces of the outline (n, 2) that cross or touch, unless none do."""
    if shapely.LinearRing(v).is_simple:
        return
    a, b = v, np.roll(v, -1, axis=0)
    n = len(v)
    i, j = np.triu_indices(n, 1)
    far = (j - i > 1) & ~((i == 0) & (j == n - 1))              # neighbours share a vertex by design
    i, j = i[far], j[far]
    hit = shapely.intersects(shapely.linestrings(np.stack([a[i], b[i]], 1)),
                             shapely.linestrings(np.stack([a[j], b[j]], 1)))
    # adjacent pieces that fold back onto each other overlap along more than their common vertex
    adjacent = np.arange(n)
    d, d_next = b - a, np.roll(b - a, -1, axis=0)
    folded = (np.abs(d[:, 0] * d_next[:, 1] - d[:, 1] * d_next[:, 0]) <= 1e-12 * np.sum(d * d, 1)) \
        & (np.sum(d * d_next, 1) < 0)
    if np.any(folded):
        k = int(adjacent[folded][0])
        raise InputError(f"the outline intersects itself: pieces {k} and {(k + 1) % n} fold back onto each other")
    if np.any(hit):
        k = int(np.flatnonzero(hit)[0])
        raise InputError(f"the outline intersects itself: pieces {i[k]} and {j[k]} cross or touch")
    raise InputError("the outline intersects itself")


def _extension(turn: float) -> float:
    """How far (in band widths) a wall's band runs on past a corner that turns by `turn` (radians).

    At a convex corner the body near the corner lies within cot(turn) s of the wall's end line
    for points at distance s from the wall, so running on by cot(turn) delta (at most delta, for
    nearly straight corners) keeps phi = s wherever the body is within delta of the wall; at a
    straight or re-entrant corner the band ends at the corner.
    """
    if turn <= 1e-9:
        return 0.0
    c = float(np.cos(turn) / np.sin(turn))
    return 0.0 if c < 1e-12 else min(c, 1.0)


def walls_of(body: Body) -> tuple[Wall, ...]:
    """The essential arcs (ArcWall, each its own wall) and the maximal runs of consecutive collinear
    straight essential pieces of one kind (Wall)."""
    n = body.n_edges
    kinds, turns = body.kinds, body.turns
    essential = [kind in ESSENTIAL_KINDS for kind in kinds]

    def joined(k: int) -> bool:            # edge k runs straight on into edge k + 1 of its kind
        return essential[k] and kinds[(k + 1) % n] == kinds[k] and abs(turns[k]) <= 1e-12

    arcs = [k for k in range(n) if essential[k] and body.arcs and body.arcs[k] is not None]
    walls = [_arc_wall(body, k) for k in arcs]      # first: their factor leads the product (dirichlet)
    essential = [e and k not in arcs for k, e in enumerate(essential)]
    first = [k for k in range(n) if essential[k] and not joined((k - 1) % n)]
    for k in sorted(first):
        pieces = [k]
        while joined(pieces[-1]):
            pieces.append((pieces[-1] + 1) % n)
        a, b = body.starts[k], body.ends[pieces[-1]]
        length = float(np.linalg.norm(b - a))
        tangent = (b - a) / length
        walls.append(Wall(kinds[k], tuple(pieces), a.copy(), tangent, np.array([-tangent[1], tangent[0]]), length,
                          (_extension(turns[(k - 1) % n]), _extension(turns[pieces[-1]]))))
    return tuple(walls)


def _arc_wall(body: Body, k: int) -> ArcWall:
    """The wall of essential arc piece k; its neighbours must meet it at right angles (convex
    corners), so that the body within a band width of the arc lies in the arc's wedge."""
    n = body.n_edges
    for corner, turn in ((k, body.turns[(k - 1) % n]), ((k + 1) % n, body.turns[k])):
        if abs(turn - np.pi / 2) > 1e-9:
            raise InputError(
                f"piece {k}: an essential ({body.kinds[k]}) arc must meet its neighbours at right angles "
                f"(interior angle 90 degrees); at {_point(body.vertices[corner])} the interior angle is "
                f"{180 - np.degrees(turn):.6g} degrees")
    radius, start, sweep = body.arc_angles(k)
    arc = body.arcs[k]
    sign = -1.0 if arc.clockwise else 1.0
    theta0 = start if sweep > 0 else start + sweep
    return ArcWall(body.kinds[k], (k,), np.asarray(arc.center, float), radius, sign, float(np.mod(theta0, 2 * np.pi)),
                   float(abs(sweep)))


def frame_of_angle(angle_deg: float) -> np.ndarray:
    """Local frame for a body whose side edges make angle_deg with the x-axis.

    Returns R (2, 2) with columns e_xi = (sin t, -cos t) along the base and
    e_eta = (cos t, sin t) normal to the base (inward); angle 90 gives R = I.
    """
    t = np.deg2rad(angle_deg)
    sin, cos = np.sin(t), np.cos(t)
    # cos(90 deg) is 6e-17 in floating point: snap so grid-aligned bodies are exactly aligned
    sin, cos = (0.0 if abs(v) < 1e-15 else v for v in (sin, cos))
    return np.array([[sin, cos], [-cos, sin]])


def frame_3d(theta_deg: float, tilt_deg: float) -> np.ndarray:
    """Local frame of a 3D box: frame_of_angle(theta) about z, then a tilt about the body's own xi axis.

    Returns R (3, 3) = blockdiag(frame_of_angle(theta), 1) @ Rx(tilt) with columns e_xi, e_eta,
    e_zeta, Rx(t) = [[1, 0, 0], [0, cos t, -sin t], [0, sin t, cos t]]; (90, 0) gives R = I.
    """
    planar = np.eye(3)
    planar[:2, :2] = frame_of_angle(theta_deg)
    t = np.deg2rad(tilt_deg)
    sin, cos = (0.0 if abs(v) < 1e-15 else v for v in (np.sin(t), np.cos(t)))   # as frame_of_angle
    return planar @ np.array([[1.0, 0.0, 0.0], [0.0, cos, -sin], [0.0, sin, cos]])


def rectangle(width: float, height: float, kinds: tuple[str, str, str, str], angle_deg: float,
              corner: np.ndarray) -> Body:
    """A width x height rectangle with its base corner at `corner`.

    kinds are (base, right side, top, left side); the base lies along e_xi.
    """
    if not (np.isfinite(width) and np.isfinite(height) and width > 0 and height > 0):
        raise InputError(f"rectangle sides must be positive, got {width} x {height}")
    R = frame_of_angle(angle_deg)
    local = np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]])
    return Body(vertices=np.asarray(corner, float) + local @ R.T, kinds=kinds, frame=R)
