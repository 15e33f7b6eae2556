"""Strain operators and sparse assembly of element blocks.

Voigt rows of the strain of nodal DOF (I, a) with the Dirichlet matrix D:
    Q[I, i, a, j] = d(N_I D_ia)/dx_j = D_ia dN_I/dx_j + N_I dD_ia/dx_j
    eps_xx = Q[0, a, 0], eps_yy = Q[1, a, 1], gamma_xy = Q[0, a, 1] + Q[1, a, 0]
Without D (D = I) this is the ordinary Q4 strain operator.

Sparse matrices are built straight into CSR from the structured grid: the DOF (I, a)
couples only to the DOFs (J, b) of the 3 x 3 nodes around I, so every row has 18 slots,
ordered by column. A block entry of a cell lands at (row, slot) with the slot read off a
fixed (8, 8) table; no (row, col) pairs are sorted (no COO round-trip).

The ordinary stiffness of many points in one cell only needs the cell's volume moments:
B is affine in the local coordinates (a, b) of a Q4 cell, B = B0 + a Ba + b Bb, so
sum_p V_p B^T C B = sum_k m_k K_k over the six moments m = sum V (1, a, b, a^2, a b, b^2).
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

from ibm.grid import Grid

# (i, j) offsets of a cell's local nodes, counter-clockwise from the lower-left (ibm.grid)
LOCAL_NODES = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])
SLOTS = 18   # row (I, a) -> columns (I + (dx, dy), b), dx, dy in {-1, 0, 1}, b in {0, 1}
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


def _slot_table() -> np.ndarray:
    """(8, 8) slot of block entry (2 l + a, 2 m + b) in row (node l, a): (dy + 1) 6 + (dx + 1) 2 + b."""
    d = LOCAL_NODES[None, :, :] - LOCAL_NODES[:, None, :] + 1          # (4, 4, 2): (dx+1, dy+1) of m from l
    slot_nodes = d[:, :, 1] * 3 + d[:, :, 0]                           # (4, 4)
    table = 2 * slot_nodes[:, None, :, None] + np.arange(2)[None, None, None, :]   # (l, a, m, b)
    return np.broadcast_to(table, (4, 2, 4, 2)).reshape(8, 8)


SLOT_TABLE = _slot_table()


def _present_slots() -> np.ndarray:
    """(16, 36) slots present in a node's two rows, by the node's code (bit l: the cell in
    which the node is local node l is occupied). Slot (dy + 1) 3 + (dx + 1) of the 3 x 3
    neighbours exists when some occupied cell holds both nodes."""
    table = np.zeros((16, 3, 3), bool)
    for code in range(16):
        for l in range(4):
            if code >> l & 1:
                for m in range(4):
                    dx, dy = LOCAL_NODES[m] - LOCAL_NODES[l]
                    table[code, dy + 1, dx + 1] = True
    return np.broadcast_to(table.reshape(16, 1, 9, 1), (16, 2, 9, 2)).reshape(16, 2 * SLOTS)


PRESENT_SLOTS = _present_slots()


def strain_matrix(N: np.ndarray, dN: np.ndarray, Dm: np.ndarray | None = None,
                  gradDm: np.ndarray | None = None) -> np.ndarray:
    """B (n, 3, 8) from N (n, 4), dN (n, 4, 2) and optionally D (n, 2, 2), grad D (n, 2, 2, 2)."""
    n = len(N)
    B = np.zeros((n, 3, 4, 2))
    if Dm is None:
        B[:, 0, :, 0] = dN[:, :, 0]
        B[:, 1, :, 1] = dN[:, :, 1]
        B[:, 2, :, 0] = dN[:, :, 1]
        B[:, 2, :, 1] = dN[:, :, 0]
        return B.reshape(n, 3, 8)    # column 2 I + a
    # Q[p, I, i, a, j] = D[p, i, a] dN[p, I, j] + N[p, I] gradD[p, i, a, j], read off row by row
    dx, dy = dN[:, :, None, 0], dN[:, :, None, 1]                     # (n, 4, 1)
    Nn = N[:, :, None]
    B[:, 0] = Dm[:, None, 0, :] * dx + Nn * gradDm[:, None, 0, :, 0]
    B[:, 1] = Dm[:, None, 1, :] * dy + Nn * gradDm[:, None, 1, :, 1]
    B[:, 2] = (Dm[:, None, 0, :] * dy + Dm[:, None, 1, :] * dx
               + Nn * (gradDm[:, None, 0, :, 1] + gradDm[:, None, 1, :, 0]))
    return B.reshape(n, 3, 8)


def shape_vector(N: np.ndarray, Dm: np.ndarray | None = None) -> np.ndarray:
    """Displacement operator Nv (n, 2, 8): u_i = sum_{I,a} N_I D_ia u_Ia."""
    if Dm is None:
        Nv = np.zeros((len(N), 2, 4, 2))
        Nv[:, 0, :, 0] = N
        Nv[:, 1, :, 1] = N
        return Nv.reshape(len(N), 2, 8)
    return (N[:, None, :, None] * Dm[:, :, None, :]).reshape(len(N), 2, 8)


def stiffness_blocks(B: np.ndarray, C: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Element blocks (n, 8, 8) = w B^T C B."""
    CB = np.matmul(C, B) * weight[:, None, None]                      # (n, 3, 8)
    return np.matmul(B.transpose(0, 2, 1), CB)


# --- structured CSR -------------------------------------------------------------------------

class GridMatrix:
    """Accumulates cell blocks into the 18-slot rows of the nodes of `cells`, then gives CSR.

    Storage: data (n_rows, 18) for the DOFs of the nodes of the given cells only, so a
    band or an edge costs what it touches, not the whole grid.
    """

    def __init__(self, grid: Grid, cells: np.ndarray):
        self.grid = grid
        nx, ny = grid.shape
        flags = np.zeros(grid.n_cells, np.uint8)
        flags[cells] = 1
        occupied = np.zeros((ny + 2, nx + 2), np.uint8)               # padded by one empty cell
        occupied[1:-1, 1:-1] = flags.reshape(ny, nx)
        # code of node (i, j): bit l set when the cell in which the node is local node l is occupied
        code = np.zeros((ny + 1, nx + 1), np.uint8)
        for l, (ox, oy) in enumerate(LOCAL_NODES):
            code |= occupied[1 - oy:ny + 2 - oy, 1 - ox:nx + 2 - ox] << l
        code = code.ravel()
        self.nodes = np.flatnonzero(code)                              # nodes of occupied cells
        rows = (2 * self.nodes[:, None] + np.arange(2)).ravel()        # (n_rows,) global DOF ids
        self.row_of = np.full(2 * grid.n_nodes, -1, np.int64)
        self.row_of[rows] = np.arange(len(rows))
        self.rows = rows
        self.mask = PRESENT_SLOTS[code[self.nodes]].reshape(len(rows), SLOTS)   # (n_rows, 18) slots that exist
        self.row_counts = np.repeat(PRESENT_SLOTS[:, :SLOTS].sum(axis=1)[code[self.nodes]], 2)   # (n_rows,)
        self.row_counts = np.repeat(PRESENT_SLOTS[:, :SLOTS].sum(axis=1)[code[self.nodes]], 2)   # (n_rows,)
        self.data = np.zeros(len(rows) * SLOTS)

    def add(self, cells: np.ndarray, blocks: np.ndarray) -> "GridMatrix":
        """Add blocks (n, 8, 8) of points (or cells) in `cells` (n,), all among the constructor's cells."""
        if len(cells) > CHUNK:   # many points per cell (bands): sum per cell first, scatter 64 per cell
            order = np.argsort(cells, kind="stable")
            cells = cells[order]
            first = np.flatnonzero(np.concatenate([[True], cells[1:] != cells[:-1]]))
            blocks = np.add.reduceat(blocks.reshape(len(cells), 64)[order], first, axis=0).reshape(-1, 8, 8)
            cells = cells[first]
        for start in range(0, len(cells), CHUNK):
            part = slice(start, start + CHUNK)
            base = self.row_of[self.grid.cell_dofs(cells[part])] * SLOTS          # (m, 8)
            position = base[:, :, None] + SLOT_TABLE[None]                        # (m, 8, 8)
            np.add.at(self.data, position.ravel(), blocks[part].ravel())
        return self

    def add_moments(self, moments: np.ndarray, C: np.ndarray) -> "GridMatrix":
        """Add the ordinary stiffness of cells with moments (n_cells, 6) (see cell_moments).

        Each node's two rows are one small product, moments of its four cells (24,) @
        stencil (24, 36): no per-point or per-entry scatter. Cells with moments must be
        among the constructor's cells.
        """
        grid = self.grid
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
        """(18,) global column of each slot relative to 2 I for the rows of node I."""
        nx = self.grid.shape[0]
        offsets = np.array([dy * (nx + 1) + dx for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
        return (2 * offsets[:, None] + np.arange(2)).ravel().astype(index)

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
        reach = (2 * (self.rows[rows] // 2)).astype(index)[:, None] + self._column_offsets(index)[None, :]
        if rows is source:
            return np.sum(self.mask[source] & (new_column.take(reach, mode="clip") >= 0), axis=1)
        lost = np.bincount(self.row_of[reach[self.mask[dropped]]], minlength=len(self.rows))
        return (self.row_counts - lost)[source]

    def tocsr(self, rows: np.ndarray | None = None, columns: np.ndarray | None = None) -> sp.csr_matrix:
        """A[rows][:, columns] as CSR, rows and columns sorted DOF ids (None: all 2 n_nodes).

        Straight from the slots, so selecting the final unknowns costs no more than the
        whole matrix (no second pass over a CSR); rows are filled in parallel blocks.
        Existing slots are stored (explicit zeros kept), columns sorted.
        """
        nx = self.grid.shape[0]
        n = 2 * self.grid.n_nodes
        index = np.int32 if n < 2**31 - 2 * SLOTS * (nx + 2) else np.int64
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
        slots = self.data.reshape(-1, SLOTS)
        contiguous = len(source) > 0 and source[-1] - source[0] == len(source) - 1

        def work(first: int, last: int) -> None:
            for start in range(first, last, CHUNK // 2):     # chunks keep the temporaries in cache
                stop = min(start + CHUNK // 2, last)
                # a slice is a view: no gathers of whole rows
                part = slice(source[start], source[stop - 1] + 1) if contiguous else source[start:stop]
                mask = self.mask[part]
                column = (2 * (self.rows[part] // 2)).astype(index)[:, None] + column_offsets[None, :]
                if new_column is not None:   # absent slots may point off the grid: clip, they are masked
                    column = new_column.take(column, mode="clip")
                    mask = mask & (column >= 0)
                begin, end = indptr[wanted[start]], indptr[wanted[stop - 1] + 1]
                data[begin:end] = slots[part][mask]
                indices[begin:end] = column[mask]

        in_parallel(work, len(source), CHUNK // 2)
        shape = (len(rows), n if columns is None else len(columns))
        A = sp.csr_matrix((data, indices, indptr), shape=shape)
        if nx < 2:   # the slot order is the column order only when a grid row has 3+ nodes
            A.sort_indices()
        A.has_sorted_indices = True
        return A


def assemble_matrix(grid: Grid, cells: np.ndarray, blocks: np.ndarray) -> sp.csr_matrix:
    """Sum the (n, 8, 8) blocks of points in `cells` into a (2 n_nodes)^2 CSR matrix."""
    return GridMatrix(grid, cells).add(cells, blocks).tocsr()


def assemble_vector(grid: Grid, cells: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """Sum the (n, 8) blocks of points in `cells` into a (2 n_nodes,) vector."""
    return np.bincount(grid.cell_dofs(cells).ravel(), weights=blocks.ravel(), minlength=2 * grid.n_nodes)


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
    """sum_p w_p B_p^T C B_p (ordinary Q4 operator): by cell moments, point by point in concentrated cells.

    Returns CSR, or adds into `matrix` (which must hold `cells`) and returns it.
    """
    target = GridMatrix(grid, cells) if matrix is None else matrix
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
    """(n, 3) engineering Voigt strain from a displacement gradient or strain tensor (n, 2, 2)."""
    out = np.empty((len(eps_tensor), 3))
    out[:, 0], out[:, 1] = eps_tensor[:, 0, 0], eps_tensor[:, 1, 1]
    out[:, 2] = eps_tensor[:, 0, 1] + eps_tensor[:, 1, 0]
    return out


def tensor(sigma_voigt: np.ndarray) -> np.ndarray:
    """(n, 2, 2) symmetric tensor from Voigt stresses (n, 3)."""
    s = sigma_voigt
    out = np.empty((len(s), 2, 2))
    out[:, 0, 0], out[:, 1, 1] = s[:, 0], s[:, 1]
    out[:, 0, 1] = out[:, 1, 0] = s[:, 2]
    return out
