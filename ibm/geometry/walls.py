"""Walls: the supports of the Dirichlet functions of the implicit boundary method, and their distances.

A straight wall (Wall) is a maximal run of collinear essential pieces of one kind
(ibm.geometry.outline.walls_of). Its distance is the largest of |s|, the distance past its start and
the distance past its end, measured in the wall's own frame (a box distance, piecewise linear, so
that bands stay polygons and their quadrature exact): where a wall meets another at a convex corner
its band runs on along its line far enough to cover the corner region inside the body, as the
seed's line distance does; where it ends inside a straight side or at a re-entrant corner the band
ends there. An essential arc is a wall of its own (ArcWall), its distance radial.
Points x are (n, 2) arrays; distances (n,), gradients (n, 2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
