"""Tiny cut cells: node support and the extension remedy.

The support fraction of node I is s_I = int_Omega N_I dOmega / h^d (1 for a node whose 2^d
cells are full). A node with a sliver of support (s_I << 1) gives the system a near-null
direction: its shape function on the sliver is almost a combination of its neighbours'.
The remedy ties such a node to the nearest cell whose nodes are all well supported,
by bilinear extrapolation of that cell's interpolant:

    u_I = sum_J N_J^(cell)(x_I) u_J,     so u = T u_kept and K_kept = T^T K T.

Linear fields stay in the space (the extrapolation of a bilinear field is exact for them),
so patch tests still pass while the condition number returns to that of full cells.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ibm.discretise.assembly import GridMatrix, restrict
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid, lattice
from ibm.discretise.points import MaterialPoints


def support_fractions(grid: Grid, points: MaterialPoints) -> np.ndarray:
    """(n_nodes,) int_Omega N_I / h^d, by the material-point rule."""
    N, _ = grid.shape_functions(points.x, points.cells)
    nodes = grid.cell_nodes(points.cells)
    return np.bincount(nodes.ravel(), weights=(N * points.volume[:, None]).ravel(),
                       minlength=grid.n_nodes) / grid.h ** grid.dim


@dataclass(frozen=True, eq=False)
class Extension:
    """u_full = T @ u_kept over the DOFs; `extended` are the node ids that were tied."""

    T: sp.csr_matrix           # (n_dofs_in, n_dofs_kept)
    kept: np.ndarray           # DOF ids (into the input DOF list) that stay unknown
    extended: np.ndarray       # node ids tied to a neighbour cell
    min_support: float

    def reduce(self, K: sp.spmatrix | GridMatrix, f: np.ndarray,
               dofs: np.ndarray | None = None) -> tuple[sp.csr_matrix, np.ndarray]:
        """T^T K T and T^T f for a symmetric K, touching only the tied rows of K.

        T is the identity on the kept DOFs and E = T[tied] on the tied ones, so
        T^T K T = K_kk + K_tk^T E + E^T K_tk + E^T K_tt E (a general product costs ~10x more).
        K and f are over the active DOFs, or with `dofs` over the whole grid (one restriction
        instead of two). K may be a GridMatrix: its blocks are then taken straight from the slots.
        """
        n = self.T.shape[0]
        dofs = np.arange(n) if dofs is None else dofs
        is_kept = np.zeros(n, bool)
        is_kept[self.kept] = True
        kept, tied = dofs[self.kept], dofs[~is_kept]
        if isinstance(K, GridMatrix):
            block = K.tocsr
        else:
            K = sp.csr_matrix(K)

            def block(rows, columns):
                return restrict(K, rows) if rows is columns else K[rows][:, columns]
        reduced = block(kept, kept)
        if len(tied) == 0:
            return reduced, f[kept]
        E = self.T[np.flatnonzero(~is_kept)]                               # (n_tied, n_kept)
        K_tk, K_tt = block(tied, kept), block(tied, tied)
        coupling = K_tk.T @ E
        reduced = reduced + (coupling + coupling.T + E.T @ K_tt @ E)        # small terms first
        return sp.csr_matrix(reduced), f[kept] + E.T @ f[tied]


def _marked(ids: np.ndarray, n: int) -> np.ndarray:
    """Sorted distinct values of `ids` (in [0, n)): np.unique by marking, O(n) without sorting or hashing."""
    mark = np.zeros(n, bool)
    mark[ids] = True
    return np.flatnonzero(mark)


def _lonely_nodes(grid: Grid, points: MaterialPoints) -> np.ndarray:
    """Nodes that two or more share as the only material point they see, which is alone in its cell.

    One point constrains three strains, so two such nodes (four unknowns) always leave a
    zero-energy mode, whatever their support fraction (a body's corner poking into a cell
    whose upper neighbours are empty, at one point per cell). In 3D a point constrains six
    strains: three such nodes (nine unknowns) do.
    """
    least = 2 if grid.dim == 2 else 3
    nodes = grid.cell_nodes(points.cells)                                   # (n_points, 2^d)
    seen = np.bincount(nodes.ravel(), minlength=grid.n_nodes)               # points each node sees
    alone = np.bincount(points.cells, minlength=grid.n_cells)[points.cells] == 1
    mine = nodes[alone]                                                     # nodes of single-point cells
    only = seen[mine] == 1
    return np.unique(mine[only.sum(axis=1) >= least][only[only.sum(axis=1) >= least]])


WINDOW = 3.4   # cell centres outside a node's 6 x 6-cell window are >= 3.5 h away


def _cells_near(grid: Grid, nodes: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The `cells` whose centre lies within the 6^d-cell window around one of `nodes`."""
    shape = np.array(grid.shape)
    index = np.rint((grid.nodes()[nodes] - grid.origin) / grid.h).astype(int)     # (n, d) node indices
    mark = np.zeros(grid.n_cells, bool)
    for offset in lattice([np.arange(-3, 3)] * grid.dim):    # 6^d window offsets, vectorised over nodes
        c = index + offset
        inside = np.all((c >= 0) & (c < shape), axis=1)
        mark[grid.cell_index(c[inside])] = True
    return cells[mark[cells]]


def extension(grid: Grid, points: MaterialPoints, dofs: np.ndarray, threshold: float,
              fraction: np.ndarray | None = None) -> Extension:
    """Extension operator on the active DOFs `dofs` (sorted) for nodes with support < threshold.

    fraction (n_nodes,): the nodes' support fractions when the points' basis is not N at the
    points (GIMP: sum_p V_p S_vp / h^d); by default from N at the points.
    """
    if not (np.isfinite(threshold) and 0 <= threshold < 1):
        raise InputError(f"support threshold {threshold} is not allowed; it must be in [0, 1)")
    lonely = _lonely_nodes(grid, points) if fraction is None else np.zeros(0, int)
    fraction = support_fractions(grid, points) if fraction is None else fraction
    d = grid.dim
    active_nodes = _marked(dofs // d, grid.n_nodes)
    weak = active_nodes[fraction[active_nodes] < threshold]
    if len(lonely):
        weak = np.union1d(weak, np.intersect1d(lonely, active_nodes))
    min_support = float(fraction[active_nodes].min(initial=1.0))
    n = len(dofs)
    if len(weak) == 0:
        return Extension(sp.identity(n, format="csr"), np.arange(n), weak, min_support)
    # good cells: cells with material whose four nodes are all well supported
    cells = _marked(points.cells, grid.n_cells)
    is_weak = np.zeros(grid.n_nodes, bool)
    is_weak[weak] = True
    good = cells[~np.any(is_weak[grid.cell_nodes(cells)], axis=1)
                 & np.all(fraction[grid.cell_nodes(cells)] >= threshold, axis=1)]
    if len(good) == 0:
        raise InputError(f"support threshold {threshold} leaves no well-supported cell; lower it")
    node_x = grid.nodes()[weak]
    # All equidistant nearest host cells share the node equally: a tie broken by index
    # order would not commute with the grid's symmetries.
    k = min(1 << d, len(good))
    near = _cells_near(grid, weak, good)
    distance, nearest = cKDTree(grid.cell_corners(near) + grid.h / 2).query(node_x, k=min(k, len(near)))
    if len(near) < k or np.max(distance) > WINDOW * grid.h:   # a host beyond the window: search all
        near = good
        distance, nearest = cKDTree(grid.cell_corners(near) + grid.h / 2).query(node_x, k=k)
    distance, nearest = distance.reshape(len(weak), k), nearest.reshape(len(weak), k)
    good = near
    tied = distance <= distance[:, :1] * (1 + 1e-9) + 1e-12 * grid.h          # (n_weak, k)
    share = tied / tied.sum(axis=1, keepdims=True)
    host = good[nearest]                                                      # (n_weak, k)
    N, _ = grid.shape_functions(np.repeat(node_x, k, axis=0), host.ravel())
    corners = N.shape[1]
    N = (N.reshape(len(weak), k, corners) * share[:, :, None]).reshape(len(weak), corners * k)
    host_nodes = grid.cell_nodes(host.ravel()).reshape(len(weak), corners * k)     # extrapolation stencil

    position = -np.ones(d * grid.n_nodes, int)
    kept = np.flatnonzero(~is_weak[dofs // d])
    position[dofs[kept]] = np.arange(len(kept))
    if np.any(position[d * host_nodes] < 0):
        raise InputError("a host cell of an extended node lies outside the active DOFs")
    row_of = -np.ones(d * grid.n_nodes, int)
    row_of[dofs] = np.arange(n)
    rows = [row_of[dofs[kept]]]
    cols = [np.arange(len(kept))]
    vals = [np.ones(len(kept))]
    for component in range(d):     # u_I,c = sum_J N_J u_J,c
        rows.append(np.repeat(row_of[d * weak + component], host_nodes.shape[1]))
        cols.append(position[d * host_nodes + component].ravel())
        vals.append(N.ravel())
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, len(kept)))
    return Extension(T, kept, weak, min_support)
