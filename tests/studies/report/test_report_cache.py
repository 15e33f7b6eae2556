"""The report's figure cache: a rebuild with nothing changed draws nothing and writes the same page, a
changed result redraws exactly the figures that show it, and figures drawn in worker processes give
the same files and page as a serial build."""
from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from studies.report import figures as report_figures, page as report
from studies.report.page import write_report
from studies.run.runner import run_study
from studies.run.identity import case_id
from studies.run.spec import parse

# 5 small cases: two row figures of one sweep, one of another, and the error maps of a sweep with fields
SPEC = textwrap.dedent("""
    title = "report cache test"
    [base]
    problem = "confined-block"
    cell = 20.0
    [[sweep]]
    name = "angles"
    methods = ["ibm"]
    angle = [0, 60]
    figures = ["error-vs-angle"]
    [[sweep]]
    name = "delta"
    methods = ["ibm"]
    angle = 30
    delta_rel = [1e-3, 1e-5]
    figures = ["error-vs-delta", "cond-vs-delta"]
    [[sweep]]
    name = "maps"
    methods = ["ibm"]
    angle = 45
    fields = true
    figures = ["error-maps"]
    """)
FIGURES = {"angles-error-vs-angle.png", "delta-error-vs-delta.png", "delta-cond-vs-delta.png",
           "maps-error-maps-ibm.png"}


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    spec = tmp_path_factory.mktemp("spec") / "cache.toml"
    spec.write_text(SPEC)
    out = tmp_path_factory.mktemp("cache")
    summary = run_study(spec, out, jobs=1, progress=False, report=False)
    assert summary.run == summary.total == 5
    write_report(out, jobs=1)
    assert set(report_figures.LAST_BUILD["drawn"]) == FIGURES
    return out


@pytest.fixture
def folder(built, tmp_path) -> Path:
    """A copy of the built study: the cache is keyed by content, not by where the folder is."""
    return Path(shutil.copytree(built, tmp_path / "study"))


def _pngs(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((out / "figures").glob("*.png"))}


def test_a_rebuild_with_nothing_changed_draws_nothing_and_writes_the_same_page(folder, drawn):
    write_report(folder)
    assert drawn == [] and report_figures.LAST_BUILD["drawn"] == []       # a copied folder reuses every figure
    assert set(report_figures.LAST_BUILD["reused"]) == FIGURES
    page, figures = (folder / "index.html").read_bytes(), _pngs(folder)
    written = (folder / "index.html").stat().st_mtime_ns
    write_report(folder)
    assert drawn == [] and report_figures.LAST_BUILD["drawn"] == []
    assert (folder / "index.html").read_bytes() == page and _pngs(folder) == figures
    assert (folder / "index.html").stat().st_mtime_ns == written   # not even written again
    live = page.count(b'<div class="interactive" data-figure="')       # drawn in the browser, PNG in figures/
    assert page.count(b'<img src="data:image/png;base64,') + live == len(FIGURES) and live >= 1


def test_one_changed_result_redraws_exactly_the_figures_of_its_sweep(folder, drawn):
    study = parse((folder / "spec.toml").read_text())
    key = case_id(study.sweep("delta").cases[0])
    results = pd.read_parquet(folder / "results.parquet")
    before = (folder / "index.html").read_bytes()
    timing = [c for c in results.columns if c.startswith("time")]
    assert timing
    results.loc[results["case_id"] == key, timing] = 123.0     # timings are not drawn: nothing to redraw
    results.to_parquet(folder / "results.parquet", index=False)
    write_report(folder)
    assert drawn == []
    results.loc[results["case_id"] == key, "err_u"] *= 1.5
    results.to_parquet(folder / "results.parquet", index=False)
    write_report(folder)
    assert sorted(drawn) == sorted(report_figures.LAST_BUILD["drawn"]) == ["delta-cond-vs-delta.png",
                                                                    "delta-error-vs-delta.png"]
    assert (folder / "index.html").read_bytes() != before
    drawn.clear()
    write_report(folder)
    assert drawn == []


def test_changed_fields_redraw_their_error_maps(folder, drawn):
    study = parse((folder / "spec.toml").read_text())
    path = folder / "fields" / f"{case_id(study.sweep('maps').cases[0])}.npz"
    with np.load(path) as data:
        fields = {k: data[k] for k in data.files}
    fields["u_h"] = fields["u_h"] * (1 + 1e-3)
    np.savez_compressed(path, **fields)
    write_report(folder)
    assert drawn == ["maps-error-maps-ibm.png"]


def test_changed_drawing_code_or_a_damaged_file_redraws(folder, drawn, monkeypatch):
    (folder / "figures" / "angles-error-vs-angle.png").write_bytes(b"not the figure")
    (folder / "figures" / ".cache" / "delta-cond-vs-delta.png").unlink()
    write_report(folder)
    assert sorted(drawn) == ["angles-error-vs-angle.png", "delta-cond-vs-delta.png"]
    drawn.clear()
    monkeypatch.setattr(report_figures, "VERSION", "other drawing code")
    write_report(folder)
    assert sorted(drawn) == sorted(FIGURES)


def test_a_parallel_build_equals_a_serial_build_byte_for_byte(folder, monkeypatch):
    monkeypatch.setattr(report, "_now", lambda: "2000-01-01 00:00:00")

    def cold(jobs: int) -> tuple[bytes, dict[str, bytes]]:
        shutil.rmtree(folder / "figures")
        (folder / "index.html").unlink()
        write_report(folder, jobs=jobs)
        assert set(report_figures.LAST_BUILD["drawn"]) == FIGURES and report_figures.LAST_BUILD["workers"] == jobs
        return (folder / "index.html").read_bytes(), _pngs(folder)

    serial, parallel = cold(1), cold(2)
    assert parallel[0] == serial[0]
    assert parallel[1] == serial[1] and set(serial[1]) == FIGURES
