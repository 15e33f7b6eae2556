"""Mohr-Coulomb plasticity (cohesion c, friction angle phi, dilation angle psi; perfectly plastic), returned in
principal stresses (docs/plasticity.md; de Souza Neto, Peric and Owen, Computational Methods for
Plasticity, 2008, section 8.2 and box 8.5).

Tension positive, principal values sorted sigma_1 >= sigma_2 >= sigma_3:

    yield:  Phi_13 = sigma_1 - sigma_3 + (sigma_1 + sigma_3) sin phi - 2 c cos phi <= 0
    flow:   N_13 = d/d sigma [sigma_1 - sigma_3 + (sigma_1 + sigma_3) sin psi] = (1 + sin psi, 0, -(1 - sin psi))

With the principal elastic matrix D = lam 1 1^T + 2 mu I and planes a_k, flows N_k, a return to the set S of
active planes solves A dgamma = Phi_S(sigma_tr), A_jk = a_j . D N_k, and gives sigma = sigma_tr - D N_S dgamma
with c = D - D N_S A^-1 (D a_S)^T: constants, since the planes are flat and the cohesion does not harden.
The regions, tried in turn:

    1 the main plane S = {13}, if the result keeps sigma_1 >= sigma_2 >= sigma_3;
    2 the edge sigma_1 = sigma_2, S = {13, 23}, where the plane's result had sigma_2 > sigma_1 (the larger
      violation), if it keeps sigma_2 >= sigma_3;
    3 the edge sigma_2 = sigma_3, S = {13, 12}, where it had sigma_3 > sigma_2, if it keeps sigma_1 >= sigma_2;
    4 the apex sigma_a = c cot phi (phi > 0), c = 0.

The tensors, the strains and the tangent at small and finite strain are those of ibm.models.isotropic.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.models.isotropic import FrictionalSoil, PrincipalFiniteStrain, PrincipalSmallStrain

ELASTIC, PLANE, EDGE_12, EDGE_23, APEX = 0, 1, 2, 3, 4
# a trial stress counts as yielding (and an order as kept) beyond this fraction of its size
TOLERANCE = 1e-12


def _planes(sine: float) -> dict:
    """The gradients of Phi_13, Phi_23 and Phi_12 (or of the flow potentials, with sin psi) in sorted order."""
    return {"13": np.array([1 + sine, 0.0, -(1 - sine)]), "23": np.array([0.0, 1 + sine, -(1 - sine)]),
            "12": np.array([1 + sine, -(1 - sine), 0.0])}


def mohr_coulomb_return(strain: np.ndarray, lam: float, mu: float, cohesion: float, friction_angle: float,
                        dilation_angle: float):
    """The returned principal stresses (n, 3), c = d sigma / d eps_tr (n, 3, 3) and the region (n,) of trial
    elastic principal strains (n, 3), in their own order (module doc; angles in degrees)."""
    n = len(strain)
    order = np.argsort(-strain, axis=1, kind="stable")
    eps = np.take_along_axis(strain, order, axis=1)                             # sorted, descending
    D = lam * np.ones((3, 3)) + 2 * mu * np.eye(3)
    trial = eps @ D
    phi, psi = np.radians(friction_angle), np.radians(dilation_angle)
    a, N = _planes(np.sin(phi)), _planes(np.sin(psi))
    strength = 2 * cohesion * np.cos(phi)
    scale = np.maximum(np.abs(trial).max(axis=1), max(strength, 1e-300))
    stress, c = trial.copy(), np.broadcast_to(D, (n, 3, 3)).copy()
    region = np.zeros(n, int)

    def to(active: list[str], where: np.ndarray):
        """The return of the points `where` to the planes `active`: stresses (m, 3) and the tangent (3, 3)."""
        DN = np.stack([D @ N[k] for k in active], axis=1)                          # (3, k)
        Da = np.stack([D @ a[k] for k in active], axis=1)
        A = np.stack([a[k] for k in active]) @ DN                                 # (k, k)
        f = trial[where] @ np.stack([a[k] for k in active], axis=1) - strength     # (m, k)
        return trial[where] - np.linalg.solve(A, f.T).T @ DN.T, D - DN @ np.linalg.solve(A, Da.T)

    def assign(where, values, tangent, code):
        stress[where], c[where], region[where] = values, tangent, code

    left = trial @ a["13"] - strength > TOLERANCE * scale
    plane, tangent = to(["13"], left)
    slack = np.stack([plane[:, 0] - plane[:, 1], plane[:, 1] - plane[:, 2]], axis=1) / scale[left, None]
    keeps = np.all(slack >= -TOLERANCE, axis=1)
    assign(np.flatnonzero(left)[keeps], plane[keeps], tangent, PLANE)
    left = np.flatnonzero(left)[~keeps]
    first = slack[~keeps, 0] < slack[~keeps, 1]                                    # sigma_2 > sigma_1 is the larger
    for code, active, kept_order, mine in ((EDGE_12, ["13", "23"], 1, first), (EDGE_23, ["13", "12"], 0, ~first)):
        where = left[mine]
        edge, tangent = to(active, where)
        keeps = edge[:, kept_order] - edge[:, kept_order + 1] >= -TOLERANCE * scale[where]
        assign(where[keeps], edge[keeps], tangent, code)
        if friction_angle > 0:
            assign(where[~keeps], cohesion / np.tan(phi), np.zeros((3, 3)), APEX)
        else:                       # Tresca has no apex: its edges hold every trial (sigma_1 > sigma_3 on both)
            assign(where[~keeps], edge[~keeps], tangent, code)
    rank = np.argsort(order, axis=1)
    return (np.take_along_axis(stress, rank, axis=1),
            c[np.arange(n)[:, None, None], rank[:, :, None], rank[:, None, :]], region)


def mohr_coulomb_yield(stress: np.ndarray, cohesion: float, friction_angle: float) -> np.ndarray:
    """Phi (n,) of principal stresses (n, 3) in any order (<= 0 inside)."""
    high, low = stress.max(axis=1), stress.min(axis=1)
    phi = np.radians(friction_angle)
    return high - low + (high + low) * np.sin(phi) - 2 * cohesion * np.cos(phi)


@dataclass(frozen=True)
class MohrCoulomb(FrictionalSoil, PrincipalSmallStrain):
    """Mohr-Coulomb at small strain: E, nu, cohesion, friction_angle, dilation_angle (degrees)."""

    return_map = staticmethod(mohr_coulomb_return)


@dataclass(frozen=True)
class HenckyMohrCoulomb(FrictionalSoil, PrincipalFiniteStrain):
    """Mohr-Coulomb at finite strain on Hencky elasticity (Kirchhoff stresses, logarithmic strains)."""

    return_map = staticmethod(mohr_coulomb_return)
