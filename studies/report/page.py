"""The study report: tables (CSV + HTML), figures (PNG) and DIR/index.html from a jinja2 template.

The HTML is self-contained: figures are embedded (base64 PNG, a 256-colour copy to keep the page
light) as well as written beside it in full colour under figures/, tables are inline and also
written as CSV under tables/. Every figure carries a one-line "how to read" caption
(studies.report.captions), a table of contents at the top links every section, and the footer states
the page's own size. It reads only the output folder (spec.toml, results.parquet, fields/, run.json),
so it can be rebuilt any time with `ibm-study report DIR`. Each sweep is a section, except the 3D
sweeps (dim = 3 in every case): they share one section, "Three dimensions", where the first of them stands.

This module assembles the page: the sections and their tables. Each section plans its figures
(studies.report.sweep_figures) and reads its results (studies.report.reading); the figures are then
drawn or reused from their cache (studies.report.figures). A rebuild whose page comes out the same
leaves index.html untouched ("Generated" keeps the time its content was first written).
"""
from __future__ import annotations

import html
import importlib.metadata
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import jinja2
import pandas as pd

from ibm.exceptions import InputError
from studies.problems.registry import get as get_problem
from studies.report import interactive, tables
from studies.report.content import Section
from studies.report.figures import PATH, Plan, render_figures
from studies.report.reading import overview, reading
from studies.report.sweep_figures import add_figures
from studies.report.verdict import BANDS, COLOURS, scorecard, shown
from studies.run import scaling
from studies.run.spec import Study, Sweep, parse
from studies.run.store import atomic_write, folder_lock, output_folder, read_results

PACKAGES = ("numpy", "scipy", "pandas", "pyarrow", "matplotlib", "jinja2", "shapely", "scikit-fem", "meshio",
            "dask", "distributed", "tqdm", "pypardiso")
GENERATED = "%Y-%m-%d %H:%M:%S"
THREE_D = "three-dimensions"                        # the one section of every 3D sweep
_STAMP = "@@generated-stamp@@"                      # as long as a GENERATED time: the page size is unchanged


def write_report(out: str | Path, lock: bool = True, jobs: int | None = None) -> Path:
    """Build DIR/index.html (and the CSV and PNG files beside it); return its path. Figures not cached
    are drawn in `jobs` worker processes (default: one per CPU; 1 draws them in this process).
    OutputFolderError (an InputError) if DIR, DIR/tables or DIR/figures cannot be written."""
    out = Path(out)
    require_study(out)
    if lock:
        with folder_lock(out):
            return _write(out, jobs)
    return _write(out, jobs)


def require_study(out: Path) -> None:
    """InputError in one line unless the folder holds a study (`ibm-study run`'s spec.toml)."""
    if not (out / "spec.toml").exists():
        raise InputError(f"{str(out)!r} holds no study (spec.toml is missing); "
                         "run `ibm-study run SPEC --out DIR` first")


def _now() -> str:
    return time.strftime(GENERATED)


def spec_source(out: Path) -> str:
    """Where the spec was run from (run.json), so that the problem files it names resolve as they did."""
    try:
        source = json.loads((out / "run.json").read_text()).get("spec", "")
    except (OSError, ValueError, AttributeError):
        source = ""
    return source if source and Path(source).parent.is_dir() else str(out / "spec.toml")


def _write(out: Path, jobs: int | None = None) -> Path:
    study = parse((out / "spec.toml").read_text(), source=spec_source(out))
    results = read_results(out)
    for folder in (out, out / "tables", out / "figures"):
        output_folder(folder)
    sections, plan = build_sections(out, study, results)
    render_figures(out, plan, jobs)
    run_info = json.loads((out / "run.json").read_text()) if (out / "run.json").exists() else {}
    template = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
                                  autoescape=jinja2.select_autoescape(["html"]))
    anchors = {sweep.name: section_name(sweep) for sweep in study.sweeps}
    values = dict(study=study, sections=sections, run=run_info, environment=environment(),
                  card=scorecard(study, results), shown=shown, bands=BANDS, colours=COLOURS, anchors=anchors,
                  overview=overview(study, results, run_info), spec_text=study.text, generated=_STAMP)
    figures = [f for s in sections for f in s.figures]
    images = sum(len(f.uri) for f in figures if not f.interactive)
    count = sum(1 for f in figures if not f.interactive)
    live = [f for f in figures if f.interactive]
    values["scripts"] = interactive.script() if live else ""
    page, size = "", 0
    for _ in range(4):   # the footer states the page's own size: render until the number stops changing
        page = template.get_template("report.html").render(
            **values, page_size=page_size(size, images, count, len(live), len(values["scripts"]))).encode()
        if len(page) == size:
            break
        size = len(page)
    path = out / "index.html"
    stamp = f'<p class="muted">Generated {_STAMP}'.encode()
    try:
        old = path.read_bytes()
    except OSError:
        old = b""
    start = old.find(stamp[:-len(_STAMP)])
    if start >= 0 and page.replace(stamp, old[start:start + len(stamp)], 1) == old:
        return path        # the same page as before: left as it is, with the time it was first written
    page = page.replace(stamp, stamp[:-len(_STAMP)] + _now().encode(), 1)
    atomic_write(path, lambda handle: handle.write(page))
    return path


def build_sections(out: Path, study: Study, results: pd.DataFrame) -> tuple[list[Section], Plan]:
    """The page's sections (each sweep's tables, written as CSV under DIR/tables, and its reading) and the
    plan of their figures, not drawn yet."""
    plan = Plan(out)
    return _sweep_sections(out, plan, study, results) + [_scaling_section(out, plan)], plan


def page_size(size: int, images: int, count: int, live: int = 0, scripts: int = 0) -> str:
    """'This page: 312 kB, of which 280 kB are its 9 figures ...' (kB = 1000 bytes)."""
    text = (f"This page: {size:,} bytes ({size / 1000:.0f} kB), of which {images / 1000:.0f} kB are its {count} "
            f"embedded figure(s) (256-colour PNG; the full-colour files are in figures/)")
    if live:
        text += (f" and {scripts / 1000:.0f} kB the BokehJS that draws its {live} interactive figure(s) (their PNGs "
                 f"are in figures/ too)")
    return text + "."


def _section(out: Path, plan: Plan, study: Study, sweep: Sweep, results: pd.DataFrame) -> Section:
    rows = tables.sweep_rows(results, sweep.cases)
    n_failed = int((rows["status"] != "ok").sum()) if len(rows) else 0
    missing = len(sweep.cases) - len(rows)
    counts = f"{len(sweep.cases)} cases, {len(rows) - n_failed} solved, {n_failed} failed by design or error"
    if missing:
        counts += f", {missing} not run yet"
    section = Section(sweep.name, sweep.summary, counts)
    if rows.empty:
        return section
    axes = sweep.axes
    for kind in sweep.tables:
        _add_tables(out, section, kind, rows, axes)
    for kind in sweep.figures:
        add_figures(out, plan, section, kind, rows, sweep)
    section.reading = reading(sweep, rows)
    if n_failed:
        section.failed = tables.to_html(tables.failed_table(rows))
    return section


def solid(sweep: Sweep) -> bool:
    """Whether every case of the sweep is 3D (dim = 3)."""
    return all(case.dim == 3 for case in sweep.cases)


def section_name(sweep: Sweep) -> str:
    """The name (and page id) of the section that shows the sweep: its own, or "three-dimensions"."""
    return THREE_D if solid(sweep) else sweep.name


def _sweep_sections(out: Path, plan: Plan, study: Study, results: pd.DataFrame) -> list[Section]:
    """A section per sweep in spec order, the 3D sweeps together in one where the first of them stands."""
    sections, parts = [], []
    for sweep in study.sweeps:
        if solid(sweep):
            if not parts:
                sections.append(None)
            parts.append(_section(out, plan, study, sweep, results))
        else:
            sections.append(_section(out, plan, study, sweep, results))
    return [_three_d_section(parts) if s is None else s for s in sections]


def _three_d_section(parts: list[Section]) -> Section:
    """The sections of the 3D sweeps as one, "Three dimensions": each part's tables, figures and
    reading under its sweep's name."""
    summary = ("The box problems (studies/problems/boxes.py) as cubes in a trilinear grid, each placed at an angle θ about z "
               "and then tilted by ψ about its own ξ axis. ")
    summary += " ".join(f"{p.name}: {p.summary}" for p in parts if p.summary)
    section = Section(THREE_D, summary.strip(), "; ".join(f"{p.name}: {p.counts}" for p in parts),
                      heading="Three dimensions")
    for part in parts:
        section.tables += [(f"{part.name}: {title}", table, csv) for title, table, csv in part.tables]
        for figure in part.figures:
            figure.title = f"{part.name}: {figure.title}"
            section.figures.append(figure)
        section.reading += [f"{part.name}: {line}" for line in part.reading]
        section.failed += part.failed
    return section


def _scaling_section(out: Path, plan: Plan) -> Section:
    """Time and peak memory against unknowns, as stored by `make bench` beside the study folder."""
    folder = out.parent / "scaling"
    table = scaling.load_table(folder)
    summary = ("IBM solve of the confined block at 30 degrees, one process per size: time per phase and "
               "peak resident memory against the number of unknowns")
    if not table:
        return Section("scaling", summary, f"not measured yet: `make bench` writes {folder.as_posix()}",
                       heading="Performance: scaling")
    section = Section("scaling", summary, f"{len(table)} sizes, from {table[0]['ndof']:,} to {table[-1]['ndof']:,} unknowns",
                      heading="Performance: scaling")
    columns = {"ndof": "unknowns", "npoints": "points", "time_points": "points (s)",
               "time_assemble": "assembly (s)", "time_linear": "factorize + solve (s)",
               "time_total": "total (s)", "setup_ratio": "total / solver", "peak_memory_mb": "peak memory (MB)"}
    frame = pd.DataFrame(table)[list(columns)]
    frame["peak_memory_mb"] = frame["peak_memory_mb"].round().astype(int)   # whole MB, not 1.12e+03
    frame = frame.rename(columns=columns)
    _add_table(out, section, "Time and peak memory against unknowns", frame, "scaling")
    plan.add(section, "Time and peak memory against unknowns (log-log, fitted exponents)", "scaling",
             "scaling.png", "scaling.scaling_figure", table, PATH)
    exponents = scaling.fitted_exponents(table)
    if exponents:
        section.reading = ["Fitted exponents (time or memory ~ unknowns^p): " + ", ".join(
            f"{key.replace('time_', '').replace('_mb', '')} {value:.2f}" for key, value in exponents.items()) + "."]
    return section


def _add_table(out: Path, section: Section, title: str, frame: pd.DataFrame, stem: str, index: bool = False) -> None:
    path = out / "tables" / f"{section.name}-{stem}.csv"
    path.parent.mkdir(exist_ok=True)
    csv = frame.to_csv(index=index).encode()
    if not path.is_file() or path.read_bytes() != csv:      # an unchanged table is not written again
        atomic_write(path, lambda handle: handle.write(csv))
    section.tables.append((title, tables.to_html(frame, index=index), path.relative_to(out).as_posix()))


def _add_tables(out: Path, section: Section, kind: str, rows: pd.DataFrame, axes: dict) -> None:
    if kind == "seed":
        _add_table(out, section, "Seed comparison: our IBM beside the paper's six numbers",
                   tables.seed_table(rows), "seed")
    elif kind == "convergence":
        levels, fitted = tables.convergence_tables(rows, axes)
        _add_table(out, section, "Fitted convergence rates (least squares of log error against log h)",
                   fitted, "rates-fitted")
        _add_table(out, section, "Errors and level-to-level rates per grid level", levels, "rates-levels")
    elif kind == "method-angle":
        for error in tables.error_columns(rows)[:2]:
            _add_table(out, section, f"{tables.ERROR_LABELS[error]} ({error}) per series and angle",
                       tables.method_angle(rows, axes, error), f"method-angle-{error}", index=True)
    elif kind == "placements":
        _add_table(out, section, "Errors over placements", tables.placement_table(rows, axes), "placements")
    elif kind == "method-orientation":
        for error in tables.error_columns(rows)[:2]:
            _add_table(out, section, f"{tables.ERROR_LABELS[error]} ({error}) per series and orientation (angle θ, "
                       f"tilt ψ) in degrees", tables.method_orientation(rows, axes, error),
                       f"method-orientation-{error}", index=True)
    elif kind == "cases":
        _add_table(out, section, "Every case", tables.cases_table(rows, axes), "cases")
    elif kind == "collapse":
        for problem in axes["problem"]:
            _add_table(out, section, get_problem(problem).table_title, tables.collapse_table(rows, problem),
                       f"collapse-{problem}")
    elif kind == "contact":
        for problem in axes["problem"]:
            _add_table(out, section, f"{problem}: {get_problem(problem).summary}", tables.contact_table(rows, problem),
                       f"contact-{problem}")


def environment() -> dict:
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    try:
        root = Path(__file__).resolve().parents[2]
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, timeout=5).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
        revision = (commit + (" (with uncommitted changes)" if dirty else "")) if commit else "unknown"
    except (OSError, subprocess.SubprocessError):
        revision = "unknown"
    try:
        project = importlib.metadata.version("ibm-mpm")
    except importlib.metadata.PackageNotFoundError:
        project = "unknown"
    return {"python": sys.version.split()[0], "platform": platform.platform(), "machine": platform.machine(),
            "cpus": os.cpu_count(), "project": project, "revision": revision, "packages": versions}


def escape(text: str) -> str:
    return html.escape(text)
