"""The linear solve of the IBM system (equilibration, factorization, substitution, residual
check) per backend, and the bare factorization + substitution."""
import pytest
import scipy.sparse as sp

from benchmarks.common import cells_for, ibm_assembly, ibm_quadratures
from ibm.solvers import backends as solvers
from ibm.discretise.assembly import restrict
from ibm.solvers.linear import active_dofs, equilibrate, scaled, solve_system

SIZES = [5_000, 20_000, 80_000, 320_000]


def ibm_system(ndof):
    q = ibm_quadratures(cells_for(ndof))
    K, f = ibm_assembly(q)
    dofs = active_dofs(q.model.grid, q.points.cells, q.band.cells)
    return restrict(K, dofs), f[dofs]


@pytest.mark.parametrize("ndof", SIZES)
@pytest.mark.parametrize("backend", solvers.available())
def test_solve_system(benchmark, ndof, backend):
    if backend == "superlu" and ndof > 100_000:
        pytest.skip("SuperLU at this size takes minutes")
    A, b = ibm_system(ndof)
    benchmark.group = f"solve {ndof}"
    x, info = benchmark.pedantic(solve_system, args=(A, b), kwargs=dict(solver=backend, estimate_condition=False),
                                 rounds=3, warmup_rounds=1)
    benchmark.extra_info.update(ndof=A.shape[0], structure=info["structure"], residual=info["residual"],
                                factor_nnz=info.get("factor_nnz"))


@pytest.mark.parametrize("ndof", SIZES)
@pytest.mark.parametrize("backend", solvers.available())
def test_bare_factorize_and_solve(benchmark, ndof, backend):
    if backend == "superlu" and ndof > 100_000:
        pytest.skip("SuperLU at this size takes minutes")
    A, b = ibm_system(ndof)
    s = equilibrate(A)
    As = scaled(sp.csr_matrix(A), s)

    def run():
        lu = solvers.factorize(As, "spd", backend)
        x = lu.solve(s * b)
        lu.free()
        return x

    benchmark.group = f"solve {ndof}"
    benchmark.pedantic(run, rounds=3, warmup_rounds=1)
    benchmark.extra_info.update(ndof=A.shape[0])
