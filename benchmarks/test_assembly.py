"""Assembly into CSR: the IBM (material-point stiffness + band correction + loads) against
scikit-fem's Q1 elasticity assembly at the same number of unknowns."""
import pytest

from benchmarks.common import cells_for, ibm_assembly, ibm_quadratures, skfem_assembly, skfem_basis

SIZES = [20_000, 80_000, 320_000]


@pytest.mark.parametrize("ndof", SIZES)
@pytest.mark.parametrize("ppc", [1, 2])
def test_ibm_assembly(benchmark, ndof, ppc):
    q = ibm_quadratures(cells_for(ndof), ppc)
    benchmark.group = f"assembly {ndof}"
    K, _ = benchmark.pedantic(ibm_assembly, args=(q,), rounds=5, warmup_rounds=1)
    points = len(q.points) + len(q.band)
    benchmark.extra_info.update(ndof=K.shape[0], points=points, band_points=len(q.band),
                                points_per_second=points / benchmark.stats.stats.min)


@pytest.mark.parametrize("ndof", SIZES)
def test_skfem_assembly(benchmark, ndof):
    basis = skfem_basis(cells_for(ndof))
    benchmark.group = f"assembly {ndof}"
    K = benchmark.pedantic(skfem_assembly, args=(basis,), rounds=2 if ndof > 100_000 else 3)
    benchmark.extra_info.update(ndof=K.shape[0])
