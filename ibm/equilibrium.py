"""Internal force and consistent tangent of sets of integration points (one Newton iterate).

For a set of points with x_n-volumes V (n,), gradient operators G (n, d d, m) of their trial
field, states at the step start and (optionally) the lift's gradient:

    dF = I + G dU_local + grad du^a,   (sigma, a) = model.update(dF, state)
    f_int = sum_p V_p det dF  Gc^T sigma,       K = sum_p V_p det dF  Gc^T a Gc,   Gc = G dF^-1

The material points form one set; the IBM's band correction adds the band points twice,
with its Dirichlet kinematics (sign +1) and with plain kinematics (sign -1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ibm.constitutive import Response, State
from ibm.kinematics import current_operator, increment, planar


@dataclass(frozen=True, eq=False)
class PointSet:
    """Integration points of one kind: DOF ids (n, m), G (n, d d, m), volume (n,), state, sign."""

    dofs: np.ndarray
    G: np.ndarray
    volume: np.ndarray
    state: State
    lift_gradient: np.ndarray | None = None   # (n, d, d) grad du^a at the points this step
    sign: float = 1.0

    def __len__(self) -> int:
        return len(self.volume)


@dataclass(frozen=True, eq=False)
class Evaluation:
    force: np.ndarray            # (n_dofs,) internal force
    magnitude: np.ndarray        # (n_dofs,) sum of |point contributions|: the forces' own size
    rows: np.ndarray             # COO triplets of the tangent
    columns: np.ndarray
    values: np.ndarray
    responses: list[Response]    # one per set, for the update after convergence

    def tangent(self, n_dofs: int) -> sp.csr_matrix:
        return sp.csr_matrix((self.values, (self.rows, self.columns)), shape=(n_dofs, n_dofs))


def evaluate(model, sets: list[PointSet], dU: np.ndarray) -> Evaluation:
    """f_int and the tangent triplets of all `sets` at the nodal increment dU (n_dofs,)."""
    force, magnitude = np.zeros(len(dU)), np.zeros(len(dU))
    rows, columns, values, responses = [], [], [], []
    for points in sets:
        if len(points) == 0:
            responses.append(None)
            continue
        n, dd, m = points.G.shape
        d = int(round(np.sqrt(dd)))
        dF = increment(points.G, dU[points.dofs], points.lift_gradient)
        response = model.update(dF, points.state)
        responses.append(response)
        Gc = current_operator(points.G, dF)
        weight = points.sign * points.volume * np.linalg.det(dF[:, :d, :d])          # (n,) current volumes
        local = np.einsum("pkc,pk->pc", Gc, planar(response.sigma, d)) * weight[:, None]
        force += np.bincount(points.dofs.ravel(), local.ravel(), minlength=len(dU))
        magnitude += np.bincount(points.dofs.ravel(), np.abs(local).ravel(), minlength=len(dU))
        A = planar(response.tangent, d)                                              # (n, d d, d d)
        block = np.matmul(Gc.transpose(0, 2, 1), np.matmul(A, Gc)) * weight[:, None, None]   # (n, m, m)
        rows.append(np.repeat(points.dofs, m, axis=1).ravel())
        columns.append(np.tile(points.dofs, (1, m)).ravel())
        values.append(block.ravel())
    cat = (lambda parts, dtype: np.concatenate(parts) if parts else np.zeros(0, dtype))
    return Evaluation(force, magnitude, cat(rows, int), cat(columns, int), cat(values, float), responses)
