"""Strain operators and sparse assembly of element blocks, in 2D (Q4) and 3D (H8).

Voigt rows of the strain of nodal DOF (I, a) with the Dirichlet matrix D:
    Q[I, i, a, j] = d(N_I D_ia)/dx_j = D_ia dN_I/dx_j + N_I dD_ia/dx_j
    eps_ii = Q[i, a, i], gamma_ij = Q[i, a, j] + Q[j, a, i]
in the order of VOIGT: (xx, yy, xy) in 2D, (xx, yy, zz, xy, yz, zx) in 3D, engineering shears.
Without D (D = I) this is the ordinary multilinear strain operator.

Sparse matrices are built straight into CSR from the structured grid: the DOF (I, a)
couples only to the DOFs (J, b) of the 3^d nodes around I, so every row has 3^d d slots
(18 in 2D, 81 in 3D), ordered by column. A block entry of a cell lands at (row, slot) with
the slot read off a fixed table; no (row, col) pairs are sorted (no COO round-trip).

The ordinary stiffness of many points in one Q4 cell only needs the cell's volume moments:
B is affine in the local coordinates (a, b) of a Q4 cell, B = B0 + a Ba + b Bb, so
sum_p V_p B^T C B = sum_k m_k K_k over the six moments m = sum V (1, a, b, a^2, a b, b^2).
(In 3D B is not affine, trilinear cells are assembled point by point.)
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from ibm.discretise.grid import LOCAL_NODES as CELL_NODES, Grid

VOIGT = {2: ((0, 0), (1, 1), (0, 1)), 3: ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0))}
# (i, j) offsets of a Q4 cell's local nodes, counter-clockwise from the lower-left (ibm.discretise.grid)
LOCAL_NODES = CELL_NODES[2]
SLOTS = 18   # 2D: row (I, a) -> columns (I + (dx, dy), b), dx, dy in {-1, 0, 1}, b in {0, 1}
CHUNK = 1 << 13   # points (or rows) per chunk: keeps the (chunk, 8, 8) temporaries in cache
BLAS_ROWS = 1024  # rows per small matrix product: below BLAS's threading threshold (threads only add overhead)
# Threads for the row-parallel passes (numpy and BLAS release the GIL on these arrays);
# each writes its own rows, so results do not depend on the number of threads.
THREADS = max(1, min(4, os.cpu_count() or 1))


def in_parallel(work, n: int, step: int, threads: int | None = None) -> None:
    """Call work(start, stop) on [0, n) split into `threads` blocks of whole `step`s, one thread each."""
    threads = THREADS if threads is None else threads
    steps = -(-n // step)
    if threads <= 1 or steps < 2:
        work(0, n)
        return
    bounds = [min(n, step * (steps * k // threads)) for k in range(threads + 1)]
    blocks = [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    with ThreadPoolExecutor(len(blocks)) as pool:
        list(pool.map(lambda block: work(*block), blocks))   # list(): re-raises a worker's error


def slots(d: int) -> int:
    """Slots per row: 3^d neighbour nodes times d components."""
    return 3 ** d * d


def _neighbour(offset: np.ndarray) -> np.ndarray:
    """Neighbour slot node sum (o_a + 1) 3^a of node offsets (..., d) in {-1, 0, 1}: the first axis fastest."""
    return np.sum((offset + 1) * 3 ** np.arange(offset.shape[-1]), axis=-1)


@lru_cache(maxsize=None)
def slot_table(d: int) -> np.ndarray:
    """(k d, k d) slot of block entry (d l + a, d m + b) in row (node l, a), k = 2^d local nodes."""
    local = CELL_NODES[d]
    k = len(local)
    slot_nodes = _neighbour(local[None, :, :] - local[:, None, :])          # (k, k)
    table = d * slot_nodes[:, None, :, None] + np.arange(d)[None, None, None, :]   # (l, a, m, b)
    return np.ascontiguousarray(np.broadcast_to(table, (k, d, k, d)).reshape(k * d, k * d))


@lru_cache(maxsize=None)
def present_slots(d: int) -> np.ndarray:
    """(2^(2^d), d slots(d)) slots present in a node's d rows, by the node's code (bit l: the cell
    in which the node is local node l is occupied). A neighbour slot exists when some occupied
    cell holds both nodes."""
    local = CELL_NODES[d]
    k = len(local)
    codes = np.arange(1 << k)
    table = np.zeros((1 << k, 3 ** d), bool)
    for l in range(k):
        reach = _neighbour(local - local[l])                                  # (k,) slots cell l's nodes fill
        occupied = (codes >> l & 1).astype(bool)
        table[np.ix_(occupied, reach)] = True
    return np.broadcast_to(table[:, None, :, None], (1 << k, d, 3 ** d, d)).reshape(1 << k, d * slots(d))


SLOT_TABLE = slot_table(2)
PRESENT_SLOTS = present_slots(2)


def strain_matrix(N: np.ndarray, dN: np.ndarray, Dm: np.ndarray | None = None,
                  gradDm: np.ndarray | None = None) -> np.ndarray:
    """B (n, r, k d) from N (n, k), dN (n, k, d) and optionally D (n, d, d), grad D (n, d, d, d);
    r = 3 Voigt rows in 2D, 6 in 3D."""
    n, k, d = dN.shape
    B = np.zeros((n, len(VOIGT[d]), k, d))
    if Dm is None:
        for r, (i, j) in enumerate(VOIGT[d]):
            B[:, r, :, i] = dN[:, :, j]
            B[:, r, :, j] = dN[:, :, i]
        return B.reshape(n, len(VOIGT[d]), k * d)    # column d I + a
    # Q[p, I, i, a, j] = D[p, i, a] dN[p, I, j] + N[p, I] gradD[p, i, a, j], read off row by row
    Nn = N[:, :, None]
    for r, (i, j) in enumerate(VOIGT[d]):
        if i == j:
            B[:, r] = Dm[:, None, i, :] * dN[:, :, None, i] + Nn * gradDm[:, None, i, :, i]
        else:
            B[:, r] = (Dm[:, None, i, :] * dN[:, :, None, j] + Dm[:, None, j, :] * dN[:, :, None, i]
                       + Nn * (gradDm[:, None, i, :, j] + gradDm[:, None, j, :, i]))
    return B.reshape(n, len(VOIGT[d]), k * d)


def shape_vector(N: np.ndarray, Dm: np.ndarray | None = None) -> np.ndarray:
    """Displacement operator Nv (n, d, k d): u_i = sum_{I,a} N_I D_ia u_Ia; d = 2 without D."""
    n, k = N.shape
    if Dm is None:
        d = 2 if k == 4 else 3
        Nv = np.zeros((n, d, k, d))
        for a in range(d):
            Nv[:, a, :, a] = N
        return Nv.reshape(n, d, k * d)
    d = Dm.shape[1]
    return (N[:, None, :, None] * Dm[:, :, None, :]).reshape(n, d, k * d)


def stiffness_blocks(B: np.ndarray, C: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Element blocks (n, k d, k d) = w B^T C B."""
    CB = np.matmul(C, B) * weight[:, None, None]                      # (n, r, k d)
    return np.matmul(B.transpose(0, 2, 1), CB)


# --- structured CSR -------------------------------------------------------------------------

class GridMatrix:
    """Accumulates cell blocks into the 18-slot rows of the nodes of `cells`, then gives CSR.

    Storage: data (n_rows, 18) for the DOFs of the nodes of the given cells only, so a
    band or an edge costs what it touches, not the whole grid.
    """

    def __init__(self, grid: Grid, cells: np.ndarray):
        self.grid = grid
        d = self.dim = grid.dim
        self.slots = slots(d)
        self.table = slot_table(d)
        shape = tuple(reversed(grid.shape))                            # (nz,) ny, nx: array axes
        flags = np.zeros(grid.n_cells, np.uint8)
        flags[cells] = 1
        occupied = np.zeros(tuple(n + 2 for n in shape), np.uint8)     # padded by one empty cell
        occupied[(slice(1, -1),) * d] = flags.reshape(shape)
        # code of a node: bit l set when the cell in which the node is local node l is occupied
        code = np.zeros(tuple(n + 1 for n in shape), np.uint8)
        for l, offset in enumerate(CELL_NODES[d]):
            code |= occupied[tuple(slice(1 - o, n + 2 - o) for o, n in zip(reversed(offset), shape))] << l
        code = code.ravel()
        self.nodes = np.flatnonzero(code)                              # nodes of occupied cells
        rows = (d * self.nodes[:, None] + np.arange(d)).ravel()        # (n_rows,) global DOF ids
        self.row_of = np.full(d * grid.n_nodes, -1, np.int64)
        self.row_of[rows] = np.arange(len(rows))
        self.rows = rows
        present = present_slots(d)
        self.mask = present[code[self.nodes]].reshape(len(rows), self.slots)   # (n_rows, slots) that exist
        self.row_counts = np.repeat(present[:, :self.slots].sum(axis=1)[code[self.nodes]], d)   # (n_rows,)
        self.data = np.zeros(len(rows) * self.slots)

    def add(self, cells: np.ndarray, blocks: np.ndarray) -> "GridMatrix":
        """Add blocks (n, k d, k d) of points (or cells) in `cells` (n,), all among the constructor's cells."""
        size = blocks.shape[1]
        # many points per cell (bands), or 3D (coloured scatter of distinct cells): sum per cell first
        if len(cells) > CHUNK or (self.dim == 3 and len(np.unique(cells)) < len(cells)):
            order = np.argsort(cells, kind="stable")
            cells = cells[order]
            first = np.flatnonzero(np.concatenate([[True], cells[1:] != cells[:-1]]))
            blocks = np.add.reduceat(blocks.reshape(len(cells), size * size)[order], first, axis=0)
            blocks = blocks.reshape(-1, size, size)
            cells = cells[first]
        if self.dim == 3:
            return self._add_by_colour(cells, blocks)
        for start in range(0, len(cells), CHUNK):
            part = slice(start, start + CHUNK)
            base = self.row_of[self.grid.cell_dofs(cells[part])] * self.slots     # (m, 8)
            position = base[:, :, None] + self.table[None]                        # (m, 8, 8)
            np.add.at(self.data, position.ravel(), blocks[part].ravel())
        return self

    def _add_by_colour(self, cells: np.ndarray, blocks: np.ndarray) -> "GridMatrix":
        """Scatter blocks of distinct cells (n,) colour by colour: cells whose integer coordinates
        have the same parities share no node, so their positions are distinct and a plain
        indexed += is exact (np.add.at, which allows repeats, is many times slower)."""
        parity = self.grid.cell_coordinates(cells) % 2 @ (1 << np.arange(self.dim))   # (n,) colour 0 .. 2^d - 1
        for colour in range(1 << self.dim):
            mine = np.flatnonzero(parity == colour)
            for start in range(0, len(mine), CHUNK):
                part = mine[start:start + CHUNK]
                base = self.row_of[self.grid.cell_dofs(cells[part])] * self.slots   # (m, 24)
                position = (base[:, :, None] + self.table[None]).ravel()             # (m 24 24,)
                self.data[position] += blocks[part].ravel()
        return self

    def add_moments(self, moments: np.ndarray, C: np.ndarray) -> "GridMatrix":
        """Add the ordinary stiffness of cells with moments (n_cells, 6) (see cell_moments).

        Each node's two rows are one small product, moments of its four cells (24,) @
        stencil (24, 36): no per-point or per-entry scatter. Cells with moments must be
        among the constructor's cells.
        """
        grid = self.grid
        if self.dim != 2:
            raise ValueError("cell moments assemble Q4 cells only (2D)")
        nx, ny = grid.shape
        padded = np.zeros((ny + 2, nx + 2, 6))                         # moments, with one empty cell around
        for k in range(6):                                             # moment by moment: contiguous reads
            padded[1:-1, 1:-1, k] = moments[:, k].reshape(ny, nx)
        padded = padded.reshape(-1, 6)
        # the cell in which node (i, j) is local node l sits at padded (j + 1 - oy, i + 1 - ox)
        offsets = np.array([-(oy * (nx + 2) + ox) for ox, oy in LOCAL_NODES])
        stencil = moment_stencil(grid.h, C)
        data = self.data.reshape(-1, 2 * SLOTS)                        # (n_nodes_used, 36)

        def work(first: int, last: int) -> None:
            for start in range(first, last, CHUNK // 2):               # chunks keep temporaries in cache
                stop = min(start + CHUNK // 2, last)
                node = self.nodes[start:stop]
                base = (node // (nx + 1) + 1) * (nx + 2) + node % (nx + 1) + 1
                around = padded[base[:, None] + offsets[None, :]].reshape(len(node), 24)   # (m, 24)
                for sub in range(0, len(node), BLAS_ROWS):
                    data[start + sub:start + min(sub + BLAS_ROWS, len(node))] += around[sub:sub + BLAS_ROWS] @ stencil

        in_parallel(work, len(self.nodes), CHUNK // 2)
        return self

    def _column_offsets(self, index) -> np.ndarray:
        """(slots,) global column of each slot relative to d I for the rows of node I."""
        d = self.dim
        strides = np.concatenate([[1], np.cumprod(np.array(self.grid.shape[:-1]) + 1)])
        neighbours = np.stack(np.meshgrid(*([np.arange(-1, 2)] * d), indexing="ij")[::-1], axis=-1).reshape(-1, d)
        offsets = neighbours @ strides                                 # slot node order: first axis fastest
        return (d * offsets[:, None] + np.arange(d)).ravel().astype(index)

    def _counts(self, source: np.ndarray, new_column: np.ndarray | None, index) -> np.ndarray:
        """(len(source),) stored entries of the stored rows `source` once columns with new_column < 0 are dropped.

        Few rows: counted directly. Many: the slot pattern is symmetric (two nodes share an
        occupied cell or not), so row r loses one entry for each dropped row whose slots
        reach r, and only the dropped rows are read.
        """
        if new_column is None:
            return self.row_counts[source]
        dropped = np.flatnonzero(new_column[self.rows] < 0)
        rows = source if len(source) <= len(dropped) else dropped
        reach = (self.dim * (self.rows[rows] // self.dim)).astype(index)[:, None] + self._column_offsets(index)[None, :]
        if rows is source:
            return np.sum(self.mask[source] & (new_column.take(reach, mode="clip") >= 0), axis=1)
        lost = np.bincount(self.row_of[reach[self.mask[dropped]]], minlength=len(self.rows))
        return (self.row_counts - lost)[source]

    def tocsr(self, rows: np.ndarray | None = None, columns: np.ndarray | None = None) -> sp.csr_matrix:
        """A[rows][:, columns] as CSR, rows and columns sorted DOF ids (None: all d n_nodes).

        Straight from the slots, so selecting the final unknowns costs no more than the
        whole matrix (no second pass over a CSR); rows are filled in parallel blocks.
        Existing slots are stored (explicit zeros kept), columns sorted.
        """
        d = self.dim
        n = d * self.grid.n_nodes
        reach = int(np.prod(np.array(self.grid.shape[:-1]) + 2))     # nodes between a row and its farthest column
        index = np.int32 if n < 2**31 - d * self.slots * reach else np.int64
        rows = np.arange(n) if rows is None else np.asarray(rows)
        new_column = None
        if columns is not None:
            new_column = np.full(n, -1, index)
            new_column[columns] = np.arange(len(columns), dtype=index)
        column_offsets = self._column_offsets(index)
        source = self.row_of[rows]                          # stored row of each wanted row, -1: none
        wanted = np.flatnonzero(source >= 0)
        source = source[wanted]
        counts = np.zeros(len(rows) + 1, np.int64)
        counts[1 + wanted] = self._counts(source, new_column, index)
        indptr = np.cumsum(counts)
        data, indices = np.empty(indptr[-1]), np.empty(indptr[-1], index)
        slots = self.data.reshape(-1, self.slots)
        contiguous = len(source) > 0 and source[-1] - source[0] == len(source) - 1

        def work(first: int, last: int) -> None:
            for start in range(first, last, CHUNK // 2):     # chunks keep the temporaries in cache
                stop = min(start + CHUNK // 2, last)
                # a slice is a view: no gathers of whole rows
                part = slice(source[start], source[stop - 1] + 1) if contiguous else source[start:stop]
                mask = self.mask[part]
                column = (d * (self.rows[part] // d)).astype(index)[:, None] + column_offsets[None, :]
                if new_column is not None:   # absent slots may point off the grid: clip, they are masked
                    column = new_column.take(column, mode="clip")
                    mask = mask & (column >= 0)
                begin, end = indptr[wanted[start]], indptr[wanted[stop - 1] + 1]
                data[begin:end] = slots[part][mask]
                indices[begin:end] = column[mask]

        in_parallel(work, len(source), CHUNK // 2)
        shape = (len(rows), n if columns is None else len(columns))
        A = sp.csr_matrix((data, indices, indptr), shape=shape)
        if min(self.grid.shape[:-1]) < 2:   # the slot order is the column order only when a grid row has 3+ nodes
            A.sort_indices()
        A.has_sorted_indices = True
        return A


def assemble_matrix(grid: Grid, cells: np.ndarray, blocks: np.ndarray) -> sp.csr_matrix:
    """Sum the (n, k d, k d) blocks of points in `cells` into a (d n_nodes)^2 CSR matrix."""
    return GridMatrix(grid, cells).add(cells, blocks).tocsr()


def assemble_vector(grid: Grid, cells: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """Sum the (n, k d) blocks of points in `cells` into a (d n_nodes,) vector."""
    return np.bincount(grid.cell_dofs(cells).ravel(), weights=blocks.ravel(), minlength=grid.dim * grid.n_nodes)


# --- ordinary stiffness by cell moments ----------------------------------------------------

def moment_basis(h: float, C: np.ndarray) -> np.ndarray:
    """(6, 8, 8) matrices K_k with sum_p V_p B_p^T C B_p = sum_k m_k K_k, m = sum V (1, a, b, a^2, ab, b^2)."""
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]) * h            # (a, b) = (0,0), (1,0), (0,1)
    N, dN = Grid(h, (0, 0), (1, 1)).shape_functions(x, np.zeros(3, int))
    B = strain_matrix(N, dN)                                          # (3, 3, 8)
    B0, Ba, Bb = B[0], B[1] - B[0], B[2] - B[0]

    def sym(P, Q):
        return P.T @ C @ Q + Q.T @ C @ P

    return np.stack([B0.T @ C @ B0, sym(B0, Ba), sym(B0, Bb), Ba.T @ C @ Ba, sym(Ba, Bb), Bb.T @ C @ Bb])


def cell_moments(grid: Grid, x: np.ndarray, weight: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Moments (n_cells, 6) = sum w (1, a, b, a^2, a b, b^2) of the points of every cell, a, b local coordinates.

    Stored moment by moment (the transpose of a (6, n_cells) array), so each moment is contiguous.
    """
    nx = grid.shape[0]
    a = (x[:, 0] - grid.origin[0]) / grid.h - cells % nx
    b = (x[:, 1] - grid.origin[1]) / grid.h - cells // nx
    wa, wb = weight * a, weight * b
    moments = np.empty((6, grid.n_cells))
    for k, term in enumerate((weight, wa, wb, wa * a, wa * b, wb * b)):
        moments[k] = np.bincount(cells, term, minlength=grid.n_cells)
    return moments.T


def moment_stencil(h: float, C: np.ndarray) -> np.ndarray:
    """S (24, 36): the two rows (36 = 2 x 18 slots) of a node from the moments (4 x 6) of its four cells.

    Row 6 l + k holds the moment k of the cell in which the node is local node l.
    """
    K = moment_basis(h, C)                                             # (6, 8, 8)
    S = np.zeros((4, 6, 2, SLOTS))
    for l in range(4):
        for a in range(2):
            S[l, :, a, SLOT_TABLE[2 * l + a]] = K[:, 2 * l + a, :].T
    return S.reshape(24, 2 * SLOTS)


def concentrated_cells(moments: np.ndarray, tolerance: float = 1e-3) -> np.ndarray:
    """(n_cells,) bool: cells whose points crowd an edge of the cell.

    There a moment combination such as sum V (1 - a)^2 = m0 - 2 m_a + m_aa is much smaller
    than m0 and would lose its relative accuracy to cancellation; such cells (slivers of cut
    cells) are assembled point by point instead. Elsewhere the moments lose at most a factor
    1 / tolerance of relative accuracy in the smallest entries.
    """
    m0, ma, mb, maa, mab, mbb = moments.T
    limit = tolerance * m0
    crowded = m0 > 0
    near_edge = maa < limit
    for weight in (m0 - 2 * ma + maa, ma - maa, mbb, m0 - 2 * mb + mbb, mb - mbb):
        near_edge |= weight < limit
    return crowded & near_edge


def point_stiffness(grid: Grid, x: np.ndarray, weight: np.ndarray, cells: np.ndarray,
                    C: np.ndarray, matrix: GridMatrix | None = None) -> GridMatrix | sp.csr_matrix:
    """sum_p w_p B_p^T C B_p (ordinary multilinear operator): in 2D by cell moments, point by point
    in concentrated cells; in 3D point by point, in chunks.

    Returns CSR, or adds into `matrix` (which must hold `cells`) and returns it.
    """
    target = GridMatrix(grid, cells) if matrix is None else matrix
    if grid.dim == 3:
        order = np.argsort(cells, kind="stable")            # chunks of whole cells: the sums per cell stay whole
        for start in range(0, len(order), CHUNK):
            part = order[start:start + CHUNK]
            N, dN = grid.shape_functions(x[part], cells[part])
            target.add(cells[part], stiffness_blocks(strain_matrix(N, dN), C, weight[part]))
        return target.tocsr() if matrix is None else target
    moments = cell_moments(grid, x, weight, cells)
    concentrated = concentrated_cells(moments)
    if np.any(concentrated):
        moments[concentrated] = 0.0
        mine = concentrated[cells]
        N, dN = grid.shape_functions(x[mine], cells[mine])
        target.add(cells[mine], stiffness_blocks(strain_matrix(N, dN), C, weight[mine]))
    target.add_moments(moments, C)
    return target.tocsr() if matrix is None else target


def restrict(A: sp.csr_matrix, dofs: np.ndarray) -> sp.csr_matrix:
    """A[dofs][:, dofs] for sorted unique `dofs`; fast when every entry of A lies in those rows and columns."""
    A = sp.csr_matrix(A)
    n = A.shape[0]
    keep = np.zeros(n, bool)
    keep[dofs] = True
    counts = np.diff(A.indptr)
    new = np.cumsum(keep) - 1                                         # old -> new index where kept
    if np.any(counts[~keep]) or not np.all(keep[A.indices]):
        # keep the entries whose row and column are kept: one gather, one compress, O(nnz)
        # (scipy's A[dofs][:, dofs] takes several times longer on a 500k-row matrix)
        valid = keep[A.indices]
        removed = np.flatnonzero(~keep & (counts > 0))
        if len(removed):
            lengths = counts[removed]
            span = np.arange(lengths.sum()) + np.repeat(A.indptr[removed] - np.cumsum(lengths) + lengths, lengths)
            valid[span] = False
        running = np.concatenate([[0], np.cumsum(valid)])
        per_row = running[A.indptr[1:]] - running[A.indptr[:-1]]
        indptr = np.concatenate([[0], np.cumsum(per_row[dofs])])
        B = sp.csr_matrix((A.data[valid], new[A.indices[valid]], indptr), shape=(len(dofs), len(dofs)))
        B.has_sorted_indices = A.has_sorted_indices
        return B
    indptr = np.concatenate([[0], A.indptr[dofs + 1]])
    B = sp.csr_matrix((A.data, new[A.indices], indptr), shape=(len(dofs), len(dofs)))
    B.has_sorted_indices = A.has_sorted_indices
    return B


# --- Voigt helpers ---------------------------------------------------------------------------

def voigt(eps_tensor: np.ndarray) -> np.ndarray:
    """(n, r) engineering Voigt strain from a displacement gradient or strain tensor (n, d, d)."""
    pairs = VOIGT[eps_tensor.shape[1]]
    out = np.empty((len(eps_tensor), len(pairs)))
    for r, (i, j) in enumerate(pairs):
        out[:, r] = eps_tensor[:, i, i] if i == j else eps_tensor[:, i, j] + eps_tensor[:, j, i]
    return out


def tensor(sigma_voigt: np.ndarray) -> np.ndarray:
    """(n, d, d) symmetric tensor from Voigt stresses (n, r)."""
    s = sigma_voigt
    d = 2 if s.shape[1] == 3 else 3
    out = np.empty((len(s), d, d))
    for r, (i, j) in enumerate(VOIGT[d]):
        out[:, i, j] = out[:, j, i] = s[:, r]
    return out
