"""Dirichlet functions of the implicit boundary method (the seed paper, eq. 2).

Scalar, band width delta, phi a wall's distance (ibm.geometry.walls.Wall.distance: the distance to
the wall's line, ending past the wall's ends where the wall does):
    D(phi) = 2 phi/delta - phi^2/delta^2 for phi < delta,  D = 1 beyond.
Matrix: roller D_k = I - (1 - D) n n^T (n the wall's normal), fixed D_k = D I; several
walls: the product. grad D_k = (n n^T or I) D'(phi) grad phi, and on a roller arc, whose
normal n = -sign e_r turns with the point, also - (1 - D) grad(n n^T), with
d_j e_r,i = (delta_ij - e_r,i e_r,j) / rho.

An arc's factor leads the product (Body.walls lists arcs first): a straight roller whose band
overlaps a roller arc's lies on a radius of the arc (bands.check_commuting), so on that line
n_arc . n_line = 0 and D_arc D_line v keeps both normal components zero where each must be.
"""
from __future__ import annotations

import numpy as np

from ibm.geometry.outline import Body


def scalar(phi: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """D(phi) and dD/dphi, elementwise."""
    s = np.minimum(phi / delta, 1.0)
    return 2 * s - s * s, np.where(phi < delta, 2 / delta * (1 - s), 0.0)


def _edge_factor(kind: str, normal: np.ndarray, D: np.ndarray, dD: np.ndarray, gradient: np.ndarray | None = None):
    """One wall's matrix function, component-major: (d, d, n) and gradient (d, d, d, n) [i, a, j, p].

    gradient (n, d) of phi; None: the normal (phi the distance to the line or plane)."""
    if kind not in ("roller", "fixed"):
        raise ValueError(f"edge kind {kind!r} has no Dirichlet function")
    d = len(normal)
    shape = np.outer(normal, normal) if kind == "roller" else np.eye(d)       # n n^T or I
    # roller: I - (1 - D) n n^T; fixed: D I = I - (1 - D) I
    Dk = np.eye(d)[:, :, None] - shape[:, :, None] * (1 - D)[None, None, :]
    if gradient is None:
        grad = (shape[:, :, None] * normal[None, None, :])[..., None] * dD[None, None, None, :]
    else:
        grad = shape[:, :, None, None] * (gradient.T * dD)[None, None]
    return Dk, grad


def _arc_factor(kind: str, normal: np.ndarray, D: np.ndarray, dD: np.ndarray, gradient: np.ndarray,
                radial: np.ndarray, rho: np.ndarray):
    """_edge_factor with a normal per point (m, 2) = +-e_r; gradient (m, 2) of phi (= +-n); the
    points' e_r (m, 2) and rho (m,) about the arc's centre."""
    n = normal.T                                                            # (2, m)
    if kind == "fixed":
        shape = np.broadcast_to(np.eye(2)[:, :, None], (2, 2, len(D)))
        return (np.eye(2)[:, :, None] - shape * (1 - D)), shape[:, :, None] * (gradient.T * dD)[None, None]
    shape = n[:, None] * n[None, :]                                         # (2, 2, m)
    Dk = np.eye(2)[:, :, None] - shape * (1 - D)
    grad = shape[:, :, None] * (gradient.T * dD)[None, None]
    # n n^T = e e^T (e = e_r): d_j (e_i e_a) = (P_ij e_a + e_i P_aj) / rho, P = I - e e^T
    P = np.eye(2)[:, :, None] - shape
    e = radial.T
    grad = grad - (1 - D) * (P[:, None] * e[None, :, None] + e[:, None, None] * P[None]) / rho
    return Dk, grad


def edge_matrix(kind: str, normal: np.ndarray, D: np.ndarray, dD: np.ndarray):
    """Matrix function of one edge, (n, 2, 2), and its gradient (n, 2, 2, 2) [p, i, a, j] = d_j D_ia."""
    Dk, grad = _edge_factor(kind, normal, D, dD)
    return Dk.transpose(2, 0, 1), grad.transpose(3, 0, 1, 2)


def matrix(body: Body, x: np.ndarray, delta: float, leave_out: int | None = None,
           region: np.ndarray | None = None):
    """The product of the walls' matrix functions at points x (n, d), in the order of body.walls;
    leave_out: the index of a wall whose factor is left out (the IBM's reactions).
    region (n,) bit masks of walls: the functions of band region R_S at each point (the
    polynomial D(phi) of the walls in S, unclamped, and I for the others), for the nodes of a
    moment-fitted band rule.

    Returns D (n, d, d) and grad D (n, d, d, d) with grad[p, i, a, j] = d D_ia / d x_j.
    """
    walls = tuple(wall for w, wall in enumerate(body.walls) if w != leave_out)
    n, d = x.shape
    Dm = np.zeros((n, d, d))
    Dm[:, np.arange(d), np.arange(d)] = 1.0
    grad = np.zeros((n, d, d, d))
    if not walls:
        return Dm, grad
    # Beyond every band (phi >= delta) each factor is exactly I with zero gradient: only
    # the points inside some band need the products (few of all material points).
    indices = [w for w in range(len(body.walls)) if w != leave_out]
    if region is not None:
        near = np.flatnonzero(region != 0)
    else:
        s = np.stack([wall.signed(x) for wall in walls], axis=1)          # (n, n_walls)
        near = np.flatnonzero(np.any(np.abs(s) < delta, axis=1))
    if len(near) == 0:
        return Dm, grad
    # component-major (d, d, m) and (d, d, d, m): the small products are sums of a few
    # contiguous (m,) rows instead of batched d x d matrix products
    Dn = np.broadcast_to(np.eye(d)[:, :, None], (d, d, len(near)))
    gradn = np.zeros((d, d, d, len(near)))
    for index, wall in zip(indices, walls):   # loop over a handful of walls, vectorised over points
        phi, gradient = wall.distance(x[near], delta)
        if wall.curved:
            radial = x[near] - wall.center           # (not d: that is the dimension here)
            rho = np.hypot(radial[:, 0], radial[:, 1])
            Dk, gradk = _arc_factor(wall.kind, wall.normal_at(x[near]), *scalar(phi, delta), gradient,
                                    radial / rho[:, None], rho)
        elif region is not None:
            inside = (region[near] >> index & 1).astype(bool)
            D, dD = 2 * phi / delta - (phi / delta) ** 2, 2 / delta * (1 - phi / delta)
            Dk, gradk = _edge_factor(wall.kind, wall.normal, np.where(inside, D, 1.0), np.where(inside, dD, 0.0),
                                     gradient)
        else:
            Dk, gradk = _edge_factor(wall.kind, wall.normal, *scalar(phi, delta), gradient)
        # grad (D Dk)_ia,j = sum_c (grad D)_ic,j Dk_ca + D_ic (grad Dk)_ca,j
        gradn = (np.sum(gradn[:, :, None] * Dk[None, :, :, None], axis=1)
                 + np.sum(Dn[:, :, None, None] * gradk[None], axis=1))
        Dn = np.sum(Dn[:, :, None] * Dk[None], axis=1)
    Dm[near] = Dn.transpose(2, 0, 1)
    grad[near] = gradn.transpose(3, 0, 1, 2)
    return Dm, grad
