"""A plasticity study end to end: the collapse problems in a spec, their records in the store, the
collapse tables, the load-settlement, pressure-expansion, locking and plastic-zone figures, the
reading, and the figure cache (coarse, short runs: a few seconds in all)."""
from __future__ import annotations

import html
import json
import re
import shutil
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from studies.report import figures as report_figures
from studies.report.page import write_report
from studies.run.runner import load_fields, read_results, run_study
from studies.run.identity import case_id
from studies.run.spec import parse

pytestmark = pytest.mark.slow      # an end-to-end study: `pytest -m "not slow"` leaves it out

# The cylinder at h = 20 in 6 steps (the sixth, to 1.05 p_lim, fails with B-bar: p_final = 5/6 of it),
# the footing at B/h = 2 in 5 steps; each locked (none) and remedied (fbar), fem beside the cylinder.
SPEC = textwrap.dedent("""
    title = "plasticity report test"
    [base]
    steps = 6
    ppc = 2
    basis = "mpm"
    [[sweep]]
    name = "hill"
    problems = ["hill-cylinder"]
    methods = ["lagrange", "fem"]
    angle = 30
    cell = 20
    locking = ["none", "fbar"]
    fields = true
    tables = ["collapse"]
    figures = ["pressure-expansion", "locking", "plastic-zones"]
    [[sweep]]
    name = "footing"
    problems = ["footing"]
    methods = ["lagrange"]
    angle = 90
    cell = 80
    steps = 5
    locking = ["none", "fbar"]
    fields = true
    tables = ["collapse"]
    figures = ["load-settlement", "locking", "plastic-zones"]
    """)
FIGURES = {"hill-pressure-expansion.png", "hill-locking.png", "hill-plastic-zones-0.png",
           "footing-load-settlement.png", "footing-locking.png", "footing-plastic-zones-0.png"}


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    spec = tmp_path_factory.mktemp("spec") / "plastic.toml"
    spec.write_text(SPEC)
    out = tmp_path_factory.mktemp("plastic")
    summary = run_study(spec, out, jobs=2, progress=False, report=False)
    assert (summary.total, summary.run, summary.failed) == (5, 5, 0)
    write_report(out, jobs=2)
    assert set(report_figures.LAST_BUILD["drawn"]) == FIGURES
    return out


def _row(results: pd.DataFrame, **settings) -> pd.Series:
    match = np.ones(len(results), bool)
    for name, value in settings.items():
        match &= (results[name] == value).to_numpy()
    assert match.sum() == 1, settings
    return results[match].iloc[0]


def test_the_store_keeps_the_collapse_records_and_their_curves(built):
    results = read_results(built)
    assert (results["status"] == "ok").all()
    remedied = _row(results, problem="hill-cylinder", method="lagrange", locking="fbar")
    locked = _row(results, problem="hill-cylinder", method="lagrange", locking="none")
    # B-bar: the sixth step (to 1.05 p_lim) does not converge, 5 of 6 steps stand; locked: all six
    assert remedied["p_over_p_lim"] == pytest.approx(1.05 * 5 / 6, rel=1e-12)
    assert locked["p_over_p_lim"] == pytest.approx(1.05, rel=1e-12)
    assert len(json.loads(remedied["curve_p"])) == len(json.loads(remedied["newton_iterations"])) == 5
    assert json.loads(locked["curve_p"])[-1] == pytest.approx(1.05 * locked["p_lim"], rel=1e-12)
    assert json.loads(locked["hill_p"])[-1] == pytest.approx(locked["p_lim"], rel=1e-12)
    footing = _row(results, problem="footing", locking="fbar")
    q = json.loads(footing["q"])
    assert len(q) == len(json.loads(footing["settlement"])) == len(json.loads(footing["newton_iterations"])) == 5
    assert max(q) / footing["c"] == pytest.approx(footing["q_over_c"], rel=1e-12)
    assert json.loads(footing["settlement"])[-1] == pytest.approx(0.02 * footing["B"], rel=1e-12)
    assert footing["B_over_h"] == 2


def test_the_fields_hold_the_final_plastic_strain(built):
    study = parse((built / "spec.toml").read_text())
    for case in study.cases():
        fields = load_fields(built, case_id(case))
        assert len(fields["x"]) == len(fields["alpha"]) == len(fields["volume"]) > 100
        assert fields["alpha"].min() >= 0 and fields["alpha"].max() > 0
        # the points where they sit in the body (small strain), not moved by the mechanism's displacement
        low, high = fields["outline_points"].min(axis=0), fields["outline_points"].max(axis=0)
        assert np.all((fields["x"] >= low - 1e-9) & (fields["x"] <= high + 1e-9))
        assert np.sum(fields["volume"]) == pytest.approx(
            np.pi / 4 * (200 ** 2 - 100 ** 2) if case.problem == "hill-cylinder" else 800 * 480, rel=1e-3)
        if case.method == "fem":        # Gauss points, three per triangle, with the triangles
            assert len(fields["triangles"]) * 3 == len(fields["alpha"]) and "grid_h" not in fields
        else:
            assert float(fields["grid_h"]) == case.cell
        if case.problem == "footing":   # the body's 5 B x 3 B, B = 160
            assert np.ptp(fields["outline_points"], axis=0) == pytest.approx([800, 480], rel=1e-12)
            assert 0.1 < np.mean(fields["alpha"] > 0) < 0.6     # the mechanism under the footing yields


def test_the_collapse_tables_give_the_numbers_of_the_store(built):
    results = read_results(built)
    hill = pd.read_csv(built / "tables" / "hill-collapse-hill-cylinder.csv")
    assert list(hill["method"]) == ["lagrange", "lagrange", "fem"] and list(hill["locking"]) == ["none", "fbar", "none"]
    assert list(hill["steps"]) == ["6 of 6", "5 of 6", "5 of 6"]
    for _, line in hill.iterrows():
        row = _row(results, problem="hill-cylinder", method=line["method"], locking=line["locking"])
        assert line["p_final / p_lim"] == pytest.approx(row["p_over_p_lim"], rel=1e-12)
        assert line["Newton iterations"] == sum(json.loads(row["newton_iterations"]))
    gap = hill.filter(like="gap to Hill").iloc[:, 0]
    assert gap.iloc[2] < 0.01 < gap.iloc[1] < 0.1      # fem's P2 triangles follow Hill's curve closest
    footing = pd.read_csv(built / "tables" / "footing-collapse-footing.csv")
    assert list(footing["B/h"]) == [2, 2] and list(footing["locking"]) == ["none", "fbar"]
    assert list(footing["soil"]) == ["von Mises", "von Mises"]
    assert footing["exact q / c"].to_numpy() == pytest.approx(2 + np.pi, rel=1e-12)     # N_c of von Mises soil
    assert footing["q_max / exact"].to_numpy() == pytest.approx(footing["q_max / c"].to_numpy() / (2 + np.pi))
    assert footing["q_max / c"][0] > footing["q_max / c"][1] > 2 + np.pi    # locking adds to a coarse grid's excess


def test_the_page_holds_the_figures_and_the_reading(built):
    page = (built / "index.html").read_text()
    text = html.unescape(re.sub(r"<[^>]+>", " ", page))
    images = [html.unescape(alt) for alt in re.findall(r'<img src="data:image/png;base64,[^"]+" alt="([^"]+)"', page)]
    assert len(images) == len(FIGURES) and {p.name for p in (built / "figures").glob("*.png")} == FIGURES
    for caption in ("Load-settlement curves of every method beside Prandtl's 2 + π",
                    "Pressure-expansion curves of every method beside Hill's",
                    "Locked (locking none) beside remedied (B-bar, fbar), on the same axes",
                    "Plastic zones at collapse: footing, θ = 90°, h = 80"):
        assert caption in images
    assert text.count("How to read:") == len(FIGURES)
    assert "Footing: the peak pressure q_max over c and over its exact N_c (Prandtl's 2 + π on von Mises soil)" in text
    results = read_results(built)
    locked = _row(results, problem="hill-cylinder", method="lagrange", locking="none")
    assert (f"Locked (locking none), lagrange at θ = 30°, h = 20: carries the whole ramp to "
            f"{locked['p_over_p_lim']:.4f} p_lim (6 of 6 steps converged), where B-bar collapses at "
            f"0.8750 p_lim.") in text
    footing = _row(results, problem="footing", locking="fbar")
    assert (f"Footing at θ = 90°, B/h = 2: q_max / c lagrange {footing['q_over_c']:.2f} "
            f"({100 * (footing['q_over_c'] / (2 + np.pi) - 1):+.1f} %). None is within 5 % of 2 + π") in text


def test_a_rerun_reuses_every_case_and_a_changed_curve_redraws_its_figures(built, tmp_path, drawn):
    folder = Path(shutil.copytree(built, tmp_path / "study"))
    again = run_study(folder / "spec.toml", folder, progress=False, report=False)
    assert (again.run, again.reused) == (0, 5)
    write_report(folder)
    assert drawn == []
    study = parse((folder / "spec.toml").read_text())
    key = case_id(next(c for c in study.sweep("footing").cases if c.locking == "fbar"))
    results = pd.read_parquet(folder / "results.parquet")
    at = results["case_id"] == key
    results.loc[at, "q"] = json.dumps([0.5 * q for q in json.loads(results.loc[at, "q"].iloc[0])])
    results.to_parquet(folder / "results.parquet", index=False)
    write_report(folder)
    assert sorted(drawn) == ["footing-load-settlement.png", "footing-locking.png"]


# step cuts: the smooth footing at B/h = 2 halves some of its 5 steps (ibm and lagrange); the
# yielding block settled by 80 % of its height in one large-strain step is cut once, by 40 % not
CUTS = textwrap.dedent("""
    title = "step cuts"
    [[sweep]]
    name = "footing"
    problems = ["footing"]
    methods = ["ibm", "lagrange"]
    angle = 90
    cell = 80
    steps = 5
    ppc = 2
    tables = ["collapse"]
    [[sweep]]
    name = "block"
    problems = ["confined-block"]
    methods = ["ibm"]
    load_type = "settlement"
    kinematics = "large"
    material = "von-mises"
    yield_stress = 1.0
    steps = 1
    cell = 25
    ppc = 2
    angle = 30
    load = [40, 80]
    tables = ["cases"]
    """)


def test_the_tables_show_each_cases_step_cuts(tmp_path):
    spec = tmp_path / "cuts.toml"
    spec.write_text(CUTS)
    out = tmp_path / "out"
    summary = run_study(spec, out, jobs=2, progress=False, report=False)
    assert (summary.run, summary.failed) == (4, 0)
    write_report(out, jobs=1)
    results = read_results(out)
    footing = pd.read_csv(out / "tables" / "footing-collapse-footing.csv")
    assert list(footing["method"]) == ["ibm", "lagrange"]
    for _, line in footing.iterrows():
        assert line["step cuts"] == _row(results, problem="footing", method=line["method"])["step_cuts"]
    assert list(footing["step cuts"]) == [4, 1]                # measured: ibm halves 4 times, lagrange once
    block = pd.read_csv(out / "tables" / "block-cases.csv")
    assert list(block["load"]) == [40, 80] and list(block["step cuts"]) == [0, 1]
    assert list(block.columns[-2:]) == ["step cuts", "error"]
    for key, cuts in zip(block["case_id"], block["step cuts"]):
        assert results.set_index("case_id").loc[key, "step_cuts"] == cuts
    assert len(re.findall(r"<th[^>]*>step cuts</th>", (out / "index.html").read_text())) == 2   # both tables' heads
    from studies.report import tables
    blocks = results[results["problem"] == "confined-block"]
    assert "step cuts" in tables.cases_table(blocks, {"load": [40, 80]}).columns
    assert "step cuts" not in tables.cases_table(blocks.assign(step_cuts=np.nan), {"load": [40, 80]}).columns
