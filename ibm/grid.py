"""Structured background grid of bilinear quadrilaterals (Q4).

Nodes sit at (i h, j h) for integer i, j, so a grid is fixed by its cell size and the
index range it covers; shifting a body by whole cells shifts nothing else.
Local node order in a cell: (i, j), (i+1, j), (i+1, j+1), (i, j+1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.geometry import Body, InputError


@dataclass(frozen=True)
class Grid:
    h: float
    lower: tuple[int, int]   # integer index of the lowest-left node
    shape: tuple[int, int]   # number of cells (nx, ny)

    @classmethod
    def covering(cls, body: Body, h: float, margin: int = 1) -> "Grid":
        """The smallest grid holding the body's bounding box, plus `margin` cells around."""
        if not (np.isfinite(h) and h > 0):
            raise InputError(f"cell size h={h} is not allowed; it must be > 0")
        lo, hi = body.bounds()
        i0 = np.floor(lo / h).astype(int) - margin
        i1 = np.ceil(hi / h).astype(int) + margin
        return cls(h=float(h), lower=(int(i0[0]), int(i0[1])), shape=(int(i1[0] - i0[0]), int(i1[1] - i0[1])))

    @property
    def n_cells(self) -> int:
        return self.shape[0] * self.shape[1]

    @property
    def n_nodes(self) -> int:
        return (self.shape[0] + 1) * (self.shape[1] + 1)

    @property
    def origin(self) -> np.ndarray:
        return np.array(self.lower, float) * self.h

    def nodes(self) -> np.ndarray:
        """(n_nodes, 2) node coordinates, node id = j * (nx + 1) + i."""
        nx, ny = self.shape
        i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1))
        return self.origin + self.h * np.stack([i.ravel(), j.ravel()], axis=1)

    def cell_index(self, ij: np.ndarray) -> np.ndarray:
        """Cell ids of integer cell coordinates ij (n, 2) relative to `lower`."""
        return ij[:, 1] * self.shape[0] + ij[:, 0]

    def locate(self, x: np.ndarray) -> np.ndarray:
        """Cell id (n,) holding each point x (n, 2); points on a grid line go to the upper cell."""
        ij = np.floor((x - self.origin) / self.h).astype(int)
        outside = np.any((ij < 0) | (ij >= np.array(self.shape)), axis=1)
        if np.any(outside):
            bad = x[np.argmax(outside)]
            raise InputError(f"point ({bad[0]:.6g}, {bad[1]:.6g}) lies outside the grid")
        return self.cell_index(ij)

    def locate_towards(self, x: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """Cells of points x (n, 2) that lie on or near grid lines, taken on the side `direction`
        ((2,) or one per point (n, 2)) points to.

        The nudge is just above coordinate rounding: a point truly on a line goes to the
        chosen side, a point merely close to one stays in its own cell.
        """
        nudge = max(1e-12 * self.h, 64 * np.finfo(float).eps * float(np.abs(x).max(initial=0.0)))
        direction = np.asarray(direction, float)
        return self.locate(x + nudge * direction / np.linalg.norm(direction, axis=-1, keepdims=True))

    def cell_corners(self, cells: np.ndarray) -> np.ndarray:
        """(n, 2) lower-left corner of each cell."""
        nx = self.shape[0]
        return self.origin + self.h * np.stack([cells % nx, cells // nx], axis=1)

    def cell_nodes(self, cells: np.ndarray) -> np.ndarray:
        """(n, 4) node ids of each cell, counter-clockwise from the lower-left."""
        nx = self.shape[0]
        ci, cj = cells % nx, cells // nx
        n0 = cj * (nx + 1) + ci
        return np.stack([n0, n0 + 1, n0 + nx + 2, n0 + nx + 1], axis=1)

    def cell_dofs(self, cells: np.ndarray) -> np.ndarray:
        """(n, 8) DOF ids [2 I, 2 I + 1] of each cell's nodes, node-major."""
        nodes = self.cell_nodes(cells)
        return np.stack([2 * nodes, 2 * nodes + 1], axis=2).reshape(len(cells), 8)

    def shape_functions(self, x: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """N (n, 4) and dN/dx (n, 4, 2) of each point x (n, 2) in its cell."""
        a, b = ((x - self.cell_corners(cells)) / self.h).T
        N = np.stack([(1 - a) * (1 - b), a * (1 - b), a * b, (1 - a) * b], axis=1)
        dNa = np.stack([-(1 - b), 1 - b, b, -b], axis=1)
        dNb = np.stack([-(1 - a), -a, a, 1 - a], axis=1)
        return N, np.stack([dNa, dNb], axis=2) / self.h

    def cells_overlapping(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Ids of all cells meeting the box [lo, hi]."""
        i0 = np.clip(np.floor((lo - self.origin) / self.h).astype(int), 0, np.array(self.shape) - 1)
        i1 = np.clip(np.floor((hi - self.origin) / self.h).astype(int), 0, np.array(self.shape) - 1)
        ci, cj = np.meshgrid(np.arange(i0[0], i1[0] + 1), np.arange(i0[1], i1[1] + 1))
        return self.cell_index(np.stack([ci.ravel(), cj.ravel()], axis=1))
