"""Strain operators and sparse assembly of element blocks.

Voigt rows of the strain of nodal DOF (I, a) with the Dirichlet matrix D:
    Q[I, i, a, j] = d(N_I D_ia)/dx_j = D_ia dN_I/dx_j + N_I dD_ia/dx_j
    eps_xx = Q[0, a, 0], eps_yy = Q[1, a, 1], gamma_xy = Q[0, a, 1] + Q[1, a, 0]
Without D (D = I) this is the ordinary Q4 strain operator.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ibm.grid import Grid


def strain_matrix(N: np.ndarray, dN: np.ndarray, Dm: np.ndarray | None = None,
                  gradDm: np.ndarray | None = None) -> np.ndarray:
    """B (n, 3, 8) from N (n, 4), dN (n, 4, 2) and optionally D (n, 2, 2), grad D (n, 2, 2, 2)."""
    if Dm is None:
        Q = np.einsum("ia,pIj->pIiaj", np.eye(2), dN)
    else:
        Q = np.einsum("pia,pIj->pIiaj", Dm, dN) + np.einsum("pI,piaj->pIiaj", N, gradDm)
    B = np.stack([Q[:, :, 0, :, 0], Q[:, :, 1, :, 1], Q[:, :, 0, :, 1] + Q[:, :, 1, :, 0]], axis=1)
    return B.reshape(len(N), 3, 8)   # column 2 I + a


def shape_vector(N: np.ndarray, Dm: np.ndarray | None = None) -> np.ndarray:
    """Displacement operator Nv (n, 2, 8): u_i = sum_{I,a} N_I D_ia u_Ia."""
    Dm = np.broadcast_to(np.eye(2), (len(N), 2, 2)) if Dm is None else Dm
    return np.einsum("pI,pia->piIa", N, Dm).reshape(len(N), 2, 8)


def stiffness_blocks(B: np.ndarray, C: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Element blocks (n, 8, 8) = w B^T C B."""
    CB = np.einsum("kl,plj->pkj", C, B)
    return np.einsum("pki,pkj->pij", B, CB * weight[:, None, None])


def assemble_matrix(grid: Grid, cells: np.ndarray, blocks: np.ndarray) -> sp.csr_matrix:
    """Sum the (n, 8, 8) blocks of points in `cells` into a (2 n_nodes)^2 CSR matrix."""
    dofs = grid.cell_dofs(cells)
    n = 2 * grid.n_nodes
    rows = np.broadcast_to(dofs[:, :, None], blocks.shape).ravel()
    cols = np.broadcast_to(dofs[:, None, :], blocks.shape).ravel()
    return sp.csr_matrix((blocks.ravel(), (rows, cols)), shape=(n, n))


def assemble_vector(grid: Grid, cells: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """Sum the (n, 8) blocks of points in `cells` into a (2 n_nodes,) vector."""
    return np.bincount(grid.cell_dofs(cells).ravel(), weights=blocks.ravel(), minlength=2 * grid.n_nodes)


def voigt(eps_tensor: np.ndarray) -> np.ndarray:
    """(n, 3) engineering Voigt strain from a displacement gradient or strain tensor (n, 2, 2)."""
    return np.stack([eps_tensor[:, 0, 0], eps_tensor[:, 1, 1], eps_tensor[:, 0, 1] + eps_tensor[:, 1, 0]], axis=1)


def tensor(sigma_voigt: np.ndarray) -> np.ndarray:
    """(n, 2, 2) symmetric tensor from Voigt stresses (n, 3)."""
    s = sigma_voigt
    return np.stack([np.stack([s[:, 0], s[:, 2]], -1), np.stack([s[:, 2], s[:, 1]], -1)], axis=1)
