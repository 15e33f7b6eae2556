"""Linear solves on the DOFs that have support, with checks instead of garbage answers.

solve_system equilibrates symmetrically, picks the factorization from the matrix's
structure (SPD -> Cholesky, symmetric with a zero block -> symmetric indefinite,
otherwise LU) and the backend from `solver` (ibm.solvers.backends), and checks the residual.
"""
from __future__ import annotations

from time import perf_counter

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ibm.solvers import backends as solvers
from ibm.solvers.backends import row_ids
from ibm.exceptions import FactorizationError, SolveError

# Above this many unknowns the condition estimate is skipped unless asked for with
# condition_limit=None (info["cond_est"] is then NaN): its ~10 extra solves cost about as
# much as the factorization itself at 80k unknowns.
CONDITION_LIMIT = 50_000



def active_dofs(grid, *cell_sets: np.ndarray) -> np.ndarray:
    """Sorted DOF ids of the nodes of all cells that hold quadrature points."""
    occupied = np.zeros(grid.n_cells, bool)
    for cells in cell_sets:
        occupied[cells] = True
    nodes = np.zeros(grid.n_nodes, bool)
    nodes[grid.cell_nodes(np.flatnonzero(occupied)).ravel()] = True
    ids = np.flatnonzero(nodes)
    return (grid.dim * ids[:, None] + np.arange(grid.dim)).ravel()


def factorize(A, solver: str = "superlu", structure: str = "general", upper=None, near_null=None,
              allow_perturbed: bool = False):
    """Factorization with .solve(b, transpose=False); raises SolveError when A is singular.

    A: the matrix, or a callable returning it (see ibm.solvers.backends.factorize, also for `upper`)."""
    try:
        return solvers.factorize(A, structure, solver, upper, near_null, allow_perturbed)
    except FactorizationError as error:
        if solver == "amg":
            raise SolveError(str(error)) from None
        raise SolveError(f"the system matrix is singular ({error}); check the essential boundaries") from None


def rigid_modes(positions: np.ndarray) -> np.ndarray:
    """The rigid-body modes of unknowns ordered [x_0, y_0, (z_0,) x_1, ...] at node positions
    (n, d): (2 n, 3) in 2D (two translations, a rotation), (3 n, 6) in 3D (three of each),
    the near-null space AMG is told about."""
    n, d = positions.shape
    centred = positions - positions.mean(axis=0)
    modes = np.zeros((d * n, 3 * (d - 1)))
    for a in range(d):
        modes[a::d, a] = 1.0
    # rotation about axis c moves component a by -x_b and b by x_a, (a, b, c) cyclic
    rotations = [(0, 1)] if d == 2 else [(1, 2), (2, 0), (0, 1)]
    for r, (a, b) in enumerate(rotations):
        modes[a::d, d + r], modes[b::d, d + r] = -centred[:, b], centred[:, a]
    return modes


def condition_estimate(A: sp.spmatrix, lu) -> float:
    """1-norm condition estimate ||A||_1 ||A^-1||_1 (Hager-Higham) with a factorization of A."""
    n = A.shape[0]
    if hasattr(lu, "backend"):
        def solve(y, transpose=False):
            return lu.solve(y, transpose=transpose)
    else:   # a scipy SuperLU object
        def solve(y, transpose=False):
            return lu.solve(y, trans="T" if transpose else "N")
    inverse = spla.LinearOperator((n, n), matvec=solve, matmat=solve,
                                  rmatvec=lambda y: solve(y, True), rmatmat=lambda y: solve(y, True),
                                  dtype=float)
    # onenormest draws from numpy's global generator: run it from a fixed state, so the same
    # system always gets the same estimate, and give the caller its own state back.
    state = np.random.get_state()
    np.random.seed(0)
    try:
        return float(spla.onenormest(sp.csr_matrix(A), t=2) * spla.onenormest(inverse, t=2))
    finally:
        np.random.set_state(state)


def equilibrate(A: sp.spmatrix) -> np.ndarray:
    """Symmetric scaling s (n,) with (S A S) having unit largest entry per row, S = diag(s).

    Nodes with tiny support (small cut cells) have tiny rows; scaling removes that
    artificial part of the conditioning without changing the solution.
    """
    A = sp.csr_matrix(A)
    row_max = np.zeros(A.shape[0])
    filled = np.diff(A.indptr) > 0
    if A.nnz:
        row_max[filled] = np.maximum.reduceat(np.abs(A.data), A.indptr[:-1][filled])
    return 1.0 / np.sqrt(np.where(row_max > 0, row_max, 1.0))


def scaled(A: sp.csr_matrix, scale: np.ndarray) -> sp.csr_matrix:
    """S A S for S = diag(scale), same pattern (explicit zeros kept)."""
    As = sp.csr_matrix((A.data * scale[row_ids(A)] * scale[A.indices], A.indices, A.indptr), shape=A.shape)
    As.has_sorted_indices = A.has_sorted_indices
    return As


def structures_to_try(A: sp.csr_matrix, diagonal: np.ndarray, symmetric: bool = False) -> list[str]:
    """Factorizations to try in turn, cheapest first; the residual check decides.

    A symmetric-looking matrix with a positive diagonal is tried as SPD (Cholesky), then as
    symmetric indefinite; anything that fails those (or is clearly non-symmetric) gets LU.
    symmetric=True: the caller knows A is symmetric, no probe.
    """
    if not symmetric and not solvers.looks_symmetric(A):
        return ["general"]
    return (["spd"] if np.all(diagonal > 0) else []) + ["symmetric", "general"]


class Reuse:
    """Keeps the last PARDISO factorization of a sequence of solves (Newton's iterations) so that
    a matrix of the same pattern and structure is only refactored numerically (phase 22), its
    ordering and symbolic factorization reused. Use as a context manager (frees the factors)."""

    def __init__(self):
        self.factors = None
        self.reused = 0

    def take(self, upper, structure: str):
        """The kept factors refactored for `upper`, or None (another pattern or structure: new ones)."""
        kept, self.factors = self.factors, None
        if kept is None or upper is None or kept.structure != structure or not kept.same_pattern(upper):
            if kept is not None:
                kept.free()
            return None
        try:
            kept.refactor(upper)
        except FactorizationError:
            return None
        self.reused += 1
        return kept

    def keep(self, factors) -> bool:
        if getattr(factors, "backend", None) != "pardiso":
            return False
        if self.factors is not None and self.factors is not factors:
            self.factors.free()
        self.factors = factors
        return True

    def free(self) -> None:
        if self.factors is not None:
            self.factors.free()
            self.factors = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


def solve_system(A: sp.spmatrix, b: np.ndarray, estimate_condition: bool = True,
                 tolerance: float = 1e-8, solver: str | None = None, structure: str | None = None,
                 condition_limit: int | None = CONDITION_LIMIT, symmetric: bool = False,
                 reuse: Reuse | None = None, positions: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """x with A x = b, solved as (S A S) y = S b, x = S y.

    solver: "auto" (the fastest available for this size: ibm.solvers.backends.resolve), "pardiso" or "superlu";
    None takes the current choice (ibm.solvers.backends.choice, "auto" unless set).
    structure: "spd", "symmetric" (indefinite, e.g. saddle point) or "general"; None
    detects it (see structures_to_try; symmetric=True when the caller knows A is symmetric).
    info has the relative residual of the original system, the backend and structure
    used, timings, factor statistics, and cond_est (of the scaled system actually
    factorized): estimated when estimate_condition and n <= condition_limit (None:
    always), else NaN with cond_skipped = True. positions (n / 2, 2): where the unknowns
    (x, y pairs) sit, for AMG's rigid-body modes. reuse: a Reuse that keeps the factors for the
    next solve of a matrix of the same pattern (info["reused"] says whether these were). Raises SolveError.
    """
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:
        A = A.sorted_indices()
    b = np.asarray(b, dtype=float)
    diagonal = A.diagonal()
    if np.any(diagonal == 0):
        # Saddle-point systems have a zero block; only flag rows that are entirely empty.
        empty = np.flatnonzero(np.diff(A.indptr) == 0)
        if len(empty):
            raise SolveError(f"{len(empty)} unknowns have no stiffness (first: {empty[0]})")
    start = perf_counter()
    structures = structures_to_try(A, diagonal, symmetric) if structure is None else [structure]
    backend = solvers.resolve(solvers.current() if solver is None else solver, A.shape[0], structures[0],
                              reuse is not None, A.nnz)
    kept = getattr(reuse.factors, "structure", None) if reuse is not None else None
    if kept in structures[1:]:   # the last solve of this sequence needed that one: try it first
        structures = [kept] + [kind for kind in structures if kind != kept]
    if backend == "amg":    # conjugate gradients: symmetric positive definite or nothing
        if structures[0] != "spd":
            raise SolveError("AMG (conjugate gradients) needs a symmetric positive definite system; "
                             "use --solver pardiso or superlu for this method")
        structures = structures[:1]
    scale = equilibrate(A)
    whole = {}
    will_estimate = (estimate_condition and backend != "amg"
                     and (condition_limit is None or A.shape[0] <= condition_limit))

    def As():   # the whole scaled matrix, built only if a factorization or cond_est needs it
        if "As" not in whole:
            whole["As"] = scaled(A, scale)
        return whole["As"]

    # PARDISO's symmetric types read the upper triangle only: scale just that half
    upper = (solvers.upper_triangle(A, scale=scale)
             if backend == "pardiso" and structures[0] != "general" else None)
    prepared = perf_counter()
    reused = False
    for attempt, kind in enumerate(structures):
        if reuse is not None and attempt == 0 and backend == "pardiso":   # LU: its factors hold the whole matrix
            lu = reuse.take(upper if kind != "general" else As().sorted_indices(), kind)
        else:
            lu = None
        reused = lu is not None
        if lu is None:
            # AMG works on the scaled system: its rigid modes scale by 1 / s as the unknowns do
            near_null = (rigid_modes(positions) / scale[:, None]
                         if backend == "amg" and positions is not None and positions.size == A.shape[0] else None)
            # without a condition estimate, perturbed symmetric-indefinite factors (PARDISO's
            # remedy for a saddle system's tiny pivots) may stand: the residual check decides.
            # Above the estimate's size limit too: SuperLU's fallback there is slow, not wiser
            lu = factorize(As, backend, kind, upper, near_null, allow_perturbed=not will_estimate)
        factorized = perf_counter()
        x = scale * lu.solve(scale * b)
        residual = relative_residual(A, x, b)
        if residual <= tolerance or attempt == len(structures) - 1:
            break
        lu.free()   # e.g. a Cholesky of an indefinite matrix that did not break down: next structure
    solved = perf_counter()
    info = {"residual": float(residual), "solver": lu.backend, "structure": lu.structure,
            "time_prepare": prepared - start, "time_factorize": factorized - prepared,
            "time_substitute": solved - factorized, **lu.info, **({"reused": reused} if reuse is not None else {})}
    if will_estimate:
        info["cond_est"] = condition_estimate(As(), lu)
    elif estimate_condition:   # (AMG: an estimate would need many iterative solves)
        info.update(cond_est=float("nan"), cond_skipped=True)
    if reuse is None or not (residual <= tolerance and reuse.keep(lu)):
        lu.free()
    if backend == "amg" and not residual <= tolerance:
        raise SolveError(f"AMG-preconditioned conjugate gradients stopped at a relative residual of {residual:.3g} "
                         f"after {info.get('amg_iterations')} iterations (this boundary method's system defeats the "
                         "multigrid: a thin band or a stiff penalty); use --solver pardiso or superlu")
    if not np.all(np.isfinite(x)) or not residual <= tolerance:
        raise SolveError(f"the linear solve failed (relative residual {residual:.3g}); "
                         "the system is singular or too ill-conditioned")
    return x, info


def relative_residual(A: sp.csr_matrix, x: np.ndarray, b: np.ndarray) -> float:
    norm_b = np.linalg.norm(b)
    return float(np.linalg.norm(A @ x - b) / (norm_b if norm_b > 0 else 1.0))
