"""Finite-strain kinematics of one load step (updated Lagrangian, docs/large-deformation.md).

The step is written on the configuration x_n at its start. A trial field w = D w^h + w^a
(D = I for plain kinematics) has the gradient, with respect to x_n,

    grad w_ij = sum_(v, a) G[(i, j), (v, a)] w_va + grad w^a_ij,
    G[(i, j), (v, a)] = D_ia dS_v / dx_j + S_v dD_ia / dx_j,

so dF = I + grad dw, and the current gradient of a nodal function is G dF^-1:
Gc[(i, j), .] = sum_m G[(i, m), .] (dF^-1)_mj. Index (i, j) is flattened as i d + j, a nodal
DOF (v, a) as v d + a. Tensors of the constitutive models are 3 x 3 in every dimension:
2D is plane strain, dF_33 = 1.
"""
from __future__ import annotations

import numpy as np


def gradient_operator(S: np.ndarray, dS: np.ndarray, D: np.ndarray | None = None,
                      gradD: np.ndarray | None = None) -> np.ndarray:
    """G (n, d d, k d) from basis values S (n, k), gradients dS (n, k, d) and optionally
    D (n, d, d), grad D (n, d, d, d) [p, i, a, j] = d D_ia / d x_j."""
    n, k, d = dS.shape
    if D is None:
        G = np.zeros((n, d, d, k, d))                                   # [p, i, j, v, a]
        for i in range(d):
            G[:, i, :, :, i] = dS.transpose(0, 2, 1)
        return G.reshape(n, d * d, k * d)
    G = (np.einsum("pia,pvj->pijva", D, dS) + np.einsum("pv,piaj->pijva", S, gradD))
    return G.reshape(n, d * d, k * d)


def embed(gradient: np.ndarray) -> np.ndarray:
    """dF (n, 3, 3) = I + gradient (n, d, d) (plane strain: the third row and column of I)."""
    n, d, _ = gradient.shape
    dF = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    dF[:, :d, :d] += gradient
    return dF


def increment(G: np.ndarray, local: np.ndarray, lift_gradient: np.ndarray | None = None) -> np.ndarray:
    """dF (n, 3, 3) of nodal increments local (n, k d) through G (n, d d, k d), plus the lift's gradient."""
    n = len(G)
    d = int(round(np.sqrt(G.shape[1])))
    gradient = np.matmul(G, local[:, :, None])[:, :, 0].reshape(n, d, d)
    if lift_gradient is not None:
        gradient = gradient + lift_gradient
    return embed(gradient)


def is_small(material) -> bool:
    """Whether `material` is a small-strain model (ibm.models.small_strain): the driver then integrates on
    the initial configuration (gradients G, volumes V, no geometric stiffness) and moves nothing."""
    return getattr(material, "kinematics", "large") == "small"


def current_operator(G: np.ndarray, dF: np.ndarray) -> np.ndarray:
    """Gc (n, d d, k d): gradients with respect to the current configuration x = x_n + dw."""
    n, dd, m = G.shape
    d = int(round(np.sqrt(dd)))
    inverse = np.linalg.inv(dF[:, :d, :d])                              # plane strain: dF_33 = 1
    # Gc[p, i, j, c] = sum_m inverse[p, m, j] G[p, i, m, c]
    return np.matmul(inverse.transpose(0, 2, 1)[:, None], G.reshape(n, d, d, m)).reshape(n, dd, m)


def planar(tensor: np.ndarray, d: int) -> np.ndarray:
    """The in-plane part of a 3 x 3 (n, 3, 3) or 3^4 (n, 3, 3, 3, 3) tensor, flattened:
    (n, d d) or (n, d d, d d)."""
    n = len(tensor)
    if tensor.ndim == 3:
        return tensor[:, :d, :d].reshape(n, d * d)
    return tensor[:, :d, :d, :d, :d].reshape(n, d * d, d * d)
