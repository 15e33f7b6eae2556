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


def edge_matrix(kind: str, normal: np.ndarray, D: np.ndarray, dD: np.ndarray):
    """Matrix function of one edge, (n, 2, 2), and its gradient (n, 2, 2, 2) [p, i, a, j] = d_j D_ia."""
    n_points = len(D)
    if kind == "roller":
        nn = np.outer(normal, normal)
        Dm = np.eye(2)[None] - (1 - D)[:, None, None] * nn[None]
        grad = dD[:, None, None, None] * nn[None, :, :, None] * normal[None, None, None, :]
    elif kind == "fixed":
        Dm = D[:, None, None] * np.eye(2)[None]
        grad = dD[:, None, None, None] * np.eye(2)[None, :, :, None] * normal[None, None, None, :]
    else:
        raise ValueError(f"edge kind {kind!r} has no Dirichlet function")
    return Dm, np.broadcast_to(grad, (n_points, 2, 2, 2))


def matrix(body: Body, x: np.ndarray, delta: float, edges: list[int] | None = None):
    """The product of the essential edges' matrix functions at points x (n, 2).

    Returns D (n, 2, 2) and grad D (n, 2, 2, 2) with grad[p, i, a, j] = d D_ia / d x_j.
    """
    edges = body.essential_edges if edges is None else edges
    phi = body.signed_distance(x)
    Dm = np.broadcast_to(np.eye(2), (len(x), 2, 2)).copy()
    grad = np.zeros((len(x), 2, 2, 2))
    # Beyond every band (phi >= delta) each factor is exactly I with zero gradient: only
    # the points inside some band need the products (few of all material points).
    near = np.flatnonzero(np.any(phi[:, edges] < delta, axis=1)) if edges else np.zeros(0, int)
    Dn, gradn = Dm[near], grad[near]
    for k in edges:   # loop over a handful of edges, vectorised over points
        Dk, gradk = edge_matrix(body.kinds[k], body.normals[k], *scalar(phi[near, k], delta))
        # grad (D Dk) = (grad D) Dk + D grad Dk, per derivative direction j (batched 2 x 2 products)
        gradn = (np.matmul(gradn.transpose(0, 3, 1, 2), Dk[:, None])
                 + np.matmul(Dn[:, None], gradk.transpose(0, 3, 1, 2))).transpose(0, 2, 3, 1)
        Dn = np.matmul(Dn, Dk)
    Dm[near], grad[near] = Dn, gradn
    return Dm, grad
