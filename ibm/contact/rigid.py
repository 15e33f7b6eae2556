"""Rigid bodies a free edge of the material may touch: polygons and circles moving by a prescribed
rigid motion (docs/contact.md).

At small kinematics the contact is written on the body as given: each contact point x of the
material's edge keeps the normal n of the rigid body's outline at its closest point (outward from
the rigid body, into the material) and its initial gap g0 = signed distance (positive outside).
The rigid body moves by a translation c(t) and a small rotation theta(t) about its pivot p
(counter-clockwise), linearised like every displacement at small kinematics:

    u_rigid(x, t) = c(t) + theta(t) e_z x (x - p),

so a contact point's gap is g0 + (u(x) - u_rigid(x, t)) . n. The force the material puts on the
body and its moment about the pivot are reported per step (baselines.contact_walls).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from ibm.exceptions import InputError
from ibm.large.load_paths import LoadPath


@dataclass(frozen=True, eq=False)
class RigidBody:
    """A rigid polygon (vertices (k, 2), counter-clockwise) or circle (center (2,), radius), moved by
    `motion`, a LoadPath of (c_x, c_y, theta) (theta in radians, counter-clockwise about `pivot`); no
    motion: it stays. The pivot defaults to the polygon's centroid or the circle's center."""

    vertices: np.ndarray | None = None
    center: np.ndarray | None = None
    radius: float = 0.0
    motion: LoadPath | None = None
    pivot: np.ndarray | None = None

    def __post_init__(self):
        if (self.vertices is None) == (self.center is None):
            raise InputError("a rigid body is a polygon (vertices) or a circle (center and radius), one of the two")
        if self.vertices is not None:
            vertices = np.asarray(self.vertices, float)
            if vertices.ndim != 2 or vertices.shape[1] != 2 or len(vertices) < 3 or not np.all(np.isfinite(vertices)):
                raise InputError(f"a rigid polygon needs three or more finite 2D vertices, got shape {vertices.shape}")
            polygon = shapely.Polygon(vertices)
            if not polygon.is_valid or polygon.area <= 0 or not polygon.exterior.is_ccw:
                raise InputError("a rigid polygon's vertices must run counter-clockwise around a simple polygon")
            object.__setattr__(self, "vertices", vertices)
            centre = np.array(polygon.centroid.coords[0])
        else:
            centre = np.asarray(self.center, float)
            if centre.shape != (2,) or not np.all(np.isfinite(centre)) or not (np.isfinite(self.radius)
                                                                               and self.radius > 0):
                raise InputError(f"a rigid circle needs a 2D center and a radius > 0, got {self.center} and "
                                 f"{self.radius}")
            object.__setattr__(self, "center", centre)
        if self.motion is not None and np.shape(self.motion.values)[1:] != (3,):
            raise InputError(f"a rigid body's motion gives (c_x, c_y, theta) at each time; got values of shape "
                             f"{np.shape(self.motion.values)[1:]}")
        pivot = centre if self.pivot is None else np.asarray(self.pivot, float)
        if pivot.shape != (2,) or not np.all(np.isfinite(pivot)):
            raise InputError(f"a rigid body's pivot must be a finite 2D point, got {self.pivot}")
        object.__setattr__(self, "pivot", pivot)

    def gap(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(signed distance (m,) of the points x (m, 2) from the outline, positive outside; the outline's
        outward unit normal (m, 2) at each point's closest point)."""
        if self.center is not None:
            offset = x - self.center
            distance = np.linalg.norm(offset, axis=1)
            if np.any(distance == 0):
                raise InputError("a contact point lies at a rigid circle's center (its normal is undefined)")
            return distance - self.radius, offset / distance[:, None]
        side, along, nearest, point, d = self._closest(x)
        outward = np.stack([side[:, 1], -side[:, 0]], axis=1) / np.linalg.norm(side, axis=1)[:, None]
        inside = shapely.contains_xy(shapely.Polygon(self.vertices), x[:, 0], x[:, 1])
        sign = np.where(inside, -1.0, 1.0)
        # on a side's inside: its normal; at a corner: the direction from the corner to the point
        interior = (along > 0) & (along < 1)
        safe = np.where(d > 0, d, 1.0)
        normal = np.where((interior | (d == 0))[:, None], outward[nearest], sign[:, None] * (x - point) / safe[:, None])
        return sign * d, normal

    def features(self, x: np.ndarray) -> np.ndarray:
        """The feature of the outline closest to each point x (m, 2) (m,): a polygon's side k (0 <= k < n) or
        its corner k (n + k); a circle's 0. A contact piece does not reach across two features."""
        if self.center is not None:
            return np.zeros(len(x), int)
        n = len(self.vertices)
        _, along, nearest, _, _ = self._closest(x)
        return np.where(along <= 0, n + nearest, np.where(along >= 1, n + (nearest + 1) % n, nearest))

    def _closest(self, x: np.ndarray):
        """A polygon's sides (k, 2), and for each point x (m, 2): where along its closest side it projects
        (m,) (0 and 1 the side's ends), that side (m,), the closest point (m, 2) and the distance (m,)."""
        side = np.roll(self.vertices, -1, axis=0) - self.vertices
        along = np.clip(np.einsum("mkd,kd->mk", x[:, None] - self.vertices[None], side) / np.sum(side ** 2, axis=1),
                        0, 1)
        closest = self.vertices[None] + along[:, :, None] * side[None]
        distance = np.linalg.norm(x[:, None] - closest, axis=2)
        nearest = np.argmin(distance, axis=1)
        rows = np.arange(len(x))
        return side, along[rows, nearest], nearest, closest[rows, nearest], distance[rows, nearest]

    def displacement(self, x: np.ndarray, t: float) -> np.ndarray:
        """u_rigid (m, 2) at the points x (m, 2) at load fraction t."""
        if self.motion is None:
            return np.zeros_like(x)
        c_x, c_y, theta = self.motion.at(t)
        arm = x - self.pivot
        return np.array([c_x, c_y]) + theta * np.stack([-arm[:, 1], arm[:, 0]], axis=1)

    def key(self) -> tuple:
        shape = self.vertices.tolist() if self.vertices is not None else (self.center.tolist(), float(self.radius))
        return ("rigid", shape, None if self.motion is None else self.motion.key(), self.pivot.tolist())


def moment(x: np.ndarray, force: np.ndarray, pivot: np.ndarray) -> float:
    """The moment about `pivot` (counter-clockwise positive) of point forces force (m, 2) at x (m, 2)."""
    arm = x - pivot
    return float(np.sum(arm[:, 0] * force[:, 1] - arm[:, 1] * force[:, 0]))
