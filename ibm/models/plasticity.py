"""J2 (von Mises) plasticity at finite strain on Hencky elasticity, behind the constitutive interface.

Multiplicative split F = F_e F_p, the elastic left Cauchy-Green tensor b_e carried per point
(Simo's exponential return map, plastic flow isochoric), isotropic linear hardening:

    trial:   b_tr = dF b_e,n dF^T = sum_a lambda_a n_a n_a,   eps_tr = 1/2 ln lambda (principal),
             tau_tr = lam tr(eps_tr) 1 + 2 mu eps_tr,  s = dev tau_tr,  q = sqrt(3/2 s.s)
    yield:   f = q - (sigma_y + H alpha_n)
    return:  dgamma = f / (3 mu + H),  nu = 3/2 s / q,  eps_e = eps_tr - dgamma nu,  alpha = alpha_n + dgamma
    update:  b_e = sum_a exp(2 eps_e,a) n_a n_a,   tau = lam tr(eps_e) 1 + 2 mu eps_e

The consistent tangent of the principal stresses with respect to the trial log strains is
c = c_e - 2 mu [2 mu / (3 mu + H) nu nu + 2 mu dgamma / q (3/2 P_dev - nu nu)] on the plastic
points (c_e = lam 1 1 + 2 mu I). The spatial tangent then follows as for Hencky, with the
isotropic tensor function tau(b_tr) differentiated in the trial eigenbasis:
d tau'_aa = sum_b c_ab d eps_b and d tau'_ab = theta_ab d eps'_ab (a != b),
theta_ab = (tau_a - tau_b) / (eps_a - eps_b) (its limit c_aa - c_ab at equal eigenvalues),
a_ijkl = (1/J) (d tau / d b)_ijkq 2 b_tr,ql - sigma_il delta_jk, written in the trial eigenbasis by
ibm.models.constitutive.spatial_tangent from c and s_ab = theta_ab g_ab / 2.
State.internal holds "alpha" (n,), the equivalent plastic strain.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.models.constitutive import (Hencky, Response, State, check_yield, log_divided_differences, principal,
                              spatial_tangent, trial, undeformed)
from ibm.models.isotropic import divided_differences


@dataclass(frozen=True)
class HenckyJ2(Hencky):
    """Hencky elasticity (E, nu) with von Mises yield stress sigma_y and linear hardening modulus H."""

    yield_stress: float = np.inf
    hardening: float = 0.0

    def __post_init__(self):
        super().__post_init__()
        check_yield(self.yield_stress, self.hardening)

    def initial(self, n: int) -> State:
        state = undeformed(n)
        return State(state.F, state.be, {"alpha": np.zeros(n)})

    def update(self, dF: np.ndarray, state: State, dim: int = 3) -> Response:
        n = len(dF)
        F, J, b_trial = trial(dF, state)
        values, vectors = principal(b_trial)
        lam, mu, H = self.lam, self.mu, self.hardening
        strain = 0.5 * np.log(values)                                           # (n, 3) trial log strains
        tau_trial = lam * strain.sum(axis=1, keepdims=True) + 2 * mu * strain
        s = tau_trial - tau_trial.mean(axis=1, keepdims=True)
        q = np.sqrt(1.5 * np.sum(s * s, axis=1))
        alpha_n = state.internal.get("alpha", np.zeros(n))
        f = q - (self.yield_stress + H * alpha_n)
        plastic = f > 0
        dgamma = np.where(plastic, f / (3 * mu + H), 0.0)
        direction = np.where(plastic[:, None], 1.5 * s / np.where(q > 0, q, 1.0)[:, None], 0.0)   # nu (n, 3)
        elastic_strain = strain - dgamma[:, None] * direction
        tau = lam * elastic_strain.sum(axis=1, keepdims=True) + 2 * mu * elastic_strain          # (n, 3)
        transposed = vectors.transpose(0, 2, 1)
        be = np.matmul(vectors * np.exp(2 * elastic_strain)[:, None, :], transposed)   # sum_a x_a n_a n_a
        sigma = np.matmul(vectors * (tau / J[:, None])[:, None, :], transposed)

        # c_ab = d tau_a / d eps_tr,b
        eye = np.eye(3)
        deviator = eye - 1.0 / 3.0
        c = np.broadcast_to(lam + 2 * mu * eye, (n, 3, 3)).copy()
        outer = direction[:, :, None] * direction[:, None, :]
        c -= (2 * mu) * (2 * mu / (3 * mu + H)) * outer * plastic[:, None, None]
        c -= (2 * mu) * (2 * mu * dgamma / np.where(q > 0, q, 1.0))[:, None, None] * (1.5 * deviator - outer)
        # theta_ab: divided differences of tau over the trial strains (limit c_aa - c_ab), of the PAIRS (3, n)
        shear = 0.5 * divided_differences(tau, strain, c) * log_divided_differences(values)   # s_ab = theta_ab g_ab / 2
        tangent = spatial_tangent(vectors, values, c, shear, sigma, J, dim)
        return Response(sigma, tangent, State(F, be, {"alpha": alpha_n + dgamma}))
