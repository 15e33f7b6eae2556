"""Polygonal bodies with tagged edges, placed in the grid's plane.

Edge k runs from vertex k to vertex k+1 (vertices counter-clockwise). Its inward unit
normal n_k and signed distance phi_k(x) = (x - x_k) . n_k (> 0 inside) define the
Dirichlet functions of essential edges.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EDGE_KINDS = ("roller", "fixed", "traction", "free")
ESSENTIAL_KINDS = ("roller", "fixed")


class InputError(ValueError):
    """Bad input: the message names the bad value and what is allowed."""


@dataclass(frozen=True, eq=False)
class Body:
    """A convex polygon with one boundary kind per edge.

    vertices: (n_edges, 2), counter-clockwise; edge k joins vertex k and vertex k+1.
    kinds: one of EDGE_KINDS per edge.
    frame: (2, 2) columns e_xi, e_eta of the body's local frame (for reporting).
    convex: required of a body a user gives; the outline a large deformation carries along
    (ibm.walls.Outline) may bend its free edges inwards, so it is built with convex=False
    (its walls stay straight lines, which is all the Dirichlet functions use).
    """

    vertices: np.ndarray
    kinds: tuple[str, ...]
    frame: np.ndarray = None  # type: ignore[assignment]
    convex: bool = True

    def __post_init__(self):
        v = np.asarray(self.vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
            raise InputError(f"body vertices must be an (n >= 3, 2) array, got shape {v.shape}")
        if not np.all(np.isfinite(v)):
            raise InputError("body vertices must be finite numbers")
        if len(self.kinds) != len(v):
            raise InputError(f"body has {len(v)} edges but {len(self.kinds)} edge kinds")
        for kind in self.kinds:
            if kind not in EDGE_KINDS:
                raise InputError(f"edge kind {kind!r} is not one of {', '.join(EDGE_KINDS)}")
        # Coordinates below the rounding unit of the body's extent carry no information, and
        # subnormal ones (~1e-308) make the polygon clipping lose area: snap them to zero.
        v = np.where(np.abs(v) < 1e-15 * np.abs(v).max(), 0.0, v)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "kinds", tuple(self.kinds))
        if self.frame is None:
            object.__setattr__(self, "frame", np.eye(2))
        if self.area <= 0:
            raise InputError("body vertices must be counter-clockwise with positive area")
        t, t_next = self.tangents, np.roll(self.tangents, -1, axis=0)
        cross = t[:, 0] * t_next[:, 1] - t[:, 1] * t_next[:, 0]
        if self.convex and np.any(cross < -1e-12 * self.lengths.max() ** 2):
            raise InputError("body must be convex (a non-convex polygon was given)")

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
