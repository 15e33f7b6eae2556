"""Bodies: closed counter-clockwise outlines of straight pieces, one boundary kind per piece.

Piece (edge) k runs from vertex k to vertex k+1; non-convex outlines are allowed, and a
straight side may be split into collinear pieces of different kinds. Its inward unit
normal n_k and the signed distance s_k(x) = (x - x_k) . n_k to its line are the geometry
every method uses. A piece may be an arc (ibm.geometry.arcs).

The Dirichlet functions of the implicit boundary method belong to walls (ibm.geometry.walls):
maximal runs of collinear essential pieces of one kind, and essential arcs, found by walls_of.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely

from ibm.exceptions import InputError
from ibm.geometry.arcs import Arc, Segments, arc_angles, arc_cuts
from ibm.geometry.frames import frame_of_angle
from ibm.geometry.walls import ArcWall, Wall

EDGE_KINDS = ("roller", "fixed", "traction", "free")
ESSENTIAL_KINDS = ("roller", "fixed")


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
        return arc_angles(self.vertices[k], self.vertices[(k + 1) % self.n_edges], self.arcs[k])

    def ring(self, max_angle: float = np.radians(10.0), lines: list | None = None) -> np.ndarray:
        """(m, 2) the chord polygon (see chords)."""
        return self.chords(max_angle, lines)[0]

    def segments(self, max_angle: float = np.radians(10.0), lines: list | None = None) -> Segments:
        """The circular segments beyond the chords (see chords)."""
        return self.chords(max_angle, lines)[1]

    def chords(self, max_angle: float = np.radians(10.0), lines: list | None = None) -> tuple[np.ndarray, Segments]:
        """The chord polygon (m, 2): the vertices, and on each arc the points where it crosses `lines`
        (ibm.geometry.arcs.Lines: families of parallel lines), subdivided to at most max_angle; and the
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


def _check_arc(k: int, a: np.ndarray, b: np.ndarray, arc: Arc, kind: str) -> None:
    c = np.asarray(arc.center, float)
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise InputError(f"piece {k}: the arc's center {arc.center!r} is not a point")
    ra, rb = np.linalg.norm(a - c), np.linalg.norm(b - c)
    if abs(ra - rb) > 1e-9 * max(ra, rb):
        raise InputError(f"piece {k}: the arc's center {_point(c)} is not equidistant from its ends "
                         f"{_point(a)} and {_point(b)} (distances {ra:.9g} and {rb:.9g})")
    sweep = abs(arc_angles(a, b, arc)[2])
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
