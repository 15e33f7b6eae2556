"""The scaling study's table, exponents and 3D case (studies.run.scaling; times are measured by make bench, not asserted)."""
from __future__ import annotations

import numpy as np
import pytest

from studies.run import scaling


def _table(dim, ndofs, exponent):
    return [{"dim": dim, "ndof": n, "npoints": n // 3, "time_points": 1e-6 * n, "time_assemble": 1e-6 * n,
             "time_linear": 1e-9 * n ** exponent, "time_total": 2e-6 * n, "time_setup": 1e-6 * n,
             "setup_ratio": 2.0, "peak_memory_mb": 1e-3 * n, "time_factorize": 1e-9 * n ** exponent,
             "time_substitute": 0.0} for n in ndofs]


@pytest.mark.parametrize("dim, ndofs, fitted", [(2, [5_000, 30_000, 120_000], 2), (3, [1_100, 5_500, 34_000], 2)])
def test_exponents_are_fitted_over_the_dimension_s_sizes(dim, ndofs, fitted):
    """2D fits from 20k unknowns up, 3D from 5k: the sizes below are left out of the fit."""
    table = _table(dim, ndofs, 1.5)
    table[0]["time_linear"] *= 10          # an outlier below the fit's threshold changes nothing
    exponents = scaling.fitted_exponents(table)
    assert exponents["time_linear"] == pytest.approx(1.5, abs=1e-12)
    assert exponents["peak_memory_mb"] == pytest.approx(1.0, abs=1e-12)
    assert len([r for r in table if r["ndof"] >= scaling._fit_min(table)]) == fitted


def test_markdown_says_what_the_3d_solve_skips():
    text = scaling.markdown(_table(3, [1_100, 5_500, 34_000], 1.5))
    assert "In 3D no condition number is estimated" in text and "ndof >= 5000" in text
    assert "Below 50,000 unknowns" in scaling.markdown(_table(2, [30_000, 120_000], 1.5))


def test_the_3d_case_is_the_placed_cube():
    """The cube of side 100 at (30, 20): its volume and the five roller faces and a loaded top."""
    body, material, loads = scaling._placed(4, 30.0, 3, 20.0)
    assert body.volume == pytest.approx(1e6, rel=1e-12)
    normals = np.array([w.normal for w in body.walls])
    assert len(normals) == 5 and np.allclose(np.linalg.norm(normals, axis=1), 1)
    assert material.E == 1e4 and material.nu == 0.3


def test_the_2d_case_is_the_square_at_30_degrees_and_one_size_measures():
    """The square of side 100 at 30 degrees, and one small size measured whole (its row's fields)."""
    body, material, loads = scaling._placed(10, 30.0, 2, 0.0)
    assert body.area == pytest.approx(1e4, rel=1e-12) and material.E == 1e4
    row = scaling.measure(10)
    assert row["ndof"] > 2 * 11 ** 2 and row["npoints"] > 100 and row["time_total"] >= row["time_linear"] > 0


def test_the_benchmarks_build_the_same_block_and_scikit_fem_s():
    """benchmarks.common's IBM system and scikit-fem's script at a small size (make bench's pieces)."""
    from benchmarks.common import ibm_assembly, ibm_quadratures, skfem_assembly, skfem_basis, skfem_solve
    K, f = ibm_assembly(ibm_quadratures(10))
    assert K.shape[0] == K.shape[1] == f.shape[0] > 2 * 11 ** 2
    basis = skfem_basis(10)
    u = skfem_solve(basis, skfem_assembly(basis))
    assert u.shape == (2 * 11 ** 2,) and np.abs(u).max() == pytest.approx(10.0 * 100.0 / (1e4 * 0.7 / 1.3 / 0.4),
                                                                          rel=1e-9)


def test_bad_options_one_line(capsys):
    with pytest.raises(SystemExit) as exit_code:
        scaling.main(["--dim", "3", "--cells", "1"])
    assert exit_code.value.code == 2 and "--cells 1 is not allowed" in capsys.readouterr().err
