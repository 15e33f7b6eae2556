"""Drucker-Prager plasticity matched to Mohr-Coulomb in plane strain (perfectly plastic), returned in principal
stresses (docs/plasticity.md; de Souza Neto, Peric and Owen, Computational Methods for Plasticity,
2008, sections 8.3 and 6.4).

Tension positive, p = tr sigma / 3, s = dev sigma, J2 = s.s / 2:

    yield:  Phi = sqrt(J2) + eta p - xi c <= 0,
            eta = 3 tan phi / sqrt(9 + 12 tan^2 phi),  xi = 3 / sqrt(9 + 12 tan^2 phi)
    flow:   sqrt(J2) + eta_bar p, eta_bar the same function of psi.

With associated flow in plane strain the cone and the Mohr-Coulomb prism give the same limit state (the
plastic strain rate out of the plane vanishes), so the same collapse loads. With G = mu, K the bulk modulus:

    cone:  dgamma = Phi_tr / (G + K eta eta_bar),  s = (1 - G dgamma / sqrt(J2_tr)) s_tr,  p = p_tr - K eta_bar dgamma,
           valid while sqrt(J2_tr) >= G dgamma; otherwise
    apex:  sigma = (xi c / eta) 1, c = 0.

On the cone, with the unit deviator m = s_tr / |s_tr| and dgamma' = (sqrt(2) G m + K eta 1) / (G + K eta eta_bar)
(the derivative of dgamma by the trial strains),

    c = 2G (I - 1 1^T / 3) - sqrt(2) G m dgamma'^T - 2 sqrt(2) G^2 dgamma / |s_tr| (I - 1 1^T / 3 - m m^T)
        + K 1 (1 - eta_bar dgamma')^T.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.models.isotropic import FrictionalSoil, PrincipalFiniteStrain, PrincipalSmallStrain

ELASTIC, CONE, APEX = 0, 1, 2
TOLERANCE = 1e-12


def plane_strain_match(angle: float) -> tuple[float, float]:
    """(eta, xi) of the cone matched to Mohr-Coulomb of this angle (degrees) in plane strain."""
    tangent = np.tan(np.radians(angle))
    root = np.sqrt(9 + 12 * tangent ** 2)
    return 3 * tangent / root, 3 / root


def drucker_prager_return(strain: np.ndarray, lam: float, mu: float, cohesion: float, friction_angle: float,
                          dilation_angle: float):
    """The returned principal stresses (n, 3), c = d sigma / d eps_tr (n, 3, 3) and the region (n,) of trial
    elastic principal strains (n, 3) (module doc; angles in degrees)."""
    n = len(strain)
    K, G = lam + 2 * mu / 3, mu
    eta, xi = plane_strain_match(friction_angle)
    eta_bar, _ = plane_strain_match(dilation_angle)
    volumetric = strain.sum(axis=1)
    p_trial = K * volumetric
    s_trial = 2 * G * (strain - volumetric[:, None] / 3)
    size = np.sqrt(np.sum(s_trial ** 2, axis=1))                                 # |s_tr| = sqrt(2 J2_tr)
    f = size / np.sqrt(2) + eta * p_trial - xi * cohesion
    scale = np.maximum(np.maximum(size, np.abs(p_trial)), max(xi * cohesion, 1e-300))
    one, deviator = np.ones(3), np.eye(3) - 1.0 / 3.0
    stress = s_trial + p_trial[:, None]
    c = np.broadcast_to(K + 2 * G * deviator, (n, 3, 3)).copy()
    region = np.zeros(n, int)

    plastic = f > TOLERANCE * scale
    dgamma = f[plastic] / (G + K * eta * eta_bar)
    on_cone = size[plastic] / np.sqrt(2) - G * dgamma >= -TOLERANCE * scale[plastic]
    cone = np.flatnonzero(plastic)[on_cone]
    dgamma = dgamma[on_cone]
    m = s_trial[cone] / size[cone, None]
    factor = 1 - G * dgamma * np.sqrt(2) / size[cone]
    stress[cone] = s_trial[cone] * factor[:, None] + (p_trial[cone] - K * eta_bar * dgamma)[:, None]
    derivative = (np.sqrt(2) * G * m + K * eta) / (G + K * eta * eta_bar)        # d dgamma / d eps_tr (m, 3)
    c[cone] = (2 * G * deviator - np.sqrt(2) * G * m[:, :, None] * derivative[:, None, :]
               - (2 * np.sqrt(2) * G ** 2 * dgamma / size[cone])[:, None, None]
               * (deviator - m[:, :, None] * m[:, None, :])
               + K * one[None, :, None] * (one - eta_bar * derivative)[:, None, :])
    region[cone] = CONE
    apex = np.flatnonzero(plastic)[~on_cone]
    stress[apex] = xi * cohesion / eta if eta > 0 else 0.0
    c[apex] = 0.0
    region[apex] = APEX
    return stress, c, region


def drucker_prager_yield(stress: np.ndarray, cohesion: float, friction_angle: float) -> np.ndarray:
    """Phi (n,) of principal stresses (n, 3) (<= 0 inside)."""
    eta, xi = plane_strain_match(friction_angle)
    p = stress.mean(axis=1)
    return np.sqrt(0.5 * np.sum((stress - p[:, None]) ** 2, axis=1)) + eta * p - xi * cohesion


@dataclass(frozen=True)
class DruckerPrager(FrictionalSoil, PrincipalSmallStrain):
    """Drucker-Prager at small strain: E, nu, cohesion, friction_angle, dilation_angle (degrees)."""

    return_map = staticmethod(drucker_prager_return)


@dataclass(frozen=True)
class HenckyDruckerPrager(FrictionalSoil, PrincipalFiniteStrain):
    """Drucker-Prager at finite strain on Hencky elasticity (Kirchhoff stresses, logarithmic strains)."""

    return_map = staticmethod(drucker_prager_return)
