"""Exact finite-strain solutions in uniaxial strain: homogeneous compression and the
self-weight column (Hencky hyperelasticity, plane strain).

Material and frame:

    eps = 1/2 ln(b), b = F F^T               logarithmic strain
    tau = lam tr(eps) I + 2 mu eps            Kirchhoff stress
    sigma = tau / J, J = det F                Cauchy stress
    M = lam + 2 mu                            P-wave modulus
    xi along the base, eta the inward normal to the base (upwards)

Uniaxial strain along eta, F = diag(1, s, 1) in (xi, eta, z), stretch s:

    J = s, eps = diag(0, ln s, 0)
    sigma_eta_eta = M ln(s) / s,  sigma_xi_xi = sigma_zz = lam ln(s) / s

Compression by a pressure p > 0 on the top, M ln(s) / s = -p: with w = -ln s,
w e^w = p / M, so

    s = exp(-W(p / M))                        W the principal branch of Lambert W

and a point at initial height eta moves by u_eta = (s - 1) eta, u_xi = 0.

Self-weight column (rollers on base and sides, free top), initial height H, weight per
unit initial volume rho0 g = weight along -eta. Current equilibrium d sigma / dy = rho g
with rho = rho0 / s and dy = s dY gives d sigma / dY = weight for any material, so at
the point of initial height Y

    sigma_eta_eta(Y) = -weight (H - Y),  sigma_xi_xi = sigma_zz = (lam / M) sigma_eta_eta
    a(Y) = weight (H - Y) / M,           s(Y) = exp(-W(a)) = W(a) / a
    y(Y) = int_0^Y s dY = (M / weight) [G(a(0)) - G(a(Y))],  G(a) = W + W^2 / 2
    u_eta = y - Y = (M / weight) [K(a(0)) - K(a(Y))],  K(a) = G(a) - a = -W (expm1(W) - W / 2)

(int W(a) / a da = W + W^2 / 2 by a = W e^W). The forms exp(-W) and expm1 keep a = 0 and
small a free of 0/0 and cancellation. The small-strain column is the limit weight / M -> 0:

    u_eta = -(weight / M) (H Y - Y^2 / 2)

AMPLE's column error measure, over material points p with initial volumes V0_p:

    error = sum_p |sigma_p - sigma_exact_p| V0_p / sum_p weight H V0_p
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import lambertw


@dataclass(frozen=True)
class UniaxialState:
    """Displacements, stretch and Cauchy stresses at n points, each (n,), local frame."""

    u_xi: np.ndarray
    u_eta: np.ndarray
    stretch: np.ndarray
    sigma_xi_xi: np.ndarray
    sigma_eta_eta: np.ndarray
    sigma_zz: np.ndarray


def _lambert(a) -> np.ndarray:
    """Principal branch W(a), real, for a >= 0."""
    return lambertw(np.asarray(a, float)).real


def compression_stretch_of_pressure(pressure, M: float) -> np.ndarray:
    """Stretch s in (0, 1] with M ln(s) / s = -pressure, s = exp(-W(pressure / M))."""
    return np.exp(-_lambert(np.asarray(pressure, float) / M))


def compression(eta, stretch: float, material_lam: float, M: float) -> UniaxialState:
    """Block compressed homogeneously to height stretch H, at initial heights eta (n,)."""
    eta = np.asarray(eta, float)                                  # (n,)
    log_stretch = np.log(stretch)
    lateral = np.full_like(eta, material_lam * log_stretch / stretch)   # (n,)
    return UniaxialState(u_xi=np.zeros_like(eta), u_eta=(stretch - 1) * eta,
                         stretch=np.full_like(eta, stretch),
                         sigma_xi_xi=lateral, sigma_eta_eta=np.full_like(eta, M * log_stretch / stretch),
                         sigma_zz=lateral.copy())


def _height_minus_a(w: np.ndarray) -> np.ndarray:
    """K(a) = G(a) - a = -W (expm1(W) - W / 2), from W = W(a)."""
    return -w * (np.expm1(w) - w / 2)


def column(Y, H: float, weight: float, lam: float, M: float) -> UniaxialState:
    """Self-weight column of initial height H at initial heights Y (n,)."""
    Y = np.asarray(Y, float)                                      # (n,)
    sigma = -weight * (H - Y)                                     # (n,)
    a = weight * (H - Y) / M                                      # (n,)
    w = _lambert(a)                                               # (n,)
    if weight == 0:
        u_eta = np.zeros_like(Y)
    else:
        w_base = _lambert(weight * H / M)
        u_eta = (M / weight) * (_height_minus_a(w_base) - _height_minus_a(w))
    lateral = (lam / M) * sigma
    return UniaxialState(u_xi=np.zeros_like(Y), u_eta=u_eta, stretch=np.exp(-w),
                         sigma_xi_xi=lateral, sigma_eta_eta=sigma, sigma_zz=lateral.copy())


def column_height(H: float, weight: float, M: float) -> float:
    """Final height of the top, y(H) = (M / weight) G(weight H / M)."""
    if weight == 0:
        return float(H)
    w = float(_lambert(weight * H / M))
    return (M / weight) * (w + w * w / 2)


def ample_error(sigma_eta_eta_points, sigma_exact_points, V0, weight: float, H: float) -> float:
    """sum_p |sigma_p - sigma_exact_p| V0_p / sum_p weight H V0_p, all arrays (n,)."""
    V0 = np.asarray(V0, float)
    difference = np.abs(np.asarray(sigma_eta_eta_points, float) - np.asarray(sigma_exact_points, float))
    return float(np.sum(difference * V0) / (weight * H * np.sum(V0)))


def small_strain_column(Y, H: float, weight: float, M: float) -> np.ndarray:
    """Small-strain column displacement u_eta = -(weight / M) (H Y - Y^2 / 2), (n,)."""
    Y = np.asarray(Y, float)
    return -(weight / M) * (H * Y - Y**2 / 2)


def column_exact(H: float, load: float, material, t: float):
    """The self-weight column (rho_0 g = load / H) of a Hencky material at load fraction t: X (n, d) local ->
    (u_eta (n,), sigma_eta_eta (n,)), its top's height and the stress scale of err_sigma_ample (rho_0 g H)."""
    weight = t * load / H

    def field(X):
        state = column(X[:, 1], H, weight, material.lam, material.M)
        return state.u_eta, state.sigma_eta_eta
    return field, column_height(H, weight, material.M), weight * H
