"""Contact walls by Lagrange multipliers with an active set (docs/contact.md): one constant pressure and
one constant tangential traction per piece of a contact edge inside one grid cell (pieces shorter than
h/100 merged), as the `lagrange` method's walls.

Each piece is open, sticking or slipping; its rows, with n_out the body's outward normal and t the
wall's tangent, r = r_n + N dU - g the displacement relative to the wall (baselines.contact_walls):

    closed (stick or slip):  int_piece n_out . r = 0       multiplier p >= 0, the pressure
    stick:                   int_piece t . (N dU - g) = 0   multiplier q, the traction on the material -q t
    slip:                    the traction b d on the material, a load: b = mu p (Coulomb, p of the
                             last solve) or tau_max (Tresca), d against the piece's slip

After each solve the set is corrected (Hueber and Wohlmuth, CMAME 194 (2005), as a primal-dual
active set): a closed piece with p < 0 opens, an open piece that penetrates closes and sticks, a
sticking piece whose |q| exceeds its bound slips along -q t, a slipping piece that moves with its
friction sticks, and a slipping piece's bound follows its new pressure; the step is solved again
until nothing changes (ibm.large.loadsteps, StepTerms.refine). The laws then hold on every piece
exactly: the frictional block comes out to round-off, with no penetration on average over a piece.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from baselines.boundary import merge_short
from baselines.contact_walls import ContactWall, History
from ibm.contact.laws import OPEN, SLIP, STICK
from ibm.large.treatment import StepContext, StepTerms

TOLERANCE = 1e-10       # relative: of the pressures (bound changes) and the displacements (penetration, slip)


class MultiplierContact:
    """The contact pieces of one step, their active set and the terms of each round."""

    def __init__(self, context: StepContext, history: History, pieces: np.ndarray, others):
        self.history, self.points = history, history.points
        self.pieces = pieces                                           # (m,) the piece of each point
        n = len(np.unique(pieces)) if len(pieces) else 0
        weight = self.points.weight
        self.length = np.bincount(pieces, weight, minlength=n)         # (n,)
        self.n_in = history.normal                                     # (m, d)
        d = self.n_in.shape[1]
        self.tangent = np.stack([-self.n_in[:, 1], self.n_in[:, 0]], axis=1) if d == 2 else None
        self.others = others                                           # (C, g, wall) of the other walls
        first = np.unique(pieces, return_index=True)[1]                 # (n,) each piece's first point
        self.friction, self.coefficient = np.full(n, "frictionless"), np.zeros(n)   # each piece's law
        for law, mine in history.laws:                                 # one per contact edge
            self.friction[mine[first]], self.coefficient[mine[first]] = law.friction, law.coefficient
        # the set at the step start: each piece as its first point ended the last step; a piece that
        # starts with a gap (an obstacle) opens, one on its wall sticks
        status = history.status[first].copy()
        gap = self._mean(np.einsum("qi,qi->q", history.start, self.n_in))
        status[(status == OPEN) & (gap <= 0)] = STICK
        self.status = status
        # slip: the sign of the friction traction along t, at first as the last step left it
        self.direction = np.sign(self._mean(np.einsum("qi,qi->q", history.traction, self.tangent)))
        self.bound = np.where(self.friction == "tresca", self.coefficient, 0.0)
        self.scale = max(np.abs(self.points.g).max(initial=0.0), np.abs(history.start).max(initial=0.0), 1e-300)

    def _bounds(self, pressure: np.ndarray) -> np.ndarray:
        """Each piece's friction bound (n,) at its pressure (n,) (ibm.contact.laws.ContactLaw.bound)."""
        positive = np.maximum(pressure, 0.0)
        return np.select([self.friction == "coulomb", self.friction == "tresca"],
                         [self.coefficient * positive, np.where(positive > 0, self.coefficient, 0.0)], 0.0)

    def _mean(self, values: np.ndarray) -> np.ndarray:
        """Per-piece means (n,) of point values (m,)."""
        return np.bincount(self.pieces, self.points.weight * values, minlength=len(self.length)) / self.length

    def _rows(self, direction: np.ndarray, keep: np.ndarray):
        """Rows int_piece direction . N (for the pieces `keep`) (k, n_dofs), one per kept piece, in order."""
        p = self.points
        index = np.full(len(self.length), -1)
        index[keep] = np.arange(int(keep.sum()))
        mine = index[self.pieces] >= 0
        values = np.einsum("qi,qia,q->qa", direction[mine], p.Nv[mine], p.weight[mine])
        rows = np.broadcast_to(index[self.pieces][mine][:, None], values.shape)
        return sp.csr_matrix((values.ravel(), (rows.ravel(), p.dofs[mine].ravel())), shape=(int(keep.sum()), p.n_dofs))

    def terms(self):
        """(C, g, wall) of the current set (the other walls' rows first)."""
        p, h = self.points, self.history
        closed = self.status != OPEN
        stick = self.status == STICK
        n_out = -self.n_in
        C_n = self._rows(n_out, closed)
        g_n = self._mean(np.einsum("qi,qi->q", n_out, p.g - h.start))[closed] * self.length[closed]
        C_t = self._rows(self.tangent, stick)
        g_t = self._mean(np.einsum("qi,qi->q", self.tangent, p.g))[stick] * self.length[stick]
        slipping = self.status == SLIP
        coulomb = (self.friction == "coulomb") & slipping
        fixed = slipping & ~coulomb
        load = np.zeros(p.n_dofs)
        if np.any(fixed):             # Tresca's friction traction b d t on the material: f_int gets -int N^T (b d t)
            traction = ((self.bound * self.direction)[self.pieces] * fixed[self.pieces])[:, None] * self.tangent
            load = -np.bincount(p.dofs.ravel(), np.einsum("qia,qi->qa", p.Nv, traction * p.weight[:, None]).ravel(),
                                minlength=p.n_dofs)
        C_other, g_other, wall_other = self.others
        C = sp.vstack([C_other, C_n, C_t], format="csr")
        g = np.concatenate([g_other, g_n, g_t])
        self.split = (C_other.shape[0], C_n.shape[0])
        B = None
        if np.any(coulomb):           # Coulomb's mu p d t follows the piece's pressure p, its multiplier
            mu = self.coefficient
            column = np.full(len(self.length), -1)
            column[closed] = C_other.shape[0] + np.arange(int(closed.sum()))
            B = -self._rows(self.tangent * (mu * self.direction)[self.pieces][:, None], coulomb).T.tocsc()
            columns = sp.csr_matrix((np.ones(int(coulomb.sum())), (np.arange(int(coulomb.sum())), column[coulomb])),
                                    shape=(int(coulomb.sum()), C.shape[0]))
            B = sp.csr_matrix(B @ columns)

        def wall(dU):
            if wall_other is None:
                return load, sp.csr_matrix((p.n_dofs, p.n_dofs))
            force, stiffness = wall_other(dU)
            return force + load, stiffness
        return C, g, wall, B

    def refine(self, dU: np.ndarray, multipliers: np.ndarray) -> bool:
        """Correct the set from a solve (module doc): the friction first, and the contact only where the
        friction holds (a sticking solve that overshoots its bound also tips the body, and the pressures it
        gives are no guide); True when the set changed."""
        first, count = self.split
        closed, stick = self.status != OPEN, self.status == STICK
        pressure, friction = np.zeros(len(self.length)), np.zeros(len(self.length))
        pressure[closed] = multipliers[first:first + count]          # rows int n_out . N: the pressure itself
        friction[stick] = -multipliers[first + count:]               # the traction along t
        self.pressures, self.frictions = pressure, friction
        increment = np.einsum("qia,qa->qi", self.points.Nv, dU[self.points.dofs]) - self.points.g
        gap = self._mean(np.einsum("qi,qi->q", self.history.start + increment, self.n_in))
        moved = self._mean(np.einsum("qi,qi->q", increment, self.tangent))
        bound = self._bounds(pressure)
        status, direction = self.status.copy(), self.direction.copy()
        exceeds = (status == STICK) & ((self.friction == "frictionless") | (np.abs(friction) > bound * (1 + TOLERANCE)))
        along = np.where(friction != 0, np.sign(friction), -np.sign(moved))
        holds = (status == SLIP) & (bound > 0) & (moved * direction > TOLERANCE * self.scale)   # moves with its friction
        status[exceeds], direction[exceeds] = SLIP, along[exceeds]
        status[holds] = STICK
        if np.array_equal(status, self.status):
            stress = max(np.abs(pressure).max(initial=0.0), 1e-300)
            status[(status != OPEN) & (pressure < -TOLERANCE * stress)] = OPEN
            status[(self.status == OPEN) & (gap < -TOLERANCE * self.scale)] = STICK
        tresca = self.friction == "tresca"
        changed = not np.array_equal(status, self.status) or not np.array_equal(direction, self.direction)
        self.status, self.direction = status, direction
        self.bound = np.where(tresca, bound, 0.0)            # Tresca's bound is a load; Coulomb's follows p
        self.slip_bound = bound
        return changed

    def tractions(self) -> np.ndarray:
        """The traction on the material at each point (m, d) of the last solve."""
        status = self.status[self.pieces]
        p = np.where(status != OPEN, self.pressures[self.pieces], 0.0)
        along = np.where(status == STICK, self.frictions[self.pieces],
                         np.where(status == SLIP, (self.slip_bound * self.direction)[self.pieces], 0.0))
        return p[:, None] * self.n_in + along[:, None] * self.tangent


class MultiplierWall(ContactWall):
    """The multipliers' contact wall as baselines.contact_walls reports it (its accept)."""

    def __init__(self, contact: MultiplierContact):
        super().__init__(contact.history)
        self.contact = contact

    def response(self, dU):
        c, h = self.contact, self.history
        r = self.relative(dU)
        status = c.status[c.pieces]
        moved = r - h.start
        tangential = moved - np.einsum("qi,qi->q", moved, h.normal)[:, None] * h.normal
        slip = h.slip + np.where((status == SLIP)[:, None], tangential, 0.0)
        return r, c.tractions(), None, slip, status, None, None


def multiplier_terms(context: StepContext, points, others, cells: np.ndarray, info: dict):
    """StepTerms of the contact walls by multipliers (and the other walls' (C, g, wall) `others`)."""
    history = History.of(context, points)
    marks = history.points.wall
    runs = np.concatenate([[True], (history.points.cells[1:] != history.points.cells[:-1]) | (marks[1:] != marks[:-1])])
    pieces = merge_short(np.cumsum(runs) - 1, history.points.weight, context.grid.h ** (context.grid.dim - 1))
    # a piece does not reach across two features of an obstacle (a rigid footing's base and its corner)
    feature = history.feature
    split = np.concatenate([[True], (pieces[1:] != pieces[:-1]) | (feature[1:] != feature[:-1])])
    pieces = np.cumsum(split) - 1
    contact = MultiplierContact(context, history, pieces, others)
    reported = MultiplierWall(contact)
    cells = np.concatenate([cells, history.points.cells])

    def terms_of():
        C, g, wall, B = contact.terms()
        return StepTerms(constraints=(C, g), wall=wall, cells=cells, symmetric=B is None, multiplier_load=B,
                         support_threshold=info["support_threshold"], info={"n_multipliers": C.shape[0]},
                         accept=reported.accept, refine=refine)

    def refine(dU, multipliers):
        return terms_of() if contact.refine(dU, multipliers) else None

    return terms_of()
