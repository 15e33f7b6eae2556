"""Linear solves on the DOFs that have support, with checks instead of garbage answers."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class SolveError(RuntimeError):
    """The system cannot be solved reliably; the message says why."""


def active_dofs(grid, *cell_sets: np.ndarray) -> np.ndarray:
    """Sorted DOF ids of the nodes of all cells that hold quadrature points."""
    cells = np.unique(np.concatenate(cell_sets))
    return np.unique(grid.cell_dofs(cells))


def factorize(A: sp.spmatrix):
    """SuperLU factorization (COLAMD ordering); raises SolveError when exactly singular."""
    try:
        return spla.splu(sp.csc_matrix(A), permc_spec="COLAMD")
    except RuntimeError as error:
        raise SolveError(f"the system matrix is singular ({error}); check the essential boundaries") from None


def condition_estimate(A: sp.spmatrix, lu) -> float:
    """1-norm condition estimate ||A||_1 ||A^-1||_1 (Hager-Higham)."""
    n = A.shape[0]
    inverse = spla.LinearOperator((n, n), matvec=lu.solve, rmatvec=lambda y: lu.solve(y, trans="T"),
                                  dtype=float)
    return float(spla.onenormest(sp.csr_matrix(A), t=2) * spla.onenormest(inverse, t=2))


def equilibrate(A: sp.spmatrix) -> np.ndarray:
    """Symmetric scaling s (n,) with (S A S) having unit largest entry per row, S = diag(s).

    Nodes with tiny support (small cut cells) have tiny rows; scaling removes that
    artificial part of the conditioning without changing the solution.
    """
    row_max = abs(sp.csr_matrix(A)).max(axis=1).toarray().ravel()
    return 1.0 / np.sqrt(np.where(row_max > 0, row_max, 1.0))


def solve_system(A: sp.spmatrix, b: np.ndarray, estimate_condition: bool = True,
                 tolerance: float = 1e-8) -> tuple[np.ndarray, dict]:
    """x with A x = b, solved as (S A S) y = S b, x = S y.

    info has cond_est (of the scaled system actually factorized) and the relative
    residual of the original system. Raises SolveError.
    """
    diagonal = A.diagonal()
    if np.any(diagonal == 0) and not np.any(np.isnan(diagonal)):
        empty = np.flatnonzero(diagonal == 0)
        # Saddle-point systems have a zero block; only flag rows that are entirely empty.
        rows = np.diff(sp.csr_matrix(A).indptr)
        if np.any(rows[empty] == 0):
            raise SolveError(f"{np.sum(rows[empty] == 0)} unknowns have no stiffness (first: {empty[0]})")
    scale = equilibrate(A)
    S = sp.diags(scale)
    As = sp.csr_matrix(S @ A @ S)
    lu = factorize(As)
    x = scale * lu.solve(scale * b)
    norm_b = np.linalg.norm(b)
    residual = np.linalg.norm(A @ x - b) / (norm_b if norm_b > 0 else 1.0)
    info = {"residual": float(residual)}
    if estimate_condition:
        info["cond_est"] = condition_estimate(As, lu)
    if not np.all(np.isfinite(x)) or residual > tolerance:
        raise SolveError(f"the linear solve failed (relative residual {residual:.3g}); "
                         "the system is singular or too ill-conditioned")
    return x, info
