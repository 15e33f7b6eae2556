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

EDGE_KINDS = ("roller", "fixed", "traction", "free")
ESSENTIAL_KINDS = ("roller", "fixed")


class InputError(ValueError):
    """Bad input: the message names the bad value and what is allowed."""


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


@dataclass(frozen=True, eq=False)
class Body:
    """A closed outline of straight pieces with one boundary kind per piece.

    vertices: (n_edges, 2), counter-clockwise; edge (piece) k joins vertex k and vertex k+1.
    kinds: one of EDGE_KINDS per edge.
    frame: (2, 2) columns e_xi, e_eta of the body's local frame (for reporting).
    tracked: the outline a large deformation carries along (ibm.walls.Outline) is not checked
    for self-intersection (a body folding onto itself is the load-step loop's to report).
    """

    vertices: np.ndarray
    kinds: tuple[str, ...]
    frame: np.ndarray = None  # type: ignore[assignment]
    tracked: bool = False

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
        if not self.tracked:
            _check_simple(v)
        if self.area <= 0:
            raise InputError(f"the outline runs clockwise (signed area {self.area:.6g}); "
                             "pieces must run counter-clockwise, with the body on their left")

    @property
    def convex(self) -> bool:
        """No re-entrant corner (a straight angle between collinear pieces counts as convex)."""
        return bool(np.all(self.turns >= -1e-12))

    @property
    def turns(self) -> np.ndarray:
        """(n_edges,) signed turning angle at the end of each edge (> 0 at a convex corner)."""
        t, t_next = self.tangents, np.roll(self.tangents, -1, axis=0)
        cross = t[:, 0] * t_next[:, 1] - t[:, 1] * t_next[:, 0]
        return np.arctan2(cross, np.sum(t * t_next, axis=1))

    @cached_property
    def walls(self) -> tuple[Wall, ...]:
        """The walls of the essential pieces (see the module doc), in the order of their first piece."""
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
        x, y = self.vertices.T
        return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))

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
        return self.vertices.min(axis=0), self.vertices.max(axis=0)


def _point(p: np.ndarray) -> str:
    return f"({p[0]:.6g}, {p[1]:.6g})"


def _check_simple(v: np.ndarray) -> None:
    """InputError naming two pieces of the outline (n, 2) that cross or touch, unless none do."""
    import shapely
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
    """Maximal runs of consecutive collinear essential pieces of one kind, as walls."""
    n = body.n_edges
    kinds, turns = body.kinds, body.turns
    essential = [kind in ESSENTIAL_KINDS for kind in kinds]

    def joined(k: int) -> bool:            # edge k runs straight on into edge k + 1 of its kind
        return essential[k] and kinds[(k + 1) % n] == kinds[k] and abs(turns[k]) <= 1e-12

    if all(essential) and all(joined(k) for k in range(n)):
        raise InputError("every piece lies on one line")  # cannot happen for a body with area
    first = [k for k in range(n) if essential[k] and not joined((k - 1) % n)]
    walls = []
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
