"""A documentation page of a study's results (MyST Markdown for the Sphinx site): the verdict, then each
section's reading and tables, built from the study's stored results as the HTML report is, so that no
number on the site is typed by hand. The page names the command that rebuilds it:

    ibm-study results-page reports/paper --out docs/results/paper.md
"""
from __future__ import annotations

import time
from pathlib import Path

import jinja2

from ibm.exceptions import InputError
from studies.report.page import build_sections, environment, require_study, section_name, spec_source
from studies.report.verdict import COLOURS, scorecard, shown
from studies.run.identity import case_id
from studies.run.spec import parse
from studies.run.store import atomic_write, folder_lock, output_folder, read_results

def write_results_page(out: str | Path, page: str | Path) -> Path:
    """Write `page` (Markdown) from the study stored in `out`; return its path. InputError in one line if
    `out` holds no study or `page` is not a .md file in a folder that exists."""
    out, page = Path(out), Path(page)
    require_study(out)
    if page.suffix != ".md":
        raise InputError(f"--out {str(page)!r} must name a Markdown page (.md)")
    if not page.parent.is_dir():
        raise InputError(f"--out {str(page)!r}: the folder {str(page.parent)!r} does not exist")
    with folder_lock(out):
        text = results_markdown(out, page)
    atomic_write(page, lambda handle: handle.write(text.encode()))
    return page


def results_markdown(out: Path, page: Path) -> str:
    """The page's text for the study stored in `out`."""
    source = out / "spec.toml"
    study = parse(source.read_text(), source=spec_source(out))
    results = read_results(out)
    for folder in (out, out / "tables"):
        output_folder(folder)
    sections, _ = build_sections(out, study, results)
    ids = {case_id(c) for c in study.cases()}
    rows = results[results["case_id"].isin(ids)] if len(results) else results
    anchors = {sweep.name: f"results-{section_name(sweep)}" for sweep in study.sweeps}
    template = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
                                  autoescape=False, keep_trailing_newline=True)
    return template.get_template("results.md").render(
        study=study, sections=[s for s in sections if s.tables or s.reading], card=scorecard(study, rows),
        shown=shown, colours=COLOURS, anchors=anchors, folder=_shown_path(out), page=_shown_path(page),
        spec=_shown_path(Path(study.source)),
        solved=int((rows["status"] == "ok").sum()) if len(rows) else 0, total=len(ids),
        revision=environment()["revision"], date=time.strftime("%Y-%m-%d"))


def _shown_path(path: Path) -> str:
    """A path as the page shows it: relative to the working folder where it lies inside it, else its name."""
    try:
        return path.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return path.name
