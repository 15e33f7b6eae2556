"""Structured background grid of multilinear cells: bilinear quadrilaterals (Q4) in 2D,
trilinear hexahedra (H8) in 3D; the dimension is the length of `shape`.

Nodes sit at h times integer indices, so a grid is fixed by its cell size and the index
range it covers; shifting a body by whole cells shifts nothing else. Ids run with the first
index fastest: node (i, j, k) is i + (nx + 1) (j + (ny + 1) k), cell (i, j, k) is i + nx (j + ny k).
Local node order in a cell (LOCAL_NODES): (i, j), (i+1, j), (i+1, j+1), (i, j+1) in 2D,
and in 3D that square at k, then at k + 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.exceptions import InputError

LOCAL_NODES = {2: np.array([[0, 0], [1, 0], [1, 1], [0, 1]]),
               3: np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                            [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])}


def lattice(ranges) -> np.ndarray:
    """(n, d) integer points of the product of `ranges` (one 1D array per axis), first axis fastest."""
    axes = np.meshgrid(*reversed([np.asarray(r) for r in ranges]), indexing="ij")
    return np.stack([a.ravel() for a in reversed(axes)], axis=1)


@dataclass(frozen=True)
class Grid:
    """A background grid of square (cubic) cells of size h: the nodes lower .. lower + shape, in units of
    h, along each axis (2D or 3D); Grid.covering(body, h) is the one a body needs."""

    h: float
    lower: tuple[int, ...]   # integer index of the lowest node
    shape: tuple[int, ...]   # number of cells per axis (nx, ny[, nz])

    @classmethod
    def covering(cls, body, h: float, margin: int = 1) -> "Grid":
        """The smallest grid holding the body's bounding box, plus `margin` cells around."""
        if not (np.isfinite(h) and h > 0):
            raise InputError(f"cell size h={h} is not allowed; it must be > 0")
        lo, hi = body.bounds()
        i0 = np.floor(lo / h).astype(int) - margin
        i1 = np.ceil(hi / h).astype(int) + margin
        return cls(h=float(h), lower=tuple(int(v) for v in i0), shape=tuple(int(v) for v in i1 - i0))

    @property
    def dim(self) -> int:
        return len(self.shape)

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.shape))

    @property
    def n_nodes(self) -> int:
        return int(np.prod(np.array(self.shape) + 1))

    @property
    def local_nodes(self) -> np.ndarray:
        """(2^d, d) offsets of a cell's local nodes."""
        return LOCAL_NODES[self.dim]

    @property
    def origin(self) -> np.ndarray:
        return np.array(self.lower, float) * self.h

    def _strides(self, extra: int) -> np.ndarray:
        """(d,) id strides of the lattice with shape + extra points per axis."""
        return np.concatenate([[1], np.cumprod(np.array(self.shape[:-1]) + extra)]).astype(np.int64)

    def nodes(self) -> np.ndarray:
        """(n_nodes, d) node coordinates, in id order."""
        return self.origin + self.h * lattice([np.arange(n + 1) for n in self.shape])

    def cell_index(self, ij: np.ndarray) -> np.ndarray:
        """Cell ids of integer cell coordinates ij (n, d) relative to `lower`."""
        if self.dim == 2:
            return ij[:, 1] * self.shape[0] + ij[:, 0]
        return ij @ self._strides(0)

    def cell_coordinates(self, cells: np.ndarray) -> np.ndarray:
        """(n, d) integer coordinates of cell ids (the inverse of cell_index)."""
        if self.dim == 2:
            return np.stack([cells % self.shape[0], cells // self.shape[0]], axis=1)
        return (np.asarray(cells)[:, None] // self._strides(0)[None, :]) % np.array(self.shape)[None, :]

    def locate(self, x: np.ndarray) -> np.ndarray:
        """Cell id (n,) holding each point x (n, d); points on a grid line go to the upper cell."""
        ij = np.floor((x - self.origin) / self.h).astype(int)
        outside = np.any((ij < 0) | (ij >= np.array(self.shape)), axis=1)
        if np.any(outside):
            bad = x[np.argmax(outside)]
            raise InputError(f"point ({', '.join(f'{v:.6g}' for v in bad)}) lies outside the grid")
        return self.cell_index(ij)

    def locate_towards(self, x: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """Cells of points x (n, d) that lie on or near grid lines, taken on the side `direction`
        ((d,) or one per point (n, d)) points to.

        The nudge is just above coordinate rounding: a point truly on a line goes to the
        chosen side, a point merely close to one stays in its own cell.
        """
        nudge = max(1e-12 * self.h, 64 * np.finfo(float).eps * float(np.abs(x).max(initial=0.0)))
        direction = np.asarray(direction, float)
        return self.locate(x + nudge * direction / np.linalg.norm(direction, axis=-1, keepdims=True))

    def cell_corners(self, cells: np.ndarray) -> np.ndarray:
        """(n, d) lowest corner of each cell."""
        return self.origin + self.h * self.cell_coordinates(cells)

    def points_in_cells(self, cells: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """(n q, d) the points at offsets (q, d) from each cell's lowest corner, cell by cell."""
        return (self.cell_corners(cells)[:, None] + offsets[None]).reshape(-1, self.dim)

    def cell_nodes(self, cells: np.ndarray) -> np.ndarray:
        """(n, 2^d) node ids of each cell, in LOCAL_NODES order."""
        if self.dim == 2:
            nx = self.shape[0]
            ci, cj = cells % nx, cells // nx
            n0 = cj * (nx + 1) + ci
            return np.stack([n0, n0 + 1, n0 + nx + 2, n0 + nx + 1], axis=1)
        strides = self._strides(1)
        n0 = self.cell_coordinates(cells) @ strides
        return n0[:, None] + (self.local_nodes @ strides)[None, :]

    def cell_dofs(self, cells: np.ndarray) -> np.ndarray:
        """(n, 2^d d) DOF ids [d I + a] of each cell's nodes, node-major."""
        d = self.dim
        nodes = self.cell_nodes(cells)
        return (d * nodes[:, :, None] + np.arange(d)).reshape(len(cells), d << d)

    def shape_functions(self, x: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """N (n, 2^d) and dN/dx (n, 2^d, d) of each point x (n, d) in its cell."""
        if self.dim == 2:
            a, b = ((x - self.cell_corners(cells)) / self.h).T
            N = np.stack([(1 - a) * (1 - b), a * (1 - b), a * b, (1 - a) * b], axis=1)
            dNa = np.stack([-(1 - b), 1 - b, b, -b], axis=1)
            dNb = np.stack([-(1 - a), -a, a, 1 - a], axis=1)
            return N, np.stack([dNa, dNb], axis=2) / self.h
        t = ((x - self.cell_corners(cells)) / self.h).T                     # (d, n) local coordinates
        factor = np.stack([1 - t, t])                                         # (2, d, n): [upper, axis]
        offsets = self.local_nodes                                            # (k, d)
        axes = np.arange(self.dim)
        values = factor[offsets.T, axes[:, None]]                             # (d, k, n)
        N = np.prod(values, axis=0).T                                         # (n, k)
        sign = 2.0 * offsets - 1.0                                            # d(1 - t)/dt = -1, dt/dt = 1
        dN = np.empty((len(x), len(offsets), self.dim))
        for a in axes:
            others = np.prod(values[axes != a], axis=0)                       # (k, n)
            dN[:, :, a] = (sign[:, a, None] * others).T / self.h
        return N, dN

    def cells_overlapping(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Ids of all cells meeting the box [lo, hi]."""
        top = np.array(self.shape) - 1
        i0 = np.clip(np.floor((lo - self.origin) / self.h).astype(int), 0, top)
        i1 = np.clip(np.floor((hi - self.origin) / self.h).astype(int), 0, top)
        return self.cell_index(lattice([np.arange(a, b + 1) for a, b in zip(i0, i1)]))
