"""Contact laws of a rigid wall: unilateral contact with Coulomb, Tresca or no friction
(docs/contact.md), their return map on a trial traction with its consistent tangent, and the
penalty's trial.

At a point of the wall with unit normal n pointing into the material, the material's displacement
relative to the wall r (total, since the contact began) has the gap g = r.n (g < 0: penetration)
and the tangential part r_T = (I - n n) r. The wall's traction on the material t = p n + t_T:

    Signorini:  g >= 0,  p >= 0,  p g = 0
    friction:   |t_T| <= bound,  bound = mu p (Coulomb), tau_max where p > 0 (Tresca), 0 (frictionless);
                |t_T| < bound: no slip;  |t_T| = bound: slip along -t_T (friction resists the motion)

Every method here writes them as one projection of a trial traction z (Alart and Curnier, CMAME
92 (1991)): p = <z.n>_+, t_T = the projection of z_T = (I - n n) z onto the disc of radius
bound(p). The penalty (Wriggers, Computational Contact Mechanics, 2006, ch. 5 and 10) takes
z = -beta_n g n - beta_t (r_T - s) from the slip s (m, d) so far, so p = beta_n <-g>; Nitsche
(Chouly, Hild and Renard, Math. Comp. 84 (2015); Renard, CMAME 256 (2013)) takes the material's own
traction sigma(u) n_out minus gamma times the gap and the step's tangential motion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ibm.exceptions import InputError

FRICTION = ("frictionless", "coulomb", "tresca")
OPEN, STICK, SLIP = 0, 1, 2            # the status of a contact point
AT_BOUND = 1e-6                        # |trial| within this fraction below the bound takes the slip tangent


@dataclass(frozen=True)
class ContactLaw:
    """Unilateral contact with a friction law: `friction` one of FRICTION; `coefficient` mu (coulomb,
    dimensionless) or tau_max (tresca, a stress; an undrained interface's adhesion)."""

    friction: str = "frictionless"
    coefficient: float = 0.0

    def __post_init__(self):
        if self.friction not in FRICTION:
            raise InputError(f"friction law {self.friction!r} is not allowed; allowed: {', '.join(FRICTION)}")
        value = self.coefficient
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            what = {"coulomb": "friction", "tresca": "adhesion"}.get(self.friction, "coefficient")
            raise InputError(f"{what} {value!r} is not allowed; it must be a finite number >= 0")
        if self.friction == "frictionless" and value != 0:
            raise InputError(f"a frictionless wall takes no coefficient (got {value:g})")

    def bound(self, pressure: np.ndarray) -> np.ndarray:
        """The largest tangential traction (m,) at contact pressures (m,)."""
        if self.friction == "coulomb":
            return self.coefficient * pressure
        if self.friction == "tresca":
            return np.where(pressure > 0, self.coefficient, 0.0)
        return np.zeros_like(pressure)


@dataclass(frozen=True, eq=False)
class ContactResponse:
    """The law's answer at m points: traction on the material (m, d), its derivative with respect to the
    relative displacement dt/dr (m, d, d), the slip after the step (m, d) and each point's status (m,)
    (OPEN, STICK, SLIP)."""

    traction: np.ndarray
    tangent: np.ndarray
    slip: np.ndarray
    status: np.ndarray


def length(v: np.ndarray) -> np.ndarray:
    """|v| (m,) of vectors (m, d) without the underflow of squaring tiny components."""
    return np.hypot.reduce(v, axis=1) if v.shape[1] else np.zeros(len(v))


def return_map(law: ContactLaw, z: np.ndarray, normal: np.ndarray):
    """The law's traction t (m, d) from trial tractions z (m, d) at points with unit normals into the
    material (m, d), its derivative dt/dz (m, d, d), each point's status (m,) and which points the
    projection moved onto the bound (m,) (module doc).

    On the kinks the derivative takes the closed and the slipping branch (each a valid generalised
    derivative there): a point that touches the wall with no pressure (z.n = 0, every point of a wall
    at the start) is stiff against it, and a point that slipped last step, which starts the next
    exactly on the bound, is free to slip on (the stick branch would hold it), while a point with no
    tangential trial sticks (contact just made)."""
    m, d = z.shape
    n = normal
    z_n = np.einsum("qi,qi->q", z, n)                                             # (m,)
    nn = n[:, :, None] * n[:, None, :]
    tangential = np.eye(d)[None] - nn                                             # (m, d, d)
    z_t = z - z_n[:, None] * n
    closed, touching = z_n > 0, z_n >= 0
    pressure = np.where(closed, z_n, 0.0)
    traction = pressure[:, None] * n
    derivative = np.where(touching[:, None, None], nn, 0.0)
    size = length(z_t)
    bound = law.bound(pressure)                                                   # (m,)
    if law.friction == "frictionless":
        return traction, derivative, np.where(closed, SLIP, OPEN), closed
    # the traction: no tangential traction where the bound is zero, else stick inside the bound, slip on it
    free = closed & (bound == 0)
    slips = closed & ~free & (size > bound)
    sticks = closed & ~free & ~slips
    traction[sticks] += z_t[sticks]
    traction[slips] += (bound[slips] / size[slips])[:, None] * z_t[slips]
    status = np.select([slips | free, sticks], [SLIP, STICK], OPEN)
    # its derivative, on the touching side of the gap's kink and the slipping side of the bound's
    reach = np.where(touching & (law.friction == "tresca"), law.coefficient, bound)
    holding = touching & ((size <= (1 - AT_BOUND) * reach) | (size == 0))
    sliding = touching & ~holding & (reach > 0)
    derivative[holding] += tangential[holding]
    direction = z_t[sliding] / size[sliding, None]                                # |z_t| > 0: reach > 0
    # d(bound dir)/dz = bound (P_T - dir dir) / |z_t| + dir (x) d bound / dz
    projector = tangential[sliding] - direction[:, :, None] * direction[:, None, :]
    derivative[sliding] += (reach[sliding] / size[sliding])[:, None, None] * projector
    if law.friction == "coulomb":               # d(mu p)/dz = mu n where closed
        derivative[sliding & closed] += law.coefficient * (
            direction[closed[sliding]][:, :, None] * n[sliding & closed][:, None, :])
    return traction, derivative, status, slips | free


def penalty_response(law: ContactLaw, r: np.ndarray, slip: np.ndarray, normal: np.ndarray,
                     beta_n: float, beta_t: float) -> ContactResponse:
    """The penalty's law at m points: relative displacement r (m, d), slip so far s (m, d), unit normals
    into the material (m, d), normal and tangential penalties; z = -beta_n g n - beta_t (r_T - s).

    A point that opens loses its slip memory (s = r_T: no tangential traction stored), so that
    contact made again starts from no traction; a point that slips takes s with t_T = -beta_t (r_T - s)."""
    n = normal
    gap = np.einsum("qi,qi->q", r, n)
    nn = n[:, :, None] * n[:, None, :]
    tangential = np.eye(r.shape[1])[None] - nn
    r_t = r - gap[:, None] * n
    z = -beta_n * gap[:, None] * n - beta_t * (r_t - slip)
    traction, derivative, status, moved = return_map(law, z, n)
    t_t = traction - np.einsum("qi,qi->q", traction, n)[:, None] * n
    new_slip = np.where((status == OPEN)[:, None], r_t, slip)
    new_slip[moved] = r_t[moved] + t_t[moved] / beta_t
    tangent = np.matmul(derivative, -beta_n * nn - beta_t * tangential)          # dz/dr
    return ContactResponse(traction, tangent, new_slip, status)


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A rigid plane a free edge of the body may touch: a point on it (d,) and its unit normal (d,)
    pointing to the body's side. The gap of a point x of the edge is (x - point) . normal + r . normal."""

    point: np.ndarray
    normal: np.ndarray

    def __post_init__(self):
        point, normal = np.asarray(self.point, float), np.asarray(self.normal, float)
        if point.shape != normal.shape or point.ndim != 1 or not np.all(np.isfinite(point)) \
                or not abs(np.linalg.norm(normal) - 1) < 1e-12:
            raise InputError(f"an obstacle needs a point and a unit normal of one dimension, got {point} and {normal}")
        object.__setattr__(self, "point", point)
        object.__setattr__(self, "normal", normal)

    @property
    def pivot(self) -> np.ndarray:
        """The point its moment is taken about."""
        return self.point

    def gap(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(signed distance (m,) of the points x (m, d) from the plane, the normal (m, d)): ibm.contact.rigid's
        interface."""
        return (x - self.point) @ self.normal, np.broadcast_to(self.normal, x.shape).copy()

    def features(self, x: np.ndarray) -> np.ndarray:
        """One feature, the plane: zeros (m,)."""
        return np.zeros(len(x), int)

    def displacement(self, x: np.ndarray, t: float) -> np.ndarray:
        """The plane does not move: zeros (m, d)."""
        return np.zeros_like(x)

    def key(self) -> tuple:
        return (self.point.tolist(), self.normal.tolist())
