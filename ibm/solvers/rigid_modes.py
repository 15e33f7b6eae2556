"""Detect rigid-body motions left free by too few essential boundaries.

With nodal rigid modes R = [t_x, t_y, rotation] (n_dofs, 3), a free mode is a combination
v with R v in the null space: the generalized Rayleigh quotient of G = R^T K R against
W = R^T diag(K) R is ~ round-off. Constrained bodies give quotients many orders above it.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ibm.discretise.grid import Grid
from ibm.exceptions import SolveError

FREE_TOLERANCE = 1e-10


MODE_NAMES = {2: ("translation x", "translation y", "rotation"),
              3: ("translation x", "translation y", "translation z", "rotation about x",
                  "rotation about y", "rotation about z")}


def rigid_modes(grid: Grid, dofs: np.ndarray) -> np.ndarray:
    """(n_dofs, 3) in 2D, (n_dofs, 6) in 3D: translations along each axis and rotations about
    the active nodes' centre (MODE_NAMES)."""
    d = grid.dim
    node = dofs // d
    if d == 2:
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
    index = (grid.nodes()[node] - grid.origin) / grid.h        # node indices: the rotations are scale-free
    index -= index.mean(axis=0)
    scale = np.ptp(index, axis=0).max() or 1.0
    component = dofs % d
    R = np.zeros((len(dofs), 6))
    for a in range(3):
        R[:, a] = component == a
    for r, (a, b) in enumerate([(1, 2), (2, 0), (0, 1)]):      # rotation about axis r
        R[:, 3 + r] = np.where(component == a, -index[:, b], np.where(component == b, index[:, a], 0.0)) / scale
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
            parts = [f"{c:+.3g} {name}" for c, name in zip(v, MODE_NAMES[grid.dim])
                     if abs(c) > 1e-6]
            names.append(" ".join(parts))
    return names


def require_constrained(K: sp.spmatrix, grid: Grid, dofs: np.ndarray) -> None:
    """Raise SolveError naming a rigid-body motion that K leaves without stiffness."""
    free = free_modes(K, grid, dofs)
    if free:
        raise SolveError(f"rigid-body motion is not constrained ({free[0]}); "
                         "the body needs more essential boundaries")
