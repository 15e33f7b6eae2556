"""Contact walls inside a load step by the penalty: the wall points of the contact edges carry the
penalty-regularised contact law (ibm.contact.laws) and keep its history from step to step.

At a wall point the material's displacement relative to the wall since the run began is
r = r_n + N dU - g (r_n at the step start, g the wall's translation this step). The wall's force
on the grid is f = -int N^T t(r) and its tangent -int N^T (dt/dr) N: unsymmetric where Coulomb
slips (the bound mu p follows the pressure). On convergence the step keeps r and the slip, and
reports the wall's measures (docs/contact.md):

    contact_force_x, _y    the force the material puts on the wall (the body's reaction), -int t
    active_length          the length of the wall in contact (p > 0)
    slip_length            the part of it that slips
    max_penetration        the largest penetration <-g>, by the penalty O(p / beta)
    active_set_changes     the points whose status (open, stick, slip) changed in the step

The wall points must stay where they were (the body as given: small kinematics); a later step
whose contact points moved is refused.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baselines.wall_points import WallPoints
from ibm.contact.laws import OPEN, SLIP, penalty_response
from ibm.exceptions import SolveError
from ibm.large.treatment import StepContext


@dataclass(frozen=True, eq=False)
class ContactWall:
    """The contact points of one step (all contact edges), their laws and their history."""

    points: WallPoints
    laws: tuple                  # (law, mask (m,)) per contact edge
    start: np.ndarray            # (m, d) r at the step start
    slip: np.ndarray             # (m, d) slip at the step start
    status: np.ndarray           # (m,) OPEN, STICK or SLIP at the step start
    beta_n: float
    beta_t: float

    @classmethod
    def of(cls, context: StepContext, points: WallPoints, beta_n: float, beta_t: float) -> "ContactWall":
        """The contact edges' points of `points` (all walls) with the history the last step left."""
        essential = context.body.essential_edges
        walls = {essential.index(edge): law for edge, law in context.contact.items()}
        keep = np.isin(points.wall, list(walls))
        points = points.subset(keep)
        m, d = points.x.shape
        state = context.contact_state
        if state:
            if state["x"].shape != points.x.shape or np.abs(state["x"] - points.x).max(initial=0) > 0:
                raise SolveError("the contact points moved between load steps; contact is imposed on the body as "
                                 "given (small kinematics) only")
            start, slip, status = state["r"], state["slip"], state["status"]
        else:
            start, slip, status = np.zeros((m, d)), np.zeros((m, d)), np.full(m, OPEN)
        laws = tuple((law, points.wall == wall) for wall, law in walls.items())
        return cls(points, laws, start, slip, status, beta_n, beta_t)

    def relative(self, dU: np.ndarray) -> np.ndarray:
        """r (m, d) at the grid increment dU."""
        p = self.points
        return self.start + np.einsum("qia,qa->qi", p.Nv, dU[p.dofs]) - p.g

    def response(self, dU: np.ndarray):
        """(traction (m, d), tangent (m, d, d), slip (m, d), status (m,)) of every point at dU."""
        r = self.relative(dU)
        m, d = r.shape
        inward = -self.points.normal
        traction, tangent = np.zeros((m, d)), np.zeros((m, d, d))
        slip, status = self.slip.copy(), np.zeros(m, int)
        for law, mine in self.laws:
            answer = penalty_response(law, r[mine], self.slip[mine], inward[mine], self.beta_n, self.beta_t)
            traction[mine], tangent[mine], slip[mine], status[mine] = (answer.traction, answer.tangent,
                                                                      answer.slip, answer.status)
        return r, traction, tangent, slip, status

    def wall(self, dU: np.ndarray):
        """(force (n_dofs,), tangent csr): the contact law's -int N^T t and its derivative."""
        p = self.points
        _, traction, tangent, _, _ = self.response(dU)
        force = -np.bincount(p.dofs.ravel(), np.einsum("qia,qi->qa", p.Nv, traction * p.weight[:, None]).ravel(),
                             minlength=p.n_dofs)
        stiffness = -p.blocks(p.Nv, np.matmul(tangent, p.Nv) * p.weight[:, None, None])
        return force, stiffness

    def accept(self, dU: np.ndarray) -> tuple[dict, dict]:
        """The history for the next step and this step's measures (module doc)."""
        p = self.points
        r, traction, _, slip, status = self.response(dU)
        gap = np.einsum("qi,qi->q", r, -p.normal)
        force = -np.einsum("q,qi->i", p.weight, traction)
        measures = {"contact_force_x": float(force[0]), "contact_force_y": float(force[1]),
                    "active_length": float(p.weight[status != OPEN].sum()),
                    "slip_length": float(p.weight[status == SLIP].sum()),
                    "max_penetration": float(np.maximum(-gap, 0).max(initial=0.0)),
                    "active_set_changes": int(np.sum(status != self.status))}
        if len(force) == 3:
            measures["contact_force_z"] = float(force[2])
        return {"x": p.x, "r": r, "slip": slip, "status": status}, measures
