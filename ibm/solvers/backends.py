"""Sparse direct solvers behind one interface: factorize once, solve many right-hand sides.

Backends:
- "pardiso": Intel MKL PARDISO (through the mkl_rt library that the pypardiso package ships),
  on the upper triangle for symmetric matrices: Cholesky (matrix type 2) for SPD systems,
  Bunch-Kaufman with scaling and weighted matching (type -2) for symmetric indefinite
  (saddle-point) systems, LU (type 11) for general ones. METIS ordering.
- "superlu": SciPy's SuperLU, with a symmetric ordering (minimum degree on A^T + A) and
  diagonal pivoting preferred for symmetric systems, COLAMD for general ones.
- "amg": conjugate gradients preconditioned by smoothed-aggregation algebraic multigrid (pyamg),
  with the rigid-body modes as near-null space when the caller gives the unknowns' positions
  (translations only otherwise); symmetric positive definite systems only. Not a factorization:
  "factorizing" builds the hierarchy, each solve iterates to a relative residual of AMG_TOLERANCE.
"auto" picks pardiso where it loads, superlu otherwise (never amg).

Structures: "spd" (symmetric positive definite), "symmetric" (symmetric indefinite, e.g.
Lagrange multipliers with a zero block), "general".
"""
from __future__ import annotations

import contextvars
import ctypes
import glob
import sys
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from importlib.util import find_spec

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ibm.exceptions import FactorizationError, InputError

SOLVERS = ("auto", "pardiso", "superlu", "amg")
AMG_TOLERANCE = 1e-10
AMG_MAX_ITERATIONS = 2000
# Below PARDISO_MIN unknowns SuperLU factorizes a 2D stencil (rows of fewer than SMALL_STENCIL
# entries) as fast as PARDISO, whose per-call setup dominates; 3D stencils fill SuperLU far more.
# A Newton sequence keeps PARDISO's ordering and symbolic factors (ibm.solvers.linear.Reuse), so
# there PARDISO pays from SEQUENCE_PARDISO_MIN on. The measurements: docs/choices.md.
PARDISO_MIN = 20_000
SMALL_STENCIL = 30
SEQUENCE_PARDISO_MIN = 4_000
STRUCTURES = ("spd", "symmetric", "general")



# --- choosing -----------------------------------------------------------------------------------

# The backend solve_system uses when not told: set for a block of work with `choice`
# (the case runner does so for --solver), "auto" otherwise.
_CHOICE: contextvars.ContextVar[str] = contextvars.ContextVar("solver", default="auto")


@contextmanager
def choice(solver: str):
    """Within the block, solve_system(solver=None) uses `solver` (validated here)."""
    resolve(solver)
    token = _CHOICE.set(solver)
    try:
        yield
    finally:
        _CHOICE.reset(token)


def current() -> str:
    return _CHOICE.get()


@lru_cache(maxsize=1)
def _mkl():
    """The mkl_rt library as pypardiso finds it, or None when it is not installed or does not load."""
    if find_spec("pypardiso") is None:   # not imported: pypardiso's import walks the environment for MKL
        return None
    # where pip puts mkl_rt; pypardiso's own search walks the whole environment (slow)
    for path in sorted(glob.glob(f"{sys.prefix}/lib/libmkl_rt.so*") + glob.glob(f"{sys.prefix}/Library/bin/mkl_rt*.dll"),
                       key=len):
        try:
            return ctypes.CDLL(path)
        except OSError:
            pass
    try:   # our own handle: pypardiso sets argtypes on its function objects
        import pypardiso
        return ctypes.CDLL(pypardiso.PyPardisoSolver().libmkl._name)
    except Exception:   # OSError from a broken MKL: fall back to SuperLU
        return None


def available() -> list[str]:
    """Direct backends that work on this machine, fastest first."""
    return (["pardiso"] if _mkl() is not None else []) + ["superlu"]


def amg_available() -> bool:
    return find_spec("pyamg") is not None


def resolve(solver: str, n: int | None = None, structure: str = "spd", sequence: bool = False,
            nnz: int | None = None) -> str:
    """The backend `solver` ("auto", "pardiso" or "superlu") stands for here, for n unknowns.

    "auto" is the fastest available: PARDISO where it loads, except for a positive definite
    (`structure` "spd") system of a 2D stencil (nnz, if given, below SMALL_STENCIL entries a row)
    below PARDISO_MIN unknowns, or below SEQUENCE_PARDISO_MIN in a Newton iteration's sequence of
    solves (`sequence`: PARDISO keeps the ordering and the symbolic factorization there,
    ibm.solvers.linear.Reuse), where SuperLU is (PARDISO's setup costs more than a small Cholesky).
    Indefinite and general systems go to PARDISO at any size (SuperLU's pivoting fills them: a 3.4k
    saddle system of Lagrange multipliers took 0.37 s against 0.02 s). InputError if unknown.
    """
    if solver not in SOLVERS:
        raise InputError(f"unknown solver {solver!r}; allowed: {', '.join(SOLVERS)}")
    if solver == "auto":
        limit = SEQUENCE_PARDISO_MIN if sequence else PARDISO_MIN
        small = n is not None and n < limit and structure == "spd" and (nnz is None or nnz < SMALL_STENCIL * n)
        return "superlu" if small else available()[0]
    if solver == "amg" and amg_available():
        return solver
    if solver not in available():
        package = "pyamg" if solver == "amg" else "pypardiso"
        raise InputError(f"solver {solver!r} is not available here (is {package} installed?); "
                         f"available: {', '.join(available() + (['amg'] if amg_available() else []))}")
    return solver


# --- sparse helpers -----------------------------------------------------------------------------

def row_ids(A: sp.csr_matrix) -> np.ndarray:
    """(nnz,) row index of every stored entry."""
    return np.repeat(np.arange(A.shape[0], dtype=A.indices.dtype), np.diff(A.indptr))


def upper_triangle(A: sp.csr_matrix, with_diagonal: bool = True, scale: np.ndarray | None = None) -> sp.csr_matrix:
    """Upper triangle of a CSR matrix with sorted indices, every diagonal entry stored (zeros too).

    PARDISO's symmetric types read only this part and need the whole diagonal present.
    With `scale` (n,), the upper triangle of S A S, S = diag(scale), in the same pass.
    """
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:
        A = A.sorted_indices()
    rows = row_ids(A)
    keep = np.flatnonzero(A.indices >= rows)
    rows, columns = rows[keep], A.indices[keep]
    data = A.data[keep] if scale is None else A.data[keep] * scale[rows] * scale[columns]
    counts = np.bincount(rows, minlength=A.shape[0])
    U = sp.csr_matrix((data, columns, np.concatenate([[0], np.cumsum(counts)])), shape=A.shape)
    U.has_sorted_indices = True
    if with_diagonal:
        first = U.indices[U.indptr[:-1].clip(max=max(U.nnz - 1, 0))] if U.nnz else np.zeros(0, int)
        has = (counts > 0) & (first == np.arange(A.shape[0]))
        if not np.all(has):   # insert explicit zeros on the diagonal (kept: COO -> CSR keeps zeros)
            missing = np.flatnonzero(~has)
            coo = U.tocoo()
            U = sp.csr_matrix((np.concatenate([coo.data, np.zeros(len(missing))]),
                               (np.concatenate([coo.row, missing]), np.concatenate([coo.col, missing]))),
                              shape=A.shape)
            U.sum_duplicates()
            U.sort_indices()
    return U


def is_symmetric(A: sp.csr_matrix, tolerance: float = 1e-13) -> bool:
    """Whether A equals its transpose to `tolerance` times its largest entry (exact check)."""
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:
        A = A.sorted_indices()
    T = A.T.tocsr()                       # CSC -> CSR conversion sorts the indices
    scale = tolerance * np.abs(A.data).max(initial=0.0)
    if np.array_equal(A.indptr, T.indptr) and np.array_equal(A.indices, T.indices):
        return bool(np.all(np.abs(A.data - T.data) <= scale))
    difference = A - T
    return difference.nnz == 0 or bool(np.abs(difference.data).max() <= scale)


def looks_symmetric(A: sp.csr_matrix, tolerance: float = 1e-10) -> bool:
    """Cheap probe (two products): |y^T A x - x^T A y| <= tolerance ||A||_F |x| |y| for fixed random x, y.

    A clearly non-symmetric matrix fails it; a symmetric one passes (round-off of the products
    stays far below tolerance). Callers confirm by the residual of the solve.
    """
    x, y = np.random.default_rng(2024).standard_normal((2, A.shape[0]))
    gap = abs(y @ (A @ x) - x @ (A @ y))
    return bool(gap <= tolerance * np.linalg.norm(A.data) * np.linalg.norm(x) * np.linalg.norm(y))


# --- factorizations -------------------------------------------------------------------------------

@dataclass(eq=False)
class Factorization:
    """A factorized matrix: solve(b) for b (n,) or (n, k); free() releases the backend's memory."""

    backend: str
    structure: str
    n: int
    info: dict = field(default_factory=dict)   # backend facts: factor nonzeros, memory, inertia

    def solve(self, b: np.ndarray, transpose: bool = False) -> np.ndarray:
        raise NotImplementedError

    def free(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


class PardisoFactorization(Factorization):
    MTYPE = {"spd": 2, "symmetric": -2, "general": 11}

    def __init__(self, A: sp.csr_matrix, structure: str, upper: sp.csr_matrix | None = None,
                 allow_perturbed: bool = False):
        super().__init__("pardiso", structure, A.shape[0])
        self.allow_perturbed = allow_perturbed and structure == "symmetric"
        self._lib = _mkl()
        self.mtype = self.MTYPE[structure]
        if structure == "general":
            M = sp.csr_matrix(A).sorted_indices()
        else:
            M = upper if upper is not None else upper_triangle(A)
        # 0-based 32-bit indices (iparm[34] = 1), kept alive as long as the factors
        self._a = np.ascontiguousarray(M.data, dtype=np.float64)
        self._ia = np.ascontiguousarray(M.indptr, dtype=np.int32)
        self._ja = np.ascontiguousarray(M.indices, dtype=np.int32)
        self._pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        self._lib.pardisoinit(self._pt.ctypes.data_as(ctypes.c_void_p), ctypes.byref(ctypes.c_int32(self.mtype)),
                              self.iparm.ctypes.data_as(ctypes.c_void_p))
        self.iparm[0] = 1          # use the values below, defaults elsewhere (from pardisoinit)
        self.iparm[1] = 2          # METIS nested dissection
        self.iparm[34] = 1         # zero-based indices
        self.iparm[17] = -1        # report nonzeros in the factors
        self.iparm[33] = 1         # conditional numerical reproducibility: the same bits run to run (free here)
        if structure == "symmetric":
            self.iparm[9] = 8      # perturb pivots below 1e-8 ||A||
            self.iparm[10] = 1     # symmetric scaling and weighted matching: recommended for
            self.iparm[12] = 1     # saddle-point matrices (zero diagonal block)
        self._factorized = False
        self._call(12, np.zeros(0), np.zeros(0), 1)
        self._factorized = True
        # perturbed pivots: factors of a nearby matrix, not of A; kept only when the caller asked
        # (no condition estimate wanted, the residual check decides: saddle systems of Newton steps)
        if self.iparm[13] > 0 and not self.allow_perturbed:
            self.free()
            raise FactorizationError(f"PARDISO perturbed {self.iparm[13]} pivots (numerically singular)")
        self.info = {"factor_nnz": int(self.iparm[17]),
                     "solver_memory_mb": float(max(self.iparm[14], self.iparm[15] + self.iparm[16])) / 1024}
        if structure == "symmetric":
            self.info.update(inertia_positive=int(self.iparm[21]), inertia_negative=int(self.iparm[22]),
                             perturbed_pivots=int(self.iparm[13]))

    def same_pattern(self, M: sp.csr_matrix) -> bool:
        """M (upper triangle for symmetric types) has the pattern these factors were analysed for."""
        return (M.shape[0] == self.n and len(M.indices) == len(self._ja)
                and np.array_equal(M.indptr, self._ia) and np.array_equal(M.indices, self._ja))

    def refactor(self, M: sp.csr_matrix) -> None:
        # (LU, type 11, keeps the whole sorted matrix; the symmetric types its upper triangle)
        """Numerical factorization of new values on the analysed pattern (phase 22): the ordering
        and symbolic factorization (METIS, phase 11: more than half of phase 12 on the 2D systems
        here) are reused. FactorizationError as for a new factorization."""
        self._a = np.ascontiguousarray(M.data, dtype=np.float64)
        self._call(22, np.zeros(0), np.zeros(0), 1)
        if self.iparm[13] > 0 and not self.allow_perturbed:
            self.free()
            raise FactorizationError(f"PARDISO perturbed {self.iparm[13]} pivots (numerically singular)")

    def _call(self, phase: int, b: np.ndarray, x: np.ndarray, nrhs: int) -> None:
        error = ctypes.c_int32(0)
        i32 = ctypes.c_int32
        self._lib.pardiso(self._pt.ctypes.data_as(ctypes.c_void_p), ctypes.byref(i32(1)), ctypes.byref(i32(1)),
                          ctypes.byref(i32(self.mtype)), ctypes.byref(i32(phase)), ctypes.byref(i32(self.n)),
                          self._a.ctypes.data_as(ctypes.c_void_p), self._ia.ctypes.data_as(ctypes.c_void_p),
                          self._ja.ctypes.data_as(ctypes.c_void_p), ctypes.c_void_p(None), ctypes.byref(i32(nrhs)),
                          self.iparm.ctypes.data_as(ctypes.c_void_p), ctypes.byref(i32(0)),
                          b.ctypes.data_as(ctypes.c_void_p), x.ctypes.data_as(ctypes.c_void_p), ctypes.byref(error))
        if error.value != 0:
            if phase in (12, 22):
                self._call(-1, np.zeros(0), np.zeros(0), 1)
                self._factorized = False
            meaning = {-4: "zero or negative pivot", -2: "not enough memory", -3: "reordering failed",
                       -1: "inconsistent input"}.get(error.value, "see the PARDISO documentation")
            raise FactorizationError(f"PARDISO error {error.value} ({meaning}) in phase {phase}")

    def solve(self, b: np.ndarray, transpose: bool = False) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        nrhs = 1 if b.ndim == 1 else b.shape[1]
        bf = np.asfortranarray(b)
        x = np.zeros_like(bf)
        # symmetric factors solve A^T x = b as they are; LU: transposed solve (iparm[11] = 2)
        self.iparm[11] = 2 if (transpose and self.structure == "general") else 0
        self._call(33, bf, x, nrhs)
        self.iparm[11] = 0
        return np.ascontiguousarray(x)

    def free(self) -> None:
        if self._factorized:
            self._call(-1, np.zeros(0), np.zeros(0), 1)
            self._factorized = False

    def __del__(self):
        try:
            self.free()
        except Exception:
            pass


class SuperLUFactorization(Factorization):
    def __init__(self, A: sp.csr_matrix, structure: str, upper=None):
        super().__init__("superlu", structure, A.shape[0])
        A = sp.csc_matrix(A)
        if structure == "general":
            options = dict(permc_spec="COLAMD")
        else:   # symmetric pattern: fill-reducing ordering of A^T + A, diagonal pivots when acceptable
            options = dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0 if structure == "spd" else 0.01,
                           options=dict(SymmetricMode=True))
        try:
            self._lu = spla.splu(A, **options)
        except RuntimeError as error:
            raise FactorizationError(f"SuperLU: {error}") from None
        if structure == "spd" and (not np.array_equal(self._lu.perm_r, self._lu.perm_c)
                                   or np.any(self._lu.U.diagonal() <= 0)):
            # symmetric pivoting with a non-positive pivot: not definite (Sylvester's law of inertia)
            raise FactorizationError("SuperLU: the matrix is not positive definite")
        self.info = {"factor_nnz": int(self._lu.L.nnz + self._lu.U.nnz)}

    def solve(self, b: np.ndarray, transpose: bool = False) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=np.float64), trans="T" if transpose else "N")

    def free(self) -> None:
        self._lu = None


class AMGFactorization(Factorization):
    """Smoothed-aggregation AMG as a preconditioner of conjugate gradients (pyamg)."""

    def __init__(self, A: sp.csr_matrix, structure: str, near_null: np.ndarray | None = None):
        super().__init__("amg", structure, A.shape[0])
        if structure != "spd":
            raise FactorizationError("AMG (conjugate gradients) needs a symmetric positive definite system; "
                                     "use --solver pardiso or superlu for this method")
        import pyamg
        self._A = sp.csr_matrix(A)
        if near_null is None:   # translations, if the unknowns come in (x, y) pairs
            near_null = np.kron(np.ones((self.n // 2, 1)), np.eye(2)) if self.n % 2 == 0 else np.ones((self.n, 1))
        B = near_null
        self._hierarchy = pyamg.smoothed_aggregation_solver(self._A, B=B, symmetry="symmetric", max_coarse=500)
        self.iterations = 0
        self.info = {"amg_levels": len(self._hierarchy.levels), "amg_complexity": float(self._hierarchy.operator_complexity())}

    def solve(self, b: np.ndarray, transpose: bool = False) -> np.ndarray:
        residuals = []
        b = np.asarray(b, dtype=np.float64)
        x = self._hierarchy.solve(b, tol=AMG_TOLERANCE, accel="cg", maxiter=AMG_MAX_ITERATIONS, residuals=residuals)
        self.iterations += max(len(residuals) - 1, 0)
        self.info["amg_iterations"] = self.iterations
        self.info["amg_converged"] = bool(residuals and residuals[-1] <= AMG_TOLERANCE * residuals[0])
        return x

    def free(self) -> None:
        self._hierarchy = None


def factorize(A, structure: str = "general", solver: str = "auto",
              upper: sp.csr_matrix | None = None, near_null: np.ndarray | None = None,
              allow_perturbed: bool = False) -> Factorization:
    """Factorize A (n, n) of the given structure with the chosen backend.

    Fallbacks, in order, when a factorization fails: an "spd" Cholesky that meets a
    non-positive pivot becomes the symmetric indefinite factorization of the same
    backend; a PARDISO factorization that had to perturb pivots (a numerically singular
    matrix; its factors would belong to a nearby matrix) becomes SuperLU, whose
    threshold pivoting and condition estimate then describe A itself. The returned
    factorization's backend and structure say what ran.

    A may be a callable returning the matrix: it is called only if a backend needs the
    whole matrix, so PARDISO's symmetric types can run on `upper` (upper_triangle(A),
    sorted, full diagonal) alone.
    """
    if structure not in STRUCTURES:
        raise InputError(f"unknown matrix structure {structure!r}; allowed: {', '.join(STRUCTURES)}")
    if callable(A) and upper is None:
        A = A()
    n = upper.shape[0] if callable(A) else A.shape[0]
    backend = resolve(solver, n)
    if backend == "amg":   # no fallback: a system AMG cannot take is the user's to route elsewhere
        return AMGFactorization(sp.csr_matrix(A() if callable(A) else A), structure, near_null)
    attempts = [(backend, structure)]
    if structure == "spd":
        attempts.append((backend, "symmetric"))
    if backend == "pardiso":
        attempts.append(("superlu", "general" if structure == "general" else "symmetric"))
    kinds = {"pardiso": PardisoFactorization, "superlu": SuperLUFactorization}
    whole = {}

    def matrix():
        if "A" not in whole:
            whole["A"] = sp.csr_matrix(A() if callable(A) else A)
        return whole["A"]

    for number, (name, kind) in enumerate(attempts):
        try:
            if name == "pardiso" and kind != "general" and upper is not None:
                return kinds[name](_Shape(n), kind, upper, allow_perturbed=allow_perturbed)
            return kinds[name](matrix(), kind)
        except FactorizationError:
            if number == len(attempts) - 1:
                raise


@dataclass(frozen=True)
class _Shape:
    """Stands in for a matrix whose upper triangle alone is handed over."""

    n: int

    @property
    def shape(self) -> tuple[int, int]:
        return (self.n, self.n)
