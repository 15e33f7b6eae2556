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
                                                       "small_study"}


def test_seed_reproduction_beats_the_paper():
    rows = _example("seed_reproduction").main()
    assert [r["angle"] for r in rows] == [90, 45, 30] and all(r["at_or_below_paper"] for r in rows)


def test_custom_body_patch_test_for_every_method():
    results = _example("custom_body").main()
    for method in ("ibm", "nitsche", "lagrange"):
        assert results[method]["err_u"] <= 1e-12 and results[method]["err_sigma"] <= 1e-12, method
    assert 1e-9 < results["penalty"]["err_u"] <= 1e-6          # O(1 / beta0)


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
