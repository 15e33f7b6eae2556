"""The side-by-side comparison with scikit-fem as a benchmark that prints its ratios.

Size from BENCH_COMPARE_DOFS (default 500000); the ratios go into the
benchmark JSON (extra_info) and are printed (run with -s to see them)."""
import os

from benchmarks.compare import compare, report


def test_side_by_side_with_skfem(benchmark):
    ndof = int(os.environ.get("BENCH_COMPARE_DOFS", "500000"))
    benchmark.group = "side by side"
    row = benchmark.pedantic(compare, args=(ndof,), rounds=1, iterations=1)
    print("\n" + report(row))
    benchmark.extra_info.update({k: v for k, v in row.items() if k != "targets_met"})
    benchmark.extra_info.update({f"target_{k}": v for k, v in row["targets_met"].items()})
