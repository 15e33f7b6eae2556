"""Every example in examples/ runs, and its numbers are what its docstring says."""
import importlib.util
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _example(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_example_is_tested():
    assert {p.stem for p in EXAMPLES.glob("*.py")} == {"seed_reproduction", "custom_body", "inclined_column",
                                                       "small_study", "problem_file_bodies"}


def test_seed_reproduction_beats_the_paper():
    rows = _example("seed_reproduction").main()
    assert [r["angle"] for r in rows] == [90, 45, 30] and all(r["at_or_below_paper"] for r in rows)


def test_custom_body_patch_test_for_every_method():
    results = _example("custom_body").main()
    for method in ("ibm", "nitsche", "lagrange"):
        assert results[method]["err_u"] <= 1e-12 and results[method]["err_sigma"] <= 1e-12, method
    assert 1e-9 < results["penalty"]["err_u"] <= 1e-6          # O(1 / beta0)
    assert results["fem"]["err_u"] <= 1e-12 and results["fem"]["err_sigma"] <= 1e-11   # on a gmsh mesh


@pytest.mark.slow
def test_problem_file_bodies_compared_across_methods():
    results = _example("problem_file_bodies").main()
    bracket = {method: r for (problem, method), r in results.items() if problem == "bracket"}
    assert all(r["reference"] == "fem" and r["reference_converged"] for r in bracket.values())
    for method in ("nitsche", "lagrange"):                    # consistent methods: percent-level at h = 10
        assert bracket[method]["err_l2"] < 0.05 and bracket[method]["err_energy"] < 0.2
    # P2 on a fitted mesh is the most accurate, though the notch's re-entrant corner is singular
    assert bracket["fem"]["err_l2"] < 0.5 * min(r["err_l2"] for m, r in bracket.items() if m != "fem")
    patch = {method: r for (problem, method), r in results.items() if problem == "notched-patch"}
    assert all(r["reference"] == "exact" for r in patch.values())
    assert patch["fem"]["err_l2"] < 1e-3 and patch["nitsche"]["err_l2"] < 0.1


def test_inclined_column_matches_the_exact_curve(tmp_path):
    figure = tmp_path / "column.png"
    record = _example("inclined_column").main(str(figure))
    assert figure.stat().st_size > 10_000
    assert record["err_sigma_ample"] <= 1.5 * 3.658906e-3         # within 1.5x of the 90-degree nodal column
    assert abs(record["height_final"] - record["height_exact"]) <= 0.01 * record["cell"]


def test_small_study_runs_and_resumes(tmp_path):
    example = _example("small_study")
    summary, table = example.main(str(tmp_path))
    assert len(table) == 6 and (table["status"] == "ok").all() and (tmp_path / "index.html").exists()
    assert table.loc[table["method"] == "nitsche", "err_sigma"].max() <= 1e-12
    again, _ = example.main(str(tmp_path))
    assert again.run == 0 and again.reused == 6
