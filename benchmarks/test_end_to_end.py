"""Whole cases through the case runner (problem, model, method, errors): every registered
method at small sizes, the IBM also at larger ones."""
import pytest

from baselines.registry import METHODS
from studies.run.case import CaseSpec, run_case


@pytest.mark.parametrize("cell", [5.0, 2.5])
@pytest.mark.parametrize("method", list(METHODS))
def test_method(benchmark, method, cell):
    spec = CaseSpec(method=method, angle=30.0, cell=cell)
    benchmark.group = f"case h={cell}"
    record = benchmark.pedantic(run_case, args=(spec,), rounds=3, warmup_rounds=1)
    benchmark.extra_info.update(ndof=record["ndof"], err_u=record["err_u"], solver=record.get("solver"))


@pytest.mark.parametrize("cell", [1.0, 0.5, 0.25])
def test_ibm_large(benchmark, cell):
    spec = CaseSpec(method="ibm", angle=30.0, cell=cell)
    benchmark.group = "ibm large"
    record = benchmark.pedantic(run_case, args=(spec,), rounds=2, warmup_rounds=1)
    benchmark.extra_info.update(ndof=record["ndof"], err_u=record["err_u"], solver=record.get("solver"),
                                time_factorize=record["time_factorize"])
