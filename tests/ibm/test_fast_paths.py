"""The fast paths agree with the straightforward ones to round-off: structured CSR and
cell-moment assembly against per-point COO assembly, operator-free field evaluation against
the B/Nv operators, and every solver backend and structure against each other."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from ibm.discretise import assembly
from ibm import dirichlet
from ibm.small import forms
from ibm.solvers import backends as solvers
from ibm.discretise.assembly import shape_vector, stiffness_blocks, strain_matrix
from ibm.quadrature.bands import band_quadrature
from ibm.exceptions import InputError, SolveError
from ibm.discretise.grid import Grid
from ibm.models.elastic import Elastic
from ibm.implicit_boundary import solve_ibm
from ibm.solvers.linear import CONDITION_LIMIT, solve_system
from studies.run.case import CaseSpec, instance_of, run_case

PARDISO = "pardiso" in solvers.available()
needs_pardiso = pytest.mark.skipif(not PARDISO, reason="PARDISO (pypardiso/MKL) is not installed")
MATERIAL = Elastic(1e4, 0.3)


def model_of(angle=30.0, cell=5.0, ppc=1, offset=(0.37, 0.29)):
    from ibm.small.model import build_model
    instance = instance_of(CaseSpec(angle=angle, cell=cell, ppc=ppc, offset=offset))
    return build_model(instance.body, instance.parameters.material, instance.loads, cell, ppc)


def coo_assembly(grid: Grid, cells: np.ndarray, blocks: np.ndarray) -> sp.csr_matrix:
    """The straightforward assembly: every (row, col, value) of every block through COO."""
    dofs = grid.cell_dofs(cells)
    rows = np.broadcast_to(dofs[:, :, None], blocks.shape).ravel()
    cols = np.broadcast_to(dofs[:, None, :], blocks.shape).ravel()
    n = 2 * grid.n_nodes
    return sp.coo_matrix((blocks.ravel(), (rows, cols)), shape=(n, n)).tocsr()


def point_blocks(model, qp, D=None):
    N, dN = model.grid.shape_functions(qp.x, qp.cells)
    if D is None:
        return stiffness_blocks(strain_matrix(N, dN), model.material.C, qp.weight)
    return stiffness_blocks(strain_matrix(N, dN, *D(qp.x)), model.material.C, qp.weight)


def relative_difference(A, B) -> float:
    return float(abs(A - B).max() / abs(B).max())


# --- assembly ---------------------------------------------------------------------------------

@pytest.mark.parametrize("angle,ppc", [(30.0, 1), (90.0, 2), (17.0, 3)])
def test_moment_stiffness_equals_point_by_point_assembly(angle, ppc):
    model = model_of(angle, ppc=ppc)
    qp = model.points.quadrature()
    fast = forms.stiffness(model, qp)
    slow = coo_assembly(model.grid, qp.cells, point_blocks(model, qp))
    assert relative_difference(fast, slow) < 1e-14
    assert fast.has_sorted_indices and np.all(np.diff(fast.indices[fast.indptr[0]:fast.indptr[1]]) > 0)


def test_sliver_cells_keep_their_tiny_entries_accurate():
    """A body edge 1e-9 h past a grid line: the nodes beyond it have a support ~gap h^2, and
    entries ~gap^2 of their rows would drown in the cancellation of cell moments
    (m0 - 2 m_a + m_aa); such cells go point by point and match entry by entry."""
    gap = 1e-9
    model = model_of(90.0, cell=10.0, offset=(1 - gap, 0.29))
    qp = model.points.quadrature()
    moments = assembly.cell_moments(model.grid, qp.x, qp.weight, qp.cells)
    assert assembly.concentrated_cells(moments).sum() > 0
    fast = forms.stiffness(model, qp)
    slow = coo_assembly(model.grid, qp.cells, point_blocks(model, qp))
    row_max = abs(slow).max(axis=1).toarray().ravel()
    weak = np.flatnonzero((row_max > 0) & (row_max < 1e-6 * row_max.max()))   # the sliver nodes' rows
    assert len(weak) >= 10
    a, b = fast[weak].toarray(), slow[weak].toarray()
    stored = b != 0
    assert np.max(np.abs(a[stored] - b[stored]) / np.abs(b[stored])) < 1e-12
    assert np.any(np.abs(b[stored]) < 1e-8 * np.abs(b).max())    # there are gap-small entries


def test_corrected_stiffness_equals_the_three_forms():
    model = model_of(30.0)
    delta = 1e-3 * model.grid.h
    band = band_quadrature(model.body, model.grid, delta)

    def D(x):
        return dirichlet.matrix(model.body, x, delta)

    points = model.points.quadrature()
    fast = forms.corrected_stiffness(model, points, band, D)
    slow = (coo_assembly(model.grid, points.cells, point_blocks(model, points))
            + coo_assembly(model.grid, band.cells, point_blocks(model, band, D))
            - coo_assembly(model.grid, band.cells, point_blocks(model, band)))
    assert relative_difference(fast, slow) < 1e-12


def test_structured_csr_of_random_blocks_with_repeated_cells():
    grid = Grid(1.0, (-2, 3), (7, 5))
    rng = np.random.default_rng(1)
    cells = rng.integers(0, grid.n_cells, 60)            # repeats, any order
    blocks = rng.standard_normal((60, 8, 8))
    fast = assembly.assemble_matrix(grid, cells, blocks)
    assert relative_difference(fast, coo_assembly(grid, cells, blocks)) < 1e-15
    # one row per DOF of every touched node, 18 slots at most, no others
    counts = np.diff(fast.indptr)
    assert counts.max() <= assembly.SLOTS
    touched = np.unique(grid.cell_dofs(np.unique(cells)))
    assert np.array_equal(np.flatnonzero(counts), touched)


def test_restrict_equals_fancy_indexing():
    model = model_of(30.0)
    qp = model.points.quadrature()
    K = forms.stiffness(model, qp)
    dofs = np.unique(model.grid.cell_dofs(np.unique(qp.cells)))
    assert (assembly.restrict(K, dofs) != K[dofs][:, dofs]).nnz == 0
    fewer = dofs[::2]                                     # entries outside: the general path
    assert (assembly.restrict(K, fewer) != K[fewer][:, fewer]).nnz == 0


@pytest.mark.parametrize("threads", [1, 3])
def test_grid_matrix_selections_equal_fancy_indexing(monkeypatch, threads):
    # small chunks, so that rows are split over chunks and threads even on a small model
    monkeypatch.setattr(assembly, "CHUNK", 64)
    monkeypatch.setattr(assembly, "THREADS", threads)
    model = model_of(30.0, cell=2.5)
    delta = 1e-3 * model.grid.h
    band = band_quadrature(model.body, model.grid, delta)
    matrix = forms.corrected_stiffness(model, model.points.quadrature(), band,
                                       lambda x: dirichlet.matrix(model.body, x, delta), assemble=False)
    full = matrix.tocsr()
    dofs = matrix.rows
    rng = np.random.default_rng(4)
    some = np.sort(rng.choice(dofs, len(dofs) // 3, replace=False))
    outside = np.setdiff1d(np.arange(2 * model.grid.n_nodes), dofs)[:5]
    selections = [(dofs, dofs), (dofs[1:], dofs[1:]),                 # contiguous, from an odd row
                  (some, dofs), (dofs, some), (some, some),             # many dropped columns
                  (dofs[:7], dofs[3:40]), (dofs[[2, 9]], dofs[[2, 9]]),  # few rows: counted directly
                  (np.sort(np.concatenate([outside, dofs[:9]])), dofs)]  # rows with no slots
    for rows, columns in selections:
        part = matrix.tocsr(rows, columns)
        expected = full[rows][:, columns]
        assert part.shape == expected.shape and part.has_sorted_indices
        assert (part != expected).nnz == 0
        assert np.array_equal(np.diff(part.indptr), np.diff(expected.indptr))   # same stored pattern
    assert full.nnz == int(matrix.mask.sum()) and np.all(np.diff(full.indptr)[dofs] > 0)


@pytest.mark.parametrize("n, step, threads", [(0, 4, 2), (3, 4, 2), (8, 4, 2), (9, 4, 2), (1000, 7, 3),
                                               (64, 8, 4), (65, 8, 1)])
def test_in_parallel_covers_every_index_once_in_whole_steps(n, step, threads):
    seen = np.zeros(n, int)
    blocks = []

    def work(start, stop):
        seen[start:stop] += 1
        blocks.append((start, stop))

    assembly.in_parallel(work, n, step, threads)
    assert np.all(seen == 1)
    assert all(start % step == 0 for start, _ in blocks) and len(blocks) <= max(1, threads)


def test_loads_and_field_evaluation_equal_the_operator_forms():
    model = model_of(30.0, ppc=2)
    qp = model.points.quadrature()
    delta = 1e-2 * model.grid.h

    def D(x):
        return dirichlet.matrix(model.body, x, delta)

    band = band_quadrature(model.body, model.grid, delta)
    b = np.random.default_rng(2).standard_normal((len(band), 2))
    N, dN = model.grid.shape_functions(band.x, band.cells)
    Nv = shape_vector(N, D(band.x)[0])
    slow = assembly.assemble_vector(model.grid, band.cells, np.einsum("pia,pi->pa", Nv, b) * band.weight[:, None])
    fast = forms._load(model, band, b, D)
    assert np.max(np.abs(fast - slow)) < 1e-14 * np.max(np.abs(slow))

    U = np.random.default_rng(3).standard_normal(2 * model.grid.n_nodes)
    x = np.concatenate([qp.x, band.x])
    cells = np.concatenate([qp.cells, band.cells])
    u, sigma, _ = forms.field_evaluator(model, U, D)(x, cells)
    N, dN = model.grid.shape_functions(x, cells)
    Dm, gradDm = D(x)
    ue = U[model.grid.cell_dofs(cells)]
    u_ref = np.einsum("pia,pa->pi", shape_vector(N, Dm), ue)
    s_ref = np.einsum("pka,pa->pk", strain_matrix(N, dN, Dm, gradDm), ue) @ model.material.C.T
    assert np.max(np.abs(u - u_ref)) < 1e-13 * np.max(np.abs(u_ref))
    assert np.max(np.abs(sigma - assembly.tensor(s_ref))) < 1e-12 * np.max(np.abs(s_ref))


def test_dirichlet_matrix_beyond_the_bands_is_exactly_identity():
    model = model_of(30.0)
    delta = 0.3 * model.grid.h
    x = model.points.x
    Dm, grad = dirichlet.matrix(model.body, x, delta)
    phi = model.body.signed_distance(x)[:, model.body.essential_edges]
    far = np.all(phi >= delta, axis=1)
    assert far.sum() > 0 and (~far).sum() > 0
    assert np.array_equal(Dm[far], np.broadcast_to(np.eye(2), (far.sum(), 2, 2)))
    assert not np.any(grad[far])
    # inside: the product of the edge factors, evaluated directly
    k = model.body.essential_edges
    near = np.flatnonzero(~far)[:5]
    expected = np.broadcast_to(np.eye(2), (len(near), 2, 2))
    for edge in k:
        Dk, _ = dirichlet.edge_matrix(model.body.kinds[edge], model.body.normals[edge],
                                      *dirichlet.scalar(model.body.signed_distance(x[near])[:, edge], delta))
        expected = expected @ Dk
    assert np.max(np.abs(Dm[near] - expected)) < 1e-15


# --- solvers ----------------------------------------------------------------------------------

def ibm_system(angle=30.0, cell=5.0):
    """The IBM matrix and load of a case, captured from solve_system."""
    import ibm.implicit_boundary
    captured = {}

    def capture(A, b, *args, **kwargs):
        captured.update(A=A, b=b)
        raise StopIteration

    original = ibm.implicit_boundary.solve_system
    ibm.implicit_boundary.solve_system = capture
    try:
        solve_ibm(model_of(angle, cell))
    except StopIteration:
        pass
    finally:
        ibm.implicit_boundary.solve_system = original
    return sp.csr_matrix(captured["A"]), captured["b"]


def test_known_symmetric_system_skips_the_probe_not_the_checks():
    A, b = ibm_system()
    probed, info = solve_system(A, b)
    trusted, trusted_info = solve_system(A, b, symmetric=True)
    assert np.array_equal(probed, trusted) and trusted_info["structure"] == info["structure"] == "spd"
    # a non-symmetric matrix declared symmetric still meets the residual check, not a wrong answer
    skew = A + sp.triu(A, 1) * 0.5
    for solver in solvers.available():
        x, info = solve_system(skew, b, symmetric=True, solver=solver)
        assert np.linalg.norm(skew @ x - b) <= 1e-8 * np.linalg.norm(b)


def saddle_system(K: sp.csr_matrix, b: np.ndarray, m: int = 12):
    """[[K, G^T], [G, 0]] with m well-posed constraint rows (each ties two unknowns)."""
    rng = np.random.default_rng(4)
    n = K.shape[0]
    rows = np.repeat(np.arange(m), 2)
    cols = rng.choice(n, 2 * m, replace=False)
    G = sp.csr_matrix((rng.uniform(0.5, 1.5, 2 * m) * K.diagonal().max(), (rows, cols)), shape=(m, n))
    A = sp.bmat([[K, G.T], [G, None]], format="csr")
    return A, np.concatenate([b, rng.standard_normal(m)])


def agree(x, y, cond):
    """Equal up to what the condition number allows at double precision."""
    return np.linalg.norm(x - y) <= max(cond, 1.0) * 1e-14 * np.linalg.norm(y)


BACKENDS = ["superlu"] + (["pardiso"] if PARDISO else [])


def test_backends_and_structures_agree_on_the_ibm_system():
    K, b = ibm_system()
    reference, info = solve_system(K, b, solver="superlu", structure="general")
    assert info["structure"] == "general" and info["residual"] < 1e-9
    for backend in BACKENDS:
        for structure in ("spd", "symmetric", "general", None):
            x, info = solve_system(K, b, solver=backend, structure=structure)
            assert info["solver"] == backend
            assert info["structure"] == (structure or "spd")
            assert info["residual"] < 1e-9
            assert agree(x, reference, info["cond_est"]), (backend, structure)


@pytest.mark.parametrize("backend", BACKENDS)
def test_saddle_point_systems_use_the_symmetric_indefinite_factorization(backend):
    K, b = ibm_system()
    A, rhs = saddle_system(K, b)
    x, info = solve_system(A, rhs, solver=backend)
    assert info["structure"] == "symmetric" and info["residual"] < 1e-10
    reference = sp.linalg.spsolve(A.tocsc(), rhs)
    assert agree(x, reference, info["cond_est"])
    if backend == "pardiso":   # inertia: n positive, m negative eigenvalues
        assert (info["inertia_positive"], info["inertia_negative"]) == (K.shape[0], 12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_non_symmetric_systems_get_lu(backend):
    K, b = ibm_system()
    A = (K + sp.triu(K, 1, format="csr") * 0.3).tocsr()
    x, info = solve_system(A, b, solver=backend)
    assert info["structure"] == "general" and info["residual"] < 1e-10
    assert agree(x, sp.linalg.spsolve(A.tocsc(), b), info["cond_est"])


@pytest.mark.parametrize("backend", BACKENDS)
def test_indefinite_matrix_with_positive_diagonal_falls_back_from_cholesky(backend):
    """Positive diagonal but indefinite: Cholesky breaks down (or fails the residual),
    the symmetric indefinite factorization takes over."""
    A = sp.csr_matrix(np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.5], [0.0, 0.5, 3.0]]))
    b = np.array([1.0, -2.0, 0.5])
    x, info = solve_system(A, b, solver=backend)
    assert info["structure"] == "symmetric"
    assert np.allclose(x, np.linalg.solve(A.toarray(), b), rtol=1e-13, atol=0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular_systems_are_refused(backend):
    A = sp.csr_matrix(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 2.0]]))
    with pytest.raises(SolveError):
        solve_system(A, np.array([1.0, 0.0, 1.0]), solver=backend)


def test_condition_estimate_is_skipped_above_the_limit_unless_asked():
    K, b = ibm_system()
    n = K.shape[0]
    _, skipped = solve_system(K, b, condition_limit=n - 1)
    assert skipped["cond_skipped"] and np.isnan(skipped["cond_est"])
    _, forced = solve_system(K, b, condition_limit=None)
    _, default = solve_system(K, b)
    assert n <= CONDITION_LIMIT and "cond_skipped" not in default
    assert forced["cond_est"] == pytest.approx(default["cond_est"], rel=0.5) and forced["cond_est"] > 1e3


def test_upper_triangle_stores_every_diagonal_entry():
    A = sp.csr_matrix(np.array([[0.0, 1.0, 0.0], [1.0, 2.0, 3.0], [0.0, 3.0, 0.0]]))
    A.eliminate_zeros()
    U = solvers.upper_triangle(A)
    assert np.array_equal(U.toarray(), np.triu(A.toarray()))
    assert U.nnz == 5 and np.array_equal(U.indices[U.indptr[:-1]], [0, 1, 2])
    scale = np.array([2.0, 0.5, 3.0])
    Us = solvers.upper_triangle(A, scale=scale)     # of S A S, in the same pass
    assert np.array_equal(Us.toarray(), np.triu((scale[:, None] * A.toarray()) * scale[None, :]))
    assert np.array_equal(Us.indptr, U.indptr) and np.array_equal(Us.indices, U.indices)


def test_solver_choice_and_bad_names():
    assert solvers.resolve("auto", 10) == "superlu"
    assert solvers.resolve("auto", 10**6) == solvers.available()[0]
    # a small system of 2D rows stays with SuperLU, one of trilinear 3D rows (81 entries) does not
    assert solvers.resolve("auto", 10_000, nnz=18 * 10_000) == "superlu"
    assert solvers.resolve("auto", 10_000, nnz=81 * 10_000) == solvers.available()[0]
    # a Newton sequence keeps PARDISO's analysis, so PARDISO takes over from fewer unknowns there;
    # indefinite systems go to PARDISO at any size
    below, above = solvers.SEQUENCE_PARDISO_MIN - 1, solvers.SEQUENCE_PARDISO_MIN
    assert solvers.resolve("auto", below, sequence=True, nnz=18 * below) == "superlu"
    assert solvers.resolve("auto", above, sequence=True, nnz=18 * above) == solvers.available()[0]
    assert solvers.resolve("auto", above, sequence=False, nnz=18 * above) == "superlu"
    assert solvers.resolve("auto", 100, "symmetric", sequence=True) == solvers.available()[0]
    with pytest.raises(InputError, match="unknown solver 'mumps'"):
        solvers.resolve("mumps")
    with pytest.raises(InputError, match="unknown matrix structure 'banded'"):
        solvers.factorize(sp.identity(3, format="csr"), "banded")
    with solvers.choice("superlu"):
        assert solvers.current() == "superlu"
    assert solvers.current() == "auto"


@pytest.mark.parametrize("backend", BACKENDS)
def test_case_results_do_not_depend_on_the_solver(backend):
    spec = CaseSpec(angle=30.0, cell=5.0)
    reference = run_case(spec, solver="superlu", keep_fields=True)
    record = run_case(spec, solver=backend, keep_fields=True)
    assert record["solver"] == backend
    u, u_ref = record["fields"]["solution"].u, reference["fields"]["solution"].u
    assert agree(u, u_ref, reference["cond_est"])
    assert record["err_sigma"] == pytest.approx(reference["err_sigma"], rel=1e-3)


def test_cli_solver_option(capsys):
    from studies.cli import main
    assert main(["solve", "--angle", "30", "--solver", "superlu", "--json"]) == 0
    assert '"solver": "superlu"' in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_info:
        main(["solve", "--solver", "mumps"])
    assert exit_info.value.code == 2


def test_newton_reuses_the_ordering_and_symbolic_factors_of_a_pattern():
    """A Reuse keeps PARDISO's analysis: the same pattern with new values is only refactored
    numerically (phase 22) and solves to the same bits as a new factorization; another pattern,
    or another structure, gets new factors."""
    from ibm.solvers import backends as solvers
    from ibm.solvers.linear import Reuse, solve_system
    if "pardiso" not in solvers.available():
        pytest.skip("PARDISO is not available here")
    n = 180                                                   # 32,400 unknowns: PARDISO's range
    laplace = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    A = sp.csr_matrix(sp.kron(laplace, sp.eye(n)) + sp.kron(sp.eye(n), laplace))
    b = np.random.default_rng(1).random(A.shape[0])
    with Reuse() as reuse:
        x1, info1 = solve_system(A, b, estimate_condition=False, solver="pardiso", reuse=reuse)
        B = sp.csr_matrix((A.data * (1 + 0.1 * np.cos(np.arange(A.nnz))), A.indices, A.indptr), shape=A.shape)
        B = sp.csr_matrix((B + B.T) / 2 + sp.eye(A.shape[0]))
        assert np.array_equal(B.indptr, A.indptr) and np.array_equal(B.indices, A.indices)
        x2, info2 = solve_system(B, b, estimate_condition=False, solver="pardiso", reuse=reuse)
        fresh, _ = solve_system(B, b, estimate_condition=False, solver="pardiso")
        C = sp.csr_matrix(A + sp.diags([1e-3], [2], shape=A.shape) + sp.diags([1e-3], [-2], shape=A.shape))
        x3, info3 = solve_system(C, b, estimate_condition=False, solver="pardiso", reuse=reuse)
    assert (info1["reused"], info2["reused"], info3["reused"]) == (False, True, False)
    assert np.array_equal(x2, fresh) and reuse.reused == 1 and reuse.factors is None
    # PARDISO runs in its reproducible mode (iparm(34) = 1): without it, two fresh factorizations on
    # two threads differed in the last bits in 4 of 10 tries
    for _ in range(5):
        again, _ = solve_system(B, b, estimate_condition=False, solver="pardiso")
        assert np.array_equal(again, fresh)
    assert np.abs(A @ x1 - b).max() < 1e-10 and np.abs(C @ x3 - b).max() < 1e-10


def test_amg_solves_what_the_direct_solvers_solve_and_refuses_what_it_cannot():
    """--solver amg: CG preconditioned by smoothed aggregation with the rigid-body modes, to the
    same answer where the system suits it; a saddle system, or one that stalls it, is one line."""
    from ibm.exceptions import SolveError
    from studies.run.case import CaseSpec, run_case
    for method, parameters in (("nitsche", {}), ("fem", {}), ("ibm", {"delta_rel": 1e-2})):
        spec = CaseSpec(problem="manufactured", method=method, angle=30.0, cell=5.0, ppc=2,   # a multigrid
                        method_parameters=parameters)                                       # of 2+ levels
        amg, direct = run_case(spec, solver="amg"), run_case(spec, solver="superlu")
        assert amg["solver"] == "amg" and amg["amg_iterations"] > 0
        assert abs(amg["err_l2"] - direct["err_l2"]) <= 1e-6 * direct["err_l2"], method
    with pytest.raises(SolveError, match="needs a symmetric positive definite system"):
        run_case(CaseSpec(method="lagrange", angle=30.0), solver="amg")
    with pytest.raises(SolveError, match="AMG-preconditioned conjugate gradients stopped"):
        run_case(CaseSpec(method="penalty", angle=30.0, cell=5.0), solver="amg")      # beta0 = 1e6: stalls


def test_rigid_modes_are_the_null_space_of_a_free_stiffness():
    from ibm.geometry.outline import rectangle
    from ibm.models.elastic import Elastic
    from ibm.small.model import Loads, build_model
    from ibm.solvers.linear import rigid_modes
    body = rectangle(40.0, 30.0, ("free",) * 4, 30.0, np.array([1.3, 2.1]))
    model = build_model(body, Elastic(1e4, 0.3), Loads(), 10.0, 2)
    K = forms.stiffness(model, model.points.quadrature())
    modes = rigid_modes(model.grid.nodes())
    assert np.abs(K @ modes).max() < 1e-10 * abs(K).max() * np.abs(modes).max()


def test_perturbed_saddle_factors_stand_where_no_condition_estimate_is_wanted(monkeypatch):
    """Newton's Lagrange saddle systems make PARDISO perturb tiny pivots. Without a condition
    estimate those factors stand and the residual check decides (a 116 s case fell back to SuperLU
    and now takes 2.9 s); where a condition estimate is wanted they would describe another matrix,
    so SuperLU still takes over."""
    import ibm.large.newton as newton
    from ibm.solvers.linear import solve_system
    from studies.run.case import CaseSpec, run_case
    if "pardiso" not in solvers.available():
        pytest.skip("PARDISO is not available here")
    systems, real = [], newton.solve_system

    def keep(A, b, *args, **kwargs):
        systems.append((A, b))
        return real(A, b, *args, **kwargs)
    monkeypatch.setattr(newton, "solve_system", keep)
    run_case(CaseSpec(problem="confined-block", load_type="settlement", load=1.0, method="lagrange",
                      kinematics="large", steps=1, angle=30.0, cell=1.0, basis="mpm"))
    A, b = systems[0]
    assert A.shape[0] >= solvers.PARDISO_MIN
    x, info = solve_system(A, b, estimate_condition=False, symmetric=True, solver="pardiso")
    assert info["solver"] == "pardiso" and info["perturbed_pivots"] > 0
    assert info["residual"] < 1e-9            # below even the small-strain check (1e-8), after refinement
    _, estimated = solve_system(A, b, estimate_condition=True, symmetric=True, solver="pardiso", condition_limit=None)
    assert estimated["solver"] == "superlu"
    # above the estimate's size limit no estimate is made, so the factors stand there too
    _, large = solve_system(A, b, estimate_condition=True, symmetric=True, solver="pardiso",
                            condition_limit=A.shape[0] - 1)
    assert large["solver"] == "pardiso" and large["cond_skipped"] and large["residual"] < 1e-9


def test_amg_in_3d_solves_what_pardiso_solves_and_refuses_a_saddle_system():
    """--dim 3 --solver amg: the six rigid-body modes as near-null space; on the manufactured cube at
    (30, 20), h = 20 (1131 unknowns), the IBM with a wide band (delta = 0.1 h) and Nitsche give
    PARDISO's errors (measured 2e-11 and 1.5e-14 apart, relative) in 20 and 130 iterations."""
    from ibm.exceptions import SolveError
    from studies.run.solid import solve_box_case
    for method, parameters in (("ibm", {"delta_rel": 0.1}), ("nitsche", {})):
        amg, direct = (solve_box_case("manufactured", method, 30.0, 20.0, (0.37, 0.29, 0.11), 20.0, solver=solver,
                                      **parameters) for solver in ("amg", "pardiso"))
        assert amg["solver"] == "amg" and 0 < amg["amg_iterations"] < 200, method
        for key in ("err_l2", "err_energy"):
            assert abs(amg[key] - direct[key]) <= 1e-8 * direct[key], (method, key)
    with pytest.raises(SolveError, match="needs a symmetric positive definite system"):
        solve_box_case("confined-block", "lagrange", 30.0, 20.0, (0.37, 0.29, 0.11), 20.0, solver="amg")


def test_error_norms_take_the_whole_cells_through_the_shared_rule():
    """norm_errors evaluates the whole cells' shared Gauss rule cell by cell (FieldEvaluator.in_clear_cells)
    and gives the errors of the point-by-point evaluation; an IBM evaluator without the band width
    (so no cell is known to be clear of the bands) goes point by point."""
    from ibm import norms
    from studies.run.case import CaseSpec, instance_of
    from ibm.small.model import build_model
    from baselines.registry import METHODS
    spec = CaseSpec(problem="manufactured", method="ibm", angle=30.0, cell=5.0, ppc=2)
    instance = instance_of(spec)
    model = build_model(instance.body, instance.parameters.material, instance.loads, spec.cell, spec.ppc)
    solution = METHODS["ibm"](model)
    delta = solution.info["delta"]
    rule = norms.body_rule(model.body, model.grid, 4, delta)
    assert len(rule.whole) > 100 and len(rule.rest) > 0
    fast = norms.norm_errors(model.body, model.grid, model.material, solution.evaluate, instance.exact, delta=delta)
    pointwise = norms.norm_errors(model.body, model.grid, model.material, lambda x, c: solution.evaluate(x, c),
                                   instance.exact, delta=delta)
    for key in ("err_l2", "err_energy"):
        assert abs(fast[key] - pointwise[key]) <= 1e-12 * pointwise[key], key
    called = []
    solution.evaluate.in_clear_cells = lambda *a: called.append(a)
    norms.norm_errors(model.body, model.grid, model.material, solution.evaluate, instance.exact)
    assert not called
