"""Contact walls inside a load step: the wall points of the contact edges carry the contact law
(ibm.contact.laws) as the projection of each method's trial traction, and keep their history from
step to step (docs/contact.md).

At a wall point the material's displacement relative to the wall since the run began is
r = r_n + N dU - g (r_n at the step start, g the wall's translation this step); n is the normal
into the material. The wall's traction on the material t = Pi(z) (the law's projection):
- penalty: z = -beta_n (r.n) n - beta_t (r_T - s), s the slip so far;
- Nitsche (Chouly, Hild and Renard, Math. Comp. 84 (2015); Renard, CMAME 256 (2013) for Coulomb):
  z = q(u) - gamma ((r.n) n + (I - n n)(r - r_n)), q(u) = sigma(u) n_out the material's own traction,
  gamma = gamma0 M / h; its weak form adds theta / gamma int (t - q(u)) . q(v), theta = 1 symmetric,
  0 incomplete, -1 skew-symmetric.
The wall's force on the grid is f = -int N^T t (+ the theta term) and its tangent the derivative:
unsymmetric where Coulomb slips (the bound mu p follows the pressure). On convergence the step keeps
r and the slip, and reports the wall's measures:

    contact_force_x, _y    the force the material puts on the wall (the body's reaction), -int t
    active_length          the length of the wall in contact (p > 0)
    slip_length            the part of it that slips
    max_penetration        the largest penetration <-r.n>: the penalty's O(p / beta), Nitsche's round-off
    active_set_changes     the points whose status (open, stick, slip) changed in the step
    pressure_peak          the largest mean pressure over one grid cell's part of the contact edges
    pressure_spread        with an obstacle plane: the pressure's root-mean-square distance from its point
    obstacle_force_x, _y   with an obstacle (a plane or a rigid body, ibm.contact.rigid): the force on it,
    obstacle_moment        and its moment about the obstacle's pivot (2D)

The wall points must stay where they were (the body as given: small kinematics); a later step
whose contact points moved is refused.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from baselines.wall_points import WallPoints, joined, points_on_edges
from ibm.contact.laws import OPEN, SLIP, Obstacle, penalty_response, return_map
from ibm.contact.rigid import moment
from ibm.exceptions import SolveError
from ibm.large.treatment import StepContext


@dataclass(frozen=True, eq=False)
class History:
    """The contact points of one step (the contact walls' and the free edges' that may touch an obstacle),
    their laws, their contact normals and what the last step left."""

    points: WallPoints           # normal: the body's outward normal
    laws: tuple                  # (law, mask (m,)) per contact edge
    normal: np.ndarray           # (m, d) the contact normal into the material (the wall's or the obstacle's)
    start: np.ndarray            # (m, d) r at the step start (at the first, the obstacle's gap along normal)
    slip: np.ndarray             # (m, d) slip at the step start
    status: np.ndarray           # (m,) OPEN, STICK or SLIP at the step start
    traction: np.ndarray         # (m, d) the traction on the material at the step start
    obstacle: object = None      # the first obstacle (Obstacle or RigidBody), None: walls only
    touching: np.ndarray | None = None    # (m,) the points that may touch it
    feature: np.ndarray | None = None     # (m,) the obstacle's feature each point faces (0 on walls)

    @classmethod
    def of(cls, context: StepContext, points: WallPoints) -> "History":
        """The contact edges' points: those of `points` (all walls) on contact walls, then the points of the
        free edges with an obstacle, with the history the last step left."""
        essential = context.body.essential_edges
        marks = {essential.index(edge) if edge in essential else -1 - edge: law for edge, law in context.contact.items()}
        points = points.subset(np.isin(points.wall, list(marks)))
        free = [edge for edge in context.contact if edge not in essential]
        if free:
            points = joined(points, points_on_edges(context.body, context.grid, free))
        m, d = points.x.shape
        normal = -points.normal.copy()
        start, g, feature = np.zeros((m, d)), points.g.copy(), np.zeros(m, int)
        t0, t1 = context.times
        for edge in free:        # the obstacle's normal and gap at the body as given, its motion this step
            obstacle, mine = context.obstacles[edge], points.wall == -1 - edge
            gap, normal[mine] = obstacle.gap(points.x[mine])
            start[mine] = gap[:, None] * normal[mine]
            g[mine] = obstacle.displacement(points.x[mine], t1) - obstacle.displacement(points.x[mine], t0)
            feature[mine] = obstacle.features(points.x[mine])
        points = replace(points, g=g)
        first = context.obstacles[free[0]] if free else None
        touching = np.isin(points.wall, [-1 - edge for edge in free if context.obstacles[edge] is first])
        slip, status, traction = np.zeros((m, d)), np.full(m, OPEN), np.zeros((m, d))
        state = context.contact_state
        if state:
            if state["x"].shape != points.x.shape or np.abs(state["x"] - points.x).max(initial=0) > 0:
                raise SolveError("the contact points moved between load steps; contact is imposed on the body as "
                                 "given (small kinematics) only")
            start, slip, status, traction = state["r"], state["slip"], state["status"], state["traction"]
        laws = tuple((law, points.wall == mark) for mark, law in marks.items())
        return cls(points, laws, normal, start, slip, status, traction, first, touching, feature)


class ContactWall:
    """What every method's contact wall does with its trial traction (subclasses: `response`)."""

    def __init__(self, history: History):
        self.history = history
        self.points = history.points
        self.obstacle = history.obstacle

    def relative(self, dU: np.ndarray) -> np.ndarray:
        """r (m, d) at the grid increment dU."""
        p = self.points
        return self.history.start + np.einsum("qia,qa->qi", p.Nv, dU[p.dofs]) - p.g

    def response(self, dU: np.ndarray):
        """(r, traction (m, d), dt/dU (m, d, k d), slip (m, d), status (m,), force (n_dofs,), stiffness csr)."""
        raise NotImplementedError

    def wall(self, dU: np.ndarray):
        """(force (n_dofs,), tangent csr) of the wall on the grid."""
        return self.response(dU)[5:]

    def accept(self, dU: np.ndarray) -> tuple[dict, dict]:
        """The history for the next step and this step's measures (module doc)."""
        p = self.points
        r, traction, _, slip, status, _, _ = self.response(dU)
        d = r.shape[1]
        gap = np.einsum("qi,qi->q", r, self.history.normal)
        force = -np.einsum("q,qi->i", p.weight, traction)
        measures = {"contact_force_x": float(force[0]), "contact_force_y": float(force[1]),
                    "active_length": float(p.weight[status != OPEN].sum()),
                    "slip_length": float(p.weight[status == SLIP].sum()),
                    "max_penetration": float(np.maximum(-gap, 0).max(initial=0.0)),
                    "active_set_changes": int(np.sum(status != self.history.status))}
        if len(force) == 3:
            measures["contact_force_z"] = float(force[2])
        if self.obstacle is not None and d == 2:     # the force and moment (about its pivot) on the first obstacle
            mine = self.history.touching
            on_it = -p.weight[mine, None] * traction[mine]
            measures.update({"obstacle_force_x": float(on_it[:, 0].sum()), "obstacle_force_y": float(on_it[:, 1].sum()),
                             "obstacle_moment": moment(p.x[mine], on_it, self.obstacle.pivot)})
        pressure = np.einsum("qi,qi->q", traction, self.history.normal)
        if len(pressure) and p.weight @ pressure > 0:
            # the largest mean pressure over one cell's part of the contact edge, and the pressure's spread
            # (its root-mean-square distance from the first obstacle's point along it: a / 2 for Hertz)
            measures["pressure_peak"] = float(np.max(np.bincount(p.cells, p.weight * pressure)
                                                     / np.maximum(np.bincount(p.cells, p.weight), 1e-300)))
            if isinstance(self.obstacle, Obstacle):
                along = p.x - self.obstacle.point
                along = along - (along @ self.obstacle.normal)[:, None] * self.obstacle.normal
                measures["pressure_spread"] = float(np.sqrt((p.weight * pressure) @ np.sum(along ** 2, axis=1)
                                                            / (p.weight @ pressure)))
        return {"x": p.x, "r": r, "slip": slip, "status": status, "traction": traction}, measures

    def _wall_terms(self, traction: np.ndarray, derivative: np.ndarray):
        """-int N^T t and its tangent -int N^T dt/dU from the traction (m, d) and dt/dU (m, d, k d)."""
        p = self.points
        force = -np.bincount(p.dofs.ravel(), np.einsum("qia,qi->qa", p.Nv, traction * p.weight[:, None]).ravel(),
                             minlength=p.n_dofs)
        return force, -p.blocks(p.Nv, derivative * p.weight[:, None, None])


class PenaltyContact(ContactWall):
    """The penalty's trial traction -beta_n (r.n) n - beta_t (r_T - s) (ibm.contact.laws.penalty_response)."""

    def __init__(self, history: History, beta_n: float, beta_t: float):
        super().__init__(history)
        self.beta_n, self.beta_t = beta_n, beta_t

    def response(self, dU):
        h, p = self.history, self.points
        r = self.relative(dU)
        m, d = r.shape
        traction, tangent = np.zeros((m, d)), np.zeros((m, d, d))
        slip, status = h.slip.copy(), np.zeros(m, int)
        for law, mine in h.laws:
            answer = penalty_response(law, r[mine], h.slip[mine], h.normal[mine], self.beta_n, self.beta_t)
            traction[mine], tangent[mine], slip[mine], status[mine] = (answer.traction, answer.tangent,
                                                                      answer.slip, answer.status)
        derivative = np.matmul(tangent, p.Nv)                                      # (m, d, k d)
        return (r, traction, derivative, slip, status, *self._wall_terms(traction, derivative))


class NitscheContact(ContactWall):
    """Nitsche's trial traction q(u) - gamma ((r.n) n + (I - n n)(r - r_n)) with the theta term (module doc).

    material(dU) -> (q (m, d), dq/dU (m, d, k d)): the material's traction sigma(u) n_out at the points."""

    def __init__(self, history: History, gamma: float, theta: float, material):
        super().__init__(history)
        self.gamma, self.theta, self.material = gamma, theta, material

    def response(self, dU):
        h, p = self.history, self.points
        r = self.relative(dU)
        m, d = r.shape
        n = h.normal
        q, dq = self.material(dU)
        gap = np.einsum("qi,qi->q", r, n)
        moved = r - h.start
        along = np.einsum("qi,qi->q", moved, n)[:, None] * n
        tangential = moved - along                                                    # (I - n n)(r - r_n)
        z = q - self.gamma * (gap[:, None] * n + moved - along)
        dz = dq - self.gamma * p.Nv                                                 # (m, d, k d)
        traction, derivative = np.zeros((m, d)), np.zeros((m, d, dz.shape[2]))
        status = np.zeros(m, int)
        for law, mine in h.laws:
            t, dt_dz, status[mine], _ = return_map(law, z[mine], n[mine])
            traction[mine], derivative[mine] = t, np.matmul(dt_dz, dz[mine])
        force, stiffness = self._wall_terms(traction, derivative)
        if self.theta:          # theta / gamma int (t - q(u)) . q(v)
            scale = self.theta / self.gamma * p.weight
            force += np.bincount(p.dofs.ravel(), np.einsum("qia,qi->qa", dq, (traction - q) * scale[:, None]).ravel(),
                                 minlength=p.n_dofs)
            stiffness = stiffness + p.blocks(dq, (derivative - dq) * scale[:, None, None])
        slip = h.slip + np.where((status == SLIP)[:, None], tangential, 0.0)
        return (r, traction, derivative, slip, status, force, stiffness)


def with_other_walls(contact: ContactWall, others):
    """dU -> (force, tangent) of the contact wall and of the other walls' `others` (None: there are none)."""
    def wall(dU):
        force, stiffness = contact.wall(dU)
        if others is None:
            return force, stiffness
        other_force, other_stiffness = others(dU)
        return force + other_force, stiffness + other_stiffness
    return wall
