"""The smoke study end to end: runner -> results -> tables (CSV) -> figures -> HTML report -> VTK."""
from __future__ import annotations

import html
import re
from pathlib import Path

import meshio
import numpy as np
import pandas as pd
import pytest

from studies.cli import main
from studies.run.runner import read_results, run_study
from studies.run.seed import PAPER
from studies.run.identity import case_id
from studies.run.spec import load
from studies.report.verdict import scorecard

pytestmark = pytest.mark.slow      # an end-to-end study: `pytest -m "not slow"` leaves it out

SMOKE = Path(__file__).resolve().parents[3] / "studies" / "specs" / "smoke.toml"


@pytest.fixture(scope="module")
def smoke(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("smoke")
    summary = run_study(SMOKE, out, progress=False)
    assert not summary.interrupted and summary.run == summary.total
    return out


def test_every_case_is_stored_and_failures_carry_messages(smoke):
    study, results = load(SMOKE), read_results(smoke)
    assert sorted(results["case_id"]) == sorted(case_id(c) for c in study.cases())
    failed = results[results["status"] == "failed"]
    assert len(failed) >= 1                              # nitsche with gamma = 0.1: indefinite
    nodal = failed["method"] == "nodal"                  # refuses edges off the grid lines (inclined cases)
    assert failed.loc[nodal, "error"].str.startswith(
        "InputError: method 'nodal' needs every essential edge on a grid line").all()
    assert failed.loc[~nodal, "error"].str.startswith("SolveError:").all()
    assert failed["err_u"].isna().all()
    assert (results.loc[results["status"] == "ok", "error"] == "").all()


def test_seed_table_reproduces_the_paper(smoke):
    seed = pd.read_csv(smoke / "tables" / "seed-seed.csv")
    assert seed["angle"].tolist() == list(PAPER)
    for _, row in seed.iterrows():
        paper_u, paper_sigma = PAPER[row["angle"]]
        assert row["paper err_u"] == paper_u and row["paper err_sigma"] == paper_sigma
        assert 0 < row["err_u"] <= paper_u and 0 < row["err_sigma"] <= paper_sigma
    assert seed["at or below paper"].all()


def test_convergence_table_has_fitted_and_level_rates(smoke):
    fitted = pd.read_csv(smoke / "tables" / "h-rates-fitted.csv").set_index("method")
    assert fitted.loc["fem", "fitted rate err_l2"] == pytest.approx(2.0, abs=0.15)
    assert fitted.loc["fem", "fitted rate err_energy"] == pytest.approx(1.0, abs=0.1)
    assert fitted.loc["ibm", "fitted rate err_l2"] > 1.0
    levels = pd.read_csv(smoke / "tables" / "h-rates-levels.csv")
    fem = levels[levels["method"] == "fem"].sort_values("cell", ascending=False)
    assert np.isnan(fem["rate err_l2"].iloc[0])
    h, e = fem["cell"].to_numpy(), fem["err_l2"].to_numpy()
    assert fem["rate err_l2"].iloc[1] == pytest.approx(np.log(e[0] / e[1]) / np.log(h[0] / h[1]), rel=1e-12)


def test_method_angle_table_lists_every_method(smoke):
    from studies.run.spec import load_registries
    methods, _ = load_registries()
    table = pd.read_csv(smoke / "tables" / "angles-method-angle-err_u.csv", index_col=0)
    assert set(table.index) == set(methods)
    assert list(table.columns) == ["0", "30", "60", "90"]
    assert float(table.loc["fem", "30"]) < 1e-10          # body-fitted FEM passes the patch test


def test_html_report_is_self_contained(smoke):
    page = (smoke / "index.html").read_text()
    study = load(SMOKE)
    for sweep in study.sweeps:
        assert f'id="{sweep.name}"' in page
    images = re.findall(r'<img src="([^"]+)"', page)
    live = re.findall(r'<div class="interactive" data-figure="([^"]+)"', page)
    pngs = sorted((smoke / "figures").glob("*.png"))
    assert len(images) + len(live) == len(pngs) and len(images) >= 2 and len(live) == 6
    assert all(src.startswith("data:image/png;base64,") for src in images)
    for anchor in live:       # each interactive figure's data is in the page, and its PNG beside it
        assert f'<script type="application/json" id="{anchor}">{{"panels":' in page
        assert (smoke / "figures" / f"{anchor.removeprefix('data-')}.png").is_file()
    assert page.count("Bokeh.Plotting.show") == 1 and "http://" not in page.split("<footer")[1][:200]
    for link in re.findall(r'href="([^"#][^"]*)"', page):
        assert (smoke / link).is_file(), link           # every link points to a file beside the page
    text = html.unescape(page)
    assert "All six are at or below the paper's numbers." in text
    assert "failed" in page and "SolveError" in page
    assert "numpy" in page and "python" in page.lower()
    assert "[[sweep]]" in text                          # the spec itself


def test_the_verdict_opens_the_report(smoke):
    """The scorecard comes first: a row per method, a column per criterion the smoke spec names, banded cells
    linking to their sweeps, and the sentences of "which method when" with the scorecard's own numbers."""
    page = (smoke / "index.html").read_text()
    assert page.index('id="verdict"') < page.index('id="overview"') < page.index('id="seed"')
    table = page[page.index('id="scorecard"'):page.index("</table>", page.index('id="scorecard"'))]
    methods = sorted(set(read_results(smoke)["method"]))
    assert len(re.findall(r"<tr><th class=\"method\">", table)) == len(methods) + 1
    assert table.count("<th title=") == len(load(SMOKE).verdict) == 7
    assert table.count('class="good"') >= 5 and table.count('class="poor"') >= 1
    for anchor in re.findall(r'<a href="#([^"]+)"', table):
        assert f'id="{anchor}"' in page, anchor
    text = html.unescape(page)
    assert re.search(r"Exactness on a patch test: nitsche, lagrange \(patch test \d\.\d\de-1[3-5]\); poor: lagrange-nodal, nodal\.", text)
    # the overall sentence counts the cost column, measured in seconds: read it from the stored rows, not fixed here
    card = scorecard(load(SMOKE), read_results(smoke))
    assert card.overall.startswith("Of the boundary methods, ") and card.overall in text


def test_error_maps_for_every_method_of_the_sweep(smoke):
    maps = sorted(p.name for p in (smoke / "figures").glob("seed-error-maps-*.png"))
    assert maps == ["seed-error-maps-ibm.png"]
    assert all(p.stat().st_size > 20_000 for p in (smoke / "figures").glob("*.png"))


def test_vtk_files_open_with_the_fields(smoke):
    results = read_results(smoke).set_index("case_id")
    for case in load(SMOKE).sweep("seed").cases:
        key = case_id(case)
        points = meshio.read(smoke / "vtk" / f"{key}_points.vtu")
        assert len(points.points) == results.loc[key, "npoints"]
        for name in ("displacement", "displacement_exact", "stress", "stress_exact", "err_u", "err_sigma"):
            assert name in points.point_data
        error = np.linalg.norm(points.point_data["displacement"] - points.point_data["displacement_exact"], axis=1)
        exact = np.linalg.norm(points.point_data["displacement_exact"], axis=1)
        assert error.max() / exact.max() == pytest.approx(results.loc[key, "err_u_max"], rel=1e-9)
        grid = meshio.read(smoke / "vtk" / f"{key}_grid.vtu")
        assert grid.cells[0].type == "quad"


def test_rerun_reuses_everything_and_report_command(smoke, capsys):
    again = run_study(SMOKE, smoke, progress=False, report=False)
    assert (again.run, again.reused) == (0, again.total)
    assert main(["report", str(smoke)]) == 0
    assert capsys.readouterr().out.strip().endswith("index.html")


def test_report_of_an_empty_folder_is_an_input_error(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "spec.toml is missing" in capsys.readouterr().err


def test_solve_writes_vtk(tmp_path, capsys):
    assert main(["solve", "--angle", "30", "--vtk", str(tmp_path)]) == 0
    names = sorted(p.name for p in tmp_path.glob("*.vtu"))
    assert names == [f"confined-block_ibm_angle30_h10_{k}.vtu" for k in ("body", "grid", "points")]
    body = meshio.read(tmp_path / names[0])
    assert len(body.points) == 4 and list(body.cell_data["edge_kind"][0]) == [2, 2, 1, 2]


def test_scaling_measurement_beside_the_study_enters_the_report(smoke):
    """`make bench` stores reports/scaling beside reports/paper; the report shows it with its exponents."""
    import json
    from studies.report.page import write_report
    rows = []
    for ndof, total, memory in [(10_000, 0.2, 100.0), (40_000, 0.8, 400.0), (160_000, 3.2, 1600.4)]:
        rows.append({"cells": 10, "h": 1.0, "ndof": ndof, "npoints": ndof // 2, "solver": "superlu",
                     "structure": "spd", "time_points": 0.01, "time_assemble": total / 4,
                     "time_factorize": total / 2, "time_substitute": 0.0, "time_linear": total / 2,
                     "time_setup": total / 2, "time_total": total, "setup_ratio": 2.0, "factor_nnz": 1,
                     "solver_memory_mb": None, "peak_memory_mb": memory})
    folder = smoke.parent / "scaling"
    folder.mkdir(exist_ok=True)
    (folder / "scaling.json").write_text(json.dumps({"table": rows}))
    try:
        html = write_report(smoke).read_text()
    finally:
        (folder / "scaling.json").unlink()
    assert '<h2 id="scaling">Performance: scaling' in html
    assert "160000" in html.replace(",", "") and "total 1.00" in html   # time ~ n^1 in this table
    assert "<td>1600</td>" in html.replace(' style="text-align: right;"', "") and "1.6e+03" not in html
    assert "points (s)" in html
    assert (smoke / "figures" / "scaling.png").is_file()
    assert "not measured yet" in write_report(smoke).read_text()


def test_failed_cases_show_their_kind_in_the_case_table_and_the_whole_message_below(smoke):
    from studies.report import tables
    results = read_results(smoke)
    results = results[results["method"] != "nodal"]      # nodal's refusals are InputErrors (test above)
    failed = results[results["status"] == "failed"]
    cases = tables.cases_table(results, {"method": ["nitsche", "ibm"]})
    kinds = cases.loc[cases["status"] == "failed", "error"]
    assert len(kinds) == len(failed) and (kinds == "SolveError").all()
    assert (cases.loc[cases["status"] == "ok", "error"] == "").all()
    messages = tables.failed_table(results)["error"]
    assert messages.str.startswith("SolveError: ").all() and messages.str.len().min() > len("SolveError: ") + 20


def test_results_page_of_the_smoke_study(smoke, tmp_path, capsys, monkeypatch):
    """The documentation page of a study's results: it names the command that rebuilds it, holds the verdict
    and every table of the report, and refuses a page that is not Markdown in one line."""
    monkeypatch.chdir(tmp_path)
    assert main(["results-page", str(smoke), "--out", "smoke.md"]) == 0
    text = (tmp_path / "smoke.md").read_text()
    assert text.startswith("# Results: Smoke study")
    assert "Generated by `ibm-study results-page " in text and "--out smoke.md`" in text
    assert "the study's spec is `smoke.toml`" in text                 # no folder of this machine
    assert "(results-verdict)=" in text and "Exactness on a patch test: nitsche, lagrange (patch test" in text
    page = (smoke / "index.html").read_text()
    assert text.count('<table border="0" class="dataframe data">') == page.count('<table border="0" class="dataframe data">')
    for sweep in load(SMOKE).sweeps:
        assert f"(results-{sweep.name})=" in text
    assert main(["results-page", str(smoke), "--out", "smoke.html"]) == 2
    assert capsys.readouterr().err.strip().endswith("--out 'smoke.html' must name a Markdown page (.md)")
