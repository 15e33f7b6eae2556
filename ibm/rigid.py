"""Detect rigid-body motions left free by too few essential boundaries.

With nodal rigid modes R = [t_x, t_y, rotation] (n_dofs, 3), a free mode is a combination
v with R v in the null space: the generalized Rayleigh quotient of G = R^T K R against
W = R^T diag(K) R is ~ round-off. Constrained bodies give quotients many orders above it.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ibm.grid import Grid
from ibm.solve import SolveError

FREE_TOLERANCE = 1e-10


def rigid_modes(grid: Grid, dofs: np.ndarray) -> np.ndarray:
    """(n_dofs, 3) translations along x and y and a rotation about the active nodes' centre."""
    node = dofs // 2
    columns = []
    for axis, coordinate in enumerate((node % (grid.shape[0] + 1), node // (grid.shape[0] + 1))):
        c = coordinate.astype(float)       # node index along the axis: the rotation is scale-free
        columns.append(c - c.mean())
    rx, ry = columns
    scale = max(np.ptp(rx), np.ptp(ry)) or 1.0
    component = dofs % 2
    R = np.zeros((len(dofs), 3))
    R[:, 0] = component == 0
    R[:, 1] = component == 1
    R[:, 2] = np.where(component == 0, -ry, rx) / scale
    return R


def free_modes(K: sp.spmatrix, grid: Grid, dofs: np.ndarray) -> list[str]:
    """Names of the rigid motions (or their combinations) that K leaves without stiffness."""
    R = rigid_modes(grid, dofs)
    G = R.T @ (K @ R)
    W = R.T @ (np.abs(K.diagonal())[:, None] * R)
    values, vectors = scipy.linalg.eigh(0.5 * (G + G.T), W)
    names = []
    for value, v in zip(values, vectors.T):
        if value < FREE_TOLERANCE:
            v = v / np.abs(v).max()
            parts = [f"{c:+.3g} {name}" for c, name in zip(v, ("translation x", "translation y", "rotation"))
                     if abs(c) > 1e-6]
            names.append(" ".join(parts))
    return names


def require_constrained(K: sp.spmatrix, grid: Grid, dofs: np.ndarray) -> None:
    """Raise SolveError naming a rigid-body motion that K leaves without stiffness."""
    free = free_modes(K, grid, dofs)
    if free:
        raise SolveError(f"rigid-body motion is not constrained ({free[0]}); "
                         "the body needs more essential boundaries")
