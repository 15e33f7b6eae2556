"""Dirichlet functions of the implicit boundary method (seed eq. 2, method notes section 2).

Scalar, band width delta, phi the signed distance to the edge's line:
    D(phi) = 2 phi/delta - phi^2/delta^2 for phi < delta,  D = 1 beyond.
Matrix: roller D_k = I - (1 - D) n n^T, fixed D_k = D I; several edges: the product.
"""
from __future__ import annotations

import numpy as np

from ibm.geometry import Body


def scalar(phi: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """D(phi) and dD/dphi, elementwise."""
    s = np.minimum(phi / delta, 1.0)
    return 2 * s - s * s, np.where(phi < delta, 2 / delta * (1 - s), 0.0)


def _edge_factor(kind: str, normal: np.ndarray, D: np.ndarray, dD: np.ndarray):
    """One edge's matrix function, component-major: (2, 2, n) and gradient (2, 2, 2, n) [i, a, j, p]."""
    if kind == "roller":
        shape = np.outer(normal, normal)                       # n n^T
    elif kind == "fixed":
        shape = np.eye(2)
    else:
        raise ValueError(f"edge kind {kind!r} has no Dirichlet function")
    # roller: I - (1 - D) n n^T; fixed: D I = I - (1 - D) I
    Dk = np.eye(2)[:, :, None] - shape[:, :, None] * (1 - D)[None, None, :]
    grad = (shape[:, :, None] * normal[None, None, :])[..., None] * dD[None, None, None, :]
    return Dk, grad


def edge_matrix(kind: str, normal: np.ndarray, D: np.ndarray, dD: np.ndarray):
    """Matrix function of one edge, (n, 2, 2), and its gradient (n, 2, 2, 2) [p, i, a, j] = d_j D_ia."""
    Dk, grad = _edge_factor(kind, normal, D, dD)
    return Dk.transpose(2, 0, 1), grad.transpose(3, 0, 1, 2)


def matrix(body: Body, x: np.ndarray, delta: float, edges: list[int] | None = None):
    """The product of the essential edges' matrix functions at points x (n, 2).

    Returns D (n, 2, 2) and grad D (n, 2, 2, 2) with grad[p, i, a, j] = d D_ia / d x_j.
    """
    edges = body.essential_edges if edges is None else edges
    phi = body.signed_distance(x)
    Dm = np.zeros((len(x), 2, 2))
    Dm[:, 0, 0] = Dm[:, 1, 1] = 1.0
    grad = np.zeros((len(x), 2, 2, 2))
    # Beyond every band (phi >= delta) each factor is exactly I with zero gradient: only
    # the points inside some band need the products (few of all material points).
    near = np.flatnonzero(np.any(phi[:, edges] < delta, axis=1)) if edges else np.zeros(0, int)
    if len(near) == 0:
        return Dm, grad
    # component-major (2, 2, m) and (2, 2, 2, m): the small products are sums of a few
    # contiguous (m,) rows instead of batched 2 x 2 matrix products
    Dn = np.broadcast_to(np.eye(2)[:, :, None], (2, 2, len(near)))
    gradn = np.zeros((2, 2, 2, len(near)))
    for k in edges:   # loop over a handful of edges, vectorised over points
        Dk, gradk = _edge_factor(body.kinds[k], body.normals[k], *scalar(phi[near, k], delta))
        # grad (D Dk)_ia,j = sum_c (grad D)_ic,j Dk_ca + D_ic (grad Dk)_ca,j
        gradn = (np.sum(gradn[:, :, None] * Dk[None, :, :, None], axis=1)
                 + np.sum(Dn[:, :, None, None] * gradk[None], axis=1))
        Dn = np.sum(Dn[:, :, None] * Dk[None], axis=1)
    Dm[near] = Dn.transpose(2, 0, 1)
    grad[near] = gradn.transpose(3, 0, 1, 2)
    return Dm, grad
