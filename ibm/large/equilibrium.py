"""Internal force and consistent tangent of sets of integration points (one Newton iterate).

For a set of points with x_n-volumes V (n,), gradient operators G (n, d d, m) of their trial
field, states at the step start and (optionally) the lift's gradient:

    dF = I + G dU_local + grad du^a,   (sigma, a) = model.update(dF, state)
    f_int = sum_p V_p det dF  Gc^T sigma,       K = sum_p V_p det dF  Gc^T a Gc,   Gc = G dF^-1

The material points form one set; the IBM's band correction adds the band points twice,
with its Dirichlet kinematics (sign +1) and with plain kinematics (sign -1). A small-strain
model (ibm.large.kinematics.is_small) integrates with Gc = G and the volumes V as they are.
A set that carries its response linearised about the step start (`linear`: sigma_n and the
spatial tangent a_n at dF = I) takes the first-order expansion of the expressions above,

    f_int = sum_p V_p G^T (sigma_n + a_n grad du),   K = sum_p V_p G^T a_n G,

affine in dU (exact at dU = 0, where the tangents agree): the IBM's band in 3D (ibm.large.newton).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ibm.models.constitutive import Response, State
from ibm.large.kinematics import current_operator, increment, is_small, planar


@dataclass(frozen=True, eq=False)
class Blocks:
    """Points that share one DOF row (the points of one cell) have their tangent blocks summed
    before assembly: the tangent then has one triplet block per distinct row, not per point (the
    3D band has ~10^2 moment-fitted points per cell piece). dofs (g, m) the distinct rows; order
    and starts sort the points by row for np.add.reduceat."""

    order: np.ndarray
    starts: np.ndarray
    dofs: np.ndarray

    @classmethod
    def of(cls, dofs: np.ndarray) -> "Blocks":
        unique, inverse = np.unique(dofs, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        order = np.argsort(inverse, kind="stable")
        return cls(order, np.searchsorted(inverse[order], np.arange(len(unique))), unique)

    def sum(self, values: np.ndarray) -> np.ndarray:
        """(g, ...) sums over each row's points of per-point values (n, ...)."""
        return np.add.reduceat(values[self.order], self.starts, axis=0)


@dataclass(frozen=True, eq=False)
class PointSet:
    """Integration points of one kind: DOF ids (n, m), G (n, d d, m), volume (n,), state, sign."""

    dofs: np.ndarray
    G: np.ndarray
    volume: np.ndarray
    state: State
    lift_gradient: np.ndarray | None = None   # (n, d, d) grad du^a at the points this step
    sign: float = 1.0
    fbar: object = None                       # large strain: ibm.discretise.locking.CellGroups of the points (F-bar)
    blocks: Blocks | None = None              # points sharing DOF rows (their blocks summed); None: one per point
    linear: tuple | None = None               # (sigma_n (n, d d), a_n (n, d d, d d)): the step-start response, linearised
    part: np.ndarray | None = None            # (n,) the points' places in the whole set they were split from

    @cached_property
    def linear_block(self) -> np.ndarray:
        """(n, m, m) the tangent blocks of a linearised set, sign V G^T a_n G: the same at every iterate."""
        A = self.linear[1]
        return np.matmul(self.G.transpose(0, 2, 1), np.matmul(A, self.G)) * (self.sign * self.volume)[:, None, None]

    @property
    def block_dofs(self) -> np.ndarray:
        """(b, m) the DOF rows of the tangent's blocks."""
        return self.dofs if self.blocks is None else self.blocks.dofs

    def __len__(self) -> int:
        return len(self.volume)


def triplets(sets: list[PointSet]) -> tuple[np.ndarray, np.ndarray]:
    """Row and column DOF ids of the tangent's COO triplets, in the order of `evaluate`'s values."""
    rows, columns = [], []
    for points in sets:
        if len(points):
            dofs = points.block_dofs
            m = dofs.shape[1]
            rows.append(np.repeat(dofs, m, axis=1).ravel())
            columns.append(np.tile(dofs, (1, m)).ravel())
    if not rows:
        return np.zeros(0, int), np.zeros(0, int)
    return np.concatenate(rows), np.concatenate(columns)


@dataclass(frozen=True, eq=False)
class Evaluation:
    force: np.ndarray            # (n_dofs,) internal force
    magnitude: np.ndarray        # (n_dofs,) sum of |point contributions|: the forces' own size
    values: np.ndarray           # tangent triplet values (rows and columns: `triplets(sets)`)
    summed: list                 # (start, sums of |point blocks|) of the sets with row blocks
    responses: list[Response]    # one per set, for the update after convergence
    sets: list[PointSet]

    @property
    def absolute(self) -> np.ndarray:
        """Sum of |point contributions| of each triplet (for the rounding floor, asked for only when
        Newton stalls): |values| where a triplet is one point's, the kept sums where row blocks add
        several."""
        out = np.abs(self.values)
        for start, part in self.summed:
            out[start:start + len(part)] = part
        return out

    def tangent(self, n_dofs: int) -> sp.csr_matrix:
        rows, columns = triplets(self.sets)
        return sp.csr_matrix((self.values, (rows, columns)), shape=(n_dofs, n_dofs))


# Expanding every triplet by its rows and columns of T costs nr nc entries per triplet; where the
# tiny-cell extension ties nodes to many neighbours (a body one or two cells across: rows of T with
# ~30 entries), that is ~1000 entries per triplet, and the two sparse products T^T (K T) are cheaper.
EXPANSION_LIMIT = 4.0


@dataclass(frozen=True, eq=False)
class Products:
    """A = T^T (K T) by two sparse products, K from the kept triplets (their active rows and columns);
    `zeros` holds every entry the products can fill as an explicit zero, so that A's pattern stays the
    same at every iteration (a sparse product drops entries that cancel)."""

    T: sp.csr_matrix             # (n_active, n_reduced)
    kept: np.ndarray             # (k,) the triplets inside the active DOFs
    rows: np.ndarray             # (k,) their active rows
    columns: np.ndarray          # (k,) and columns
    zeros: sp.csr_matrix         # (n_reduced, n_reduced)

    @classmethod
    def of(cls, T: sp.csr_matrix, kept: np.ndarray, rows: np.ndarray, columns: np.ndarray) -> "Products":
        n = T.shape[0]
        magnitude = abs(T)
        K = sp.csr_matrix((np.ones(len(kept)), (rows, columns)), shape=(n, n))
        structure = sp.csr_matrix(magnitude.T @ (K @ magnitude))
        zeros = sp.csr_matrix((np.zeros(structure.nnz), structure.indices, structure.indptr), shape=structure.shape)
        return cls(T, kept, rows, columns, zeros)

    def matrix(self, values: np.ndarray) -> sp.csr_matrix:
        n = self.T.shape[0]
        K = sp.csr_matrix((values[self.kept], (self.rows, self.columns)), shape=(n, n))
        return pattern_sum(self.T.T @ (K @ self.T), self.zeros)


def unique_inverse(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """np.unique(key, return_inverse=True) for a long integer key (e,), by one stable argsort:
    the keys of a step's tangent come in runs (a point's block row by row, points cell by cell),
    which the stable sort's merging of runs takes at a fraction of the cost of np.unique's quicksort
    and its inverse."""
    order = np.argsort(key, kind="stable")
    ordered = key[order].astype(np.int64, copy=False)
    first = np.empty(len(key), bool)
    first[:1] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    unique = ordered[first]
    rank = np.cumsum(first, dtype=np.int64, out=ordered)       # the sorted keys' storage, no longer needed
    rank -= 1
    slot = np.empty(len(key), np.int64)
    slot[order] = rank
    return unique, slot


@dataclass(frozen=True, eq=False)
class ReducedPattern:
    """The sparsity of A = T^T K[active, active] T for one load step's point sets, built once so
    each Newton iteration assembles A by one bincount: A.data = bincount(slot, coefficient *
    values[triplet]) (T: (n_active, n_reduced), the tiny-cell extension and fixed-DOF removal).
    Where that expansion would hold more than EXPANSION_LIMIT entries per triplet, A is formed by
    sparse `products` instead (and the expansion's fields are None). A load step whose points use the
    last step's nodes takes the last step's pattern as it is (`of`'s previous)."""

    rows: np.ndarray             # (t,) the triplets' full DOF ids (for |K| |dU|)
    columns: np.ndarray
    size: int
    triplet: np.ndarray | None = None        # (e,) index of the triplet each expanded entry comes from
    slot: np.ndarray | None = None           # (e,) position of the entry in A.data
    coefficient: np.ndarray | None = None    # (e,) T_ra,i T_ca,j
    indptr: np.ndarray | None = None
    indices: np.ndarray | None = None
    products: Products | None = None
    active: np.ndarray | None = None         # what it was built from: the active DOFs,
    T: sp.csr_matrix | None = None           # the reduction (sorted indices)
    sources: tuple = ()                      # and each set's DOF rows (block_dofs)

    @classmethod
    def of(cls, sets: list[PointSet], active: np.ndarray, n_dofs: int, T: sp.csr_matrix,
           previous: "ReducedPattern | None" = None) -> "ReducedPattern":
        """The pattern of these sets; previous: a pattern of the same structure (`same_structure`),
        taken as it is where T's values are the same too."""
        T = sp.csr_matrix(T)
        T.sort_indices()
        if previous is not None and np.array_equal(T.data, previous.T.data):
            return previous
        rows, columns = triplets(sets)
        built = dict(active=active, T=T, sources=tuple(points.block_dofs for points in sets if len(points)))
        position = np.full(n_dofs, -1)
        position[active] = np.arange(len(active))
        ra, ca = position[rows], position[columns]
        kept = np.flatnonzero((ra >= 0) & (ca >= 0))
        start, data, indices = T.indptr, T.data, T.indices
        nr = start[ra[kept] + 1] - start[ra[kept]]
        nc = start[ca[kept] + 1] - start[ca[kept]]
        count = nr * nc
        size = T.shape[1]
        if count.sum() > EXPANSION_LIMIT * max(len(kept), 1):
            return cls(rows, columns, size, products=Products.of(T, kept, ra[kept], ca[kept]), **built)
        # most T rows are one entry (a DOF kept as it is): their triplets map to one entry each
        # without the expansion's repeats; the expanded entries' order does not matter to `matrix`
        single = count == 1
        one, many = kept[single], kept[~single]
        count, nc = count[~single], nc[~single]
        triplet = np.repeat(many, count)
        local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        width = np.repeat(nc, count)
        row_entry = np.concatenate([start[ra[one]], start[ra[triplet]] + local // width])
        column_entry = np.concatenate([start[ca[one]], start[ca[triplet]] + local % width])
        triplet = np.concatenate([one, triplet])
        key = indices[row_entry].astype(np.int64) * size + indices[column_entry]
        unique, slot = unique_inverse(key)
        indptr = np.searchsorted(unique, np.arange(size + 1, dtype=np.int64) * size)
        return cls(rows, columns, size, triplet, slot, data[row_entry] * data[column_entry], indptr,
                   (unique % size).astype(np.int32), **built)

    def same_structure(self, sets: list[PointSet], active: np.ndarray, T: sp.csr_matrix) -> bool:
        """Whether `sets`, `active` and T have this pattern's triplets and T's sparsity (so the reduced
        tangent has its pattern: PARDISO's analysis stands); T with sorted indices."""
        dofs = [points.block_dofs for points in sets if len(points)]
        return (len(dofs) == len(self.sources)
                and all(a.shape == b.shape and np.array_equal(a, b) for a, b in zip(dofs, self.sources))
                and np.array_equal(active, self.active) and T.shape == self.T.shape
                and np.array_equal(T.indptr, self.T.indptr) and np.array_equal(T.indices, self.T.indices))

    def sensitivity(self, absolute: np.ndarray, dU: np.ndarray) -> np.ndarray:
        """|K| |dU| (n_dofs,): how far rounding dU (relative eps) moves the internal forces;
        absolute: the triplets' sums of |point contributions| (Evaluation.absolute)."""
        return np.bincount(self.rows, absolute * np.abs(dU[self.columns]), minlength=len(dU))

    def matrix(self, values: np.ndarray) -> sp.csr_matrix:
        if self.products is not None:
            return self.products.matrix(values)
        data = np.bincount(self.slot, self.coefficient * values[self.triplet], minlength=len(self.indices))
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.size, self.size))


def pattern_sum(A: sp.spmatrix, W: sp.spmatrix) -> sp.csr_matrix:
    """A + W on the union of their patterns, entries that cancel to zero kept (scipy's sum drops
    them, and a tangent whose pattern changes between iterations costs PARDISO its reused
    analysis, ibm.solvers.linear.Reuse)."""
    A, W = sp.coo_matrix(A), sp.coo_matrix(W)
    total = sp.coo_matrix((np.concatenate([A.data, W.data]), (np.concatenate([A.row, W.row]),
                                                              np.concatenate([A.col, W.col]))), shape=A.shape)
    out = total.tocsr()       # sums duplicates, keeps explicit zeros
    out.sort_indices()
    return out


def split_by_columns(points: PointSet) -> list[PointSet]:
    """The set split into parts by the DOF columns its operator G uses (columns of G that are zero
    for a point are dropped from its part). A GIMP window is as wide as the widest domain of the
    step: one domain over three cells gives every point 16 nodes in 2D, though almost all need 4,
    and the tangent's triplets grow with the square of that. Each part keeps `part`, its points'
    places in `points` (responses are put back together by `merged`). Plain sets only (the material
    points): no lift, row blocks, linearised response or F-bar groups."""
    if any(x is not None for x in (points.lift_gradient, points.blocks, points.linear, points.fbar)):
        raise ValueError("split_by_columns takes a plain point set (no lift, row blocks, linear response or F-bar)")
    used = np.any(points.G != 0, axis=1)                                          # (n, m)
    patterns, which = np.unique(np.packbits(used, axis=1), axis=0, return_inverse=True)
    which = which.ravel()
    parts = []
    for k in range(len(patterns)):
        index = np.flatnonzero(which == k)
        columns = np.flatnonzero(used[index[0]])
        parts.append(PointSet(points.dofs[index][:, columns], points.G[index][:, :, columns], points.volume[index],
                              points.state.take(index), sign=points.sign, part=index))
    return parts


def merged(sets: list[PointSet], responses: list[Response], n: int) -> Response:
    """One response (n points) from the responses of the parts of a split set (their `part`s)."""
    pairs = [(points.part, response) for points, response in zip(sets, responses) if points.part is not None]
    if len(pairs) == 1:        # one part: all n points in order (a single pattern, or F-bar's one set)
        return pairs[0][1]
    first = pairs[0][1]

    def whole(pick):
        like = pick(first)
        out = np.empty((n,) + like.shape[1:], like.dtype)
        for index, response in pairs:
            out[index] = pick(response)
        return out

    state = State(whole(lambda r: r.state.F), whole(lambda r: r.state.be),
                  {key: whole(lambda r, key=key: r.state.internal[key]) for key in first.state.internal})
    return Response(whole(lambda r: r.sigma), whole(lambda r: r.tangent), state)


def _add(force, magnitude, values: list, summed: list, points: PointSet, local: np.ndarray,
         block: np.ndarray) -> None:
    """A set's nodal forces local (n, m) into force and magnitude (n_dofs,), its tangent blocks
    (n, m, m) to the triplet values (summed per DOF row if it has blocks, with their sums of
    |blocks| kept in `summed`)."""
    force += np.bincount(points.dofs.ravel(), local.ravel(), minlength=len(force))
    magnitude += np.bincount(points.dofs.ravel(), np.abs(local).ravel(), minlength=len(force))
    start = sum(len(v) for v in values)
    if points.blocks is None:
        values.append(block.ravel())
    else:
        values.append(points.blocks.sum(block).ravel())
        summed.append((start, points.blocks.sum(np.abs(block)).ravel()))


def evaluate(model, sets: list[PointSet], dU: np.ndarray) -> Evaluation:
    """f_int and the tangent triplets of all `sets` at the nodal increment dU (n_dofs,)."""
    force, magnitude = np.zeros(len(dU)), np.zeros(len(dU))
    values, summed, responses = [], [], []
    for points in sets:
        if len(points) == 0:
            responses.append(None)
            continue
        n, dd, m = points.G.shape
        d = int(round(np.sqrt(dd)))
        if points.linear is not None:      # affine: the response and geometry of the step start
            sigma, A = points.linear
            gradient = np.matmul(points.G, dU[points.dofs][:, :, None])[:, :, 0]
            if points.lift_gradient is not None:
                gradient = gradient + points.lift_gradient.reshape(n, dd)
            weight = points.sign * points.volume
            stress = sigma + np.matmul(A, gradient[:, :, None])[:, :, 0]
            local = np.matmul(stress[:, None, :], points.G)[:, 0] * weight[:, None]
            _add(force, magnitude, values, summed, points, local, points.linear_block)
            responses.append(None)
            continue
        dF = increment(points.G, dU[points.dofs], points.lift_gradient)
        if points.fbar is not None:   # F-bar: the stress of the cell's mean Jacobian (ibm.discretise.locking)
            J = np.linalg.det(dF[:, :d, :d])
            stressed = dF.copy()
            stressed[:, :d, :d] *= ((points.fbar.mean(J, points.volume) / J) ** (1 / d))[:, None, None]
        else:
            stressed = dF
        response = model.update(stressed, points.state, dim=d)          # the tangent's in-plane part in 2D
        responses.append(response)
        if is_small(model):           # the initial configuration throughout
            Gc, weight = points.G, points.sign * points.volume
        else:
            Gc = current_operator(points.G, dF)
            weight = points.sign * points.volume * np.linalg.det(dF[:, :d, :d])      # (n,) current volumes
        sigma = planar(response.sigma, d)                                            # (n, d d)
        local = np.matmul(sigma[:, None, :], Gc)[:, 0] * weight[:, None]             # (n, m)
        A = planar(response.tangent, d)                                              # (n, d d, d d)
        AG = np.matmul(A, Gc)
        if points.fbar is not None:   # + q (div_c - div_p), q = (a : I - (d - 1) sigma) / d
            trace = [i * d + i for i in range(d)]
            q = (A[:, :, trace].sum(axis=2) - (d - 1) * sigma) / d                   # (n, d d)
            own = Gc[:, trace].sum(axis=1)                                           # (n, m)
            AG = AG + q[:, :, None] * (points.fbar.mean_row(own, np.abs(weight)) - own)[:, None, :]
        block = np.matmul(Gc.transpose(0, 2, 1), AG) * weight[:, None, None]        # (n, m, m)
        _add(force, magnitude, values, summed, points, local, block)
    if not values:
        return Evaluation(force, magnitude, np.zeros(0), [], responses, sets)
    return Evaluation(force, magnitude, np.concatenate(values), summed, responses, sets)
