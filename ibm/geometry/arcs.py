"""The arcs' geometry: circular pieces, the circular segments between arcs and their chords, and
the lines where arcs are cut into chords.

An arc piece runs from point a to point b about a centre c; arc_angles gives its radius, start angle
and signed sweep (> 0 counter-clockwise). Points are (2,) arrays, sets of n points (n, 2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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


def arc_angles(a: np.ndarray, b: np.ndarray, arc: Arc) -> tuple[float, float, float]:
    """Radius, start angle and signed sweep (> 0 counter-clockwise) of the arc from a (2,) to b (2,)."""
    c = np.asarray(arc.center, float)
    radius = float(np.linalg.norm(a - c))
    start, end = np.arctan2(*(a - c)[::-1]), np.arctan2(*(b - c)[::-1])
    sweep = np.mod(end - start, 2 * np.pi) if not arc.clockwise else -np.mod(start - end, 2 * np.pi)
    return radius, float(start), float(sweep)
