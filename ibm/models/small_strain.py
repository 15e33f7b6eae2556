"""Constitutive models at small strain, behind the interface of ibm.models.constitutive.

The same `initial(n)` / `update(dF, state) -> Response` as the finite-strain models, with
dF = I + grad du the increment of the displacement gradient; State.F carries I + grad u (total),
so eps = sym(F - I). The tangent is the algorithmic modulus C_ijkl (d sigma_ij / d grad u_kl,
with both minor symmetries); `kinematics = "small"` tells the driver to integrate on the
initial configuration (no geometric stiffness, no volume change).

von Mises (J2) with linear isotropic hardening H, radial return (Simo & Hughes, box 3.1),
3 x 3 tensors (plane strain: eps_zz = 0, its plastic part free):
    trial:   s* = 2 mu dev(eps - eps_p,n),  f = |s*| - sqrt(2/3) (sigma_y + H alpha_n)
    return:  dgamma = f / (2 mu + 2/3 H),  n = s* / |s*|,  s = s* - 2 mu dgamma n,
             eps_p = eps_p,n + dgamma n,  alpha = alpha_n + sqrt(2/3) dgamma
    tangent: C = K 1 x 1 + 2 mu theta I_dev - 2 mu theta_bar n x n,
             theta = 1 - 2 mu dgamma / |s*|,  theta_bar = 1 / (1 + H / (3 mu)) - (1 - theta)
(the radial return of Simo and Hughes, checked against finite differences in tests/ibm/models/test_small_strain.py;
alpha is the equivalent plastic strain, so H is the slope of sigma_y against it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.models.constitutive import Response, State, check_yield, undeformed
from ibm.models.elastic import Elastic

_EYE = np.eye(3)
_SYMMETRIC = 0.5 * (np.einsum("ik,jl->ijkl", _EYE, _EYE) + np.einsum("il,jk->ijkl", _EYE, _EYE))
_VOLUMETRIC = np.einsum("ij,kl->ijkl", _EYE, _EYE)
_DEVIATORIC = _SYMMETRIC - _VOLUMETRIC / 3


def strain(F: np.ndarray) -> np.ndarray:
    """eps = sym(F - I) (n, 3, 3)."""
    grad = F - _EYE
    return 0.5 * (grad + grad.transpose(0, 2, 1))


@dataclass(frozen=True)
class LinearElastic(Elastic):
    """Linear isotropic elasticity (E, nu) at small strain."""

    kinematics = "small"

    def initial(self, n: int) -> State:
        return undeformed(n)

    def modulus(self) -> np.ndarray:
        """C (3, 3, 3, 3) = lam 1 x 1 + 2 mu I_sym."""
        return self.lam * _VOLUMETRIC + 2 * self.mu * _SYMMETRIC

    def update(self, dF: np.ndarray, state: State, dim: int = 3) -> Response:
        F = state.F + (dF - _EYE)
        eps = strain(F)
        sigma = self.lam * np.trace(eps, axis1=1, axis2=2)[:, None, None] * _EYE + 2 * self.mu * eps
        tangent = np.broadcast_to(self.modulus()[:dim, :dim, :dim, :dim], (len(F),) + (dim,) * 4).copy()
        return Response(sigma, tangent, State(F, state.be, {}))


@dataclass(frozen=True)
class VonMises(LinearElastic):
    """von Mises plasticity at small strain: yield stress sigma_y, linear hardening modulus H."""

    yield_stress: float = np.inf
    hardening: float = 0.0

    def __post_init__(self):
        super().__post_init__()
        check_yield(self.yield_stress, self.hardening)

    def initial(self, n: int) -> State:
        state = undeformed(n)
        return State(state.F, state.be, {"plastic": np.zeros((n, 3, 3)), "alpha": np.zeros(n)})

    def update(self, dF: np.ndarray, state: State, dim: int = 3) -> Response:
        n = len(dF)
        lam, mu, H = self.lam, self.mu, self.hardening
        F = state.F + (dF - _EYE)
        plastic_n = state.internal.get("plastic", np.zeros((n, 3, 3)))
        alpha_n = state.internal.get("alpha", np.zeros(n))
        elastic = strain(F) - plastic_n
        volumetric = np.trace(elastic, axis1=1, axis2=2)
        s_trial = 2 * mu * (elastic - volumetric[:, None, None] / 3 * _EYE)
        norm = np.sqrt(np.sum(s_trial * s_trial, axis=(1, 2)))
        f = norm - np.sqrt(2 / 3) * (self.yield_stress + H * alpha_n)
        plastic = f > 0
        safe = np.where(norm > 0, norm, 1.0)
        dgamma = np.where(plastic, f / (2 * mu + 2 / 3 * H), 0.0)
        direction = s_trial / safe[:, None, None]                              # n (n, 3, 3)
        s = s_trial - (2 * mu * dgamma)[:, None, None] * direction
        K = lam + 2 * mu / 3
        sigma = s + (K * volumetric)[:, None, None] * _EYE
        theta = 1 - 2 * mu * dgamma / safe
        theta_bar = np.where(plastic, 1 / (1 + H / (3 * mu)) - (1 - theta), 0.0)
        tangent = (K * _VOLUMETRIC + 2 * mu * theta[:, None, None, None, None] * _DEVIATORIC
                   - (2 * mu * theta_bar)[:, None, None, None, None] * np.einsum("nij,nkl->nijkl", direction, direction))
        internal = {"plastic": plastic_n + dgamma[:, None, None] * direction,
                    "alpha": alpha_n + np.sqrt(2 / 3) * dgamma}
        return Response(sigma, tangent[:, :dim, :dim, :dim, :dim], State(F, state.be, internal))
