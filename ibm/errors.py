"""Error measures, one definition for every method (method notes section 5).

err_u     = sqrt(sum_p V_p |u_h - u|^2 / sum_p V_p |u|^2)
err_sigma = the same for the problem's reported stress component (e.g. sigma_eta_eta)
*_max     = max_p |h - exact| / max_p |exact|
err_sigma_fro: the whole stress tensor (in-plane and zz) in the Frobenius norm.
"""
from __future__ import annotations

import numpy as np


def _relative(volume, error_sq, exact_sq):
    exact = np.sum(volume * exact_sq)
    return float(np.sqrt(np.sum(volume * error_sq) / exact)) if exact > 0 else float(np.sqrt(np.sum(volume * error_sq)))


def _relative_max(error_abs, exact_abs):
    top = exact_abs.max(initial=0.0)
    return float(error_abs.max(initial=0.0) / top) if top > 0 else float(error_abs.max(initial=0.0))


def stress_component(sigma: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """d . sigma . d for sigma (n, 2, 2) and a unit direction d (2,)."""
    return np.einsum("i,pij,j->p", direction, sigma, direction)


def point_errors(volume, u_h, u, sigma_h, sigma, sigma_zz_h, sigma_zz, direction) -> dict:
    """The material-point errors of method notes section 5, as a dict of floats."""
    du = np.sum((u_h - u) ** 2, axis=1)
    s_h, s = stress_component(sigma_h, direction), stress_component(sigma, direction)
    ds_full = np.sum((sigma_h - sigma) ** 2, axis=(1, 2)) + (sigma_zz_h - sigma_zz) ** 2
    s_full = np.sum(sigma ** 2, axis=(1, 2)) + sigma_zz ** 2
    return {
        "err_u": _relative(volume, du, np.sum(u ** 2, axis=1)),
        "err_sigma": _relative(volume, (s_h - s) ** 2, s ** 2),
        "err_sigma_fro": _relative(volume, ds_full, s_full),
        "err_u_max": _relative_max(np.sqrt(du), np.linalg.norm(u, axis=1)),
        "err_sigma_max": _relative_max(np.abs(s_h - s), np.abs(s)),
    }


def pointwise_relative(u_h, u, sigma_h, sigma, direction) -> tuple[np.ndarray, np.ndarray]:
    """Per-point errors |u_h - u| / max|u| and |s_h - s| / max|s| (for error maps)."""
    s_h, s = stress_component(sigma_h, direction), stress_component(sigma, direction)
    top_u = np.linalg.norm(u, axis=1).max(initial=0.0) or 1.0
    top_s = np.abs(s).max(initial=0.0) or 1.0
    return np.linalg.norm(u_h - u, axis=1) / top_u, np.abs(s_h - s) / top_s
