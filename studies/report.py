"""The study report: tables (CSV + HTML), figures (PNG) and DIR/index.html from a jinja2 template.

The HTML is self-contained: figures are embedded (base64 PNG, a 256-colour copy to keep the page
light) as well as written beside it in full colour under figures/, tables are inline and also
written as CSV under tables/. Every figure carries a one-line "how to read" caption (READING), a
table of contents at the top links every section, and the footer states the page's own size. It reads only the
output folder (spec.toml, results.parquet, fields/, run.json), so it can be rebuilt any time
with `ibm-study report DIR`.
"""
from __future__ import annotations

import base64
import html
import io
import importlib.metadata
import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import jinja2
import numpy as np
import pandas as pd

from ibm.geometry import InputError
from studies import plots, tables
from studies.store import atomic_write, folder_lock, load_fields, output_folder, read_results
from studies import peer as peer_data
from studies.spec import FIGURES, LARGE_FIGURES, Study, Sweep, case_id, parse

PACKAGES = ("numpy", "scipy", "pandas", "pyarrow", "matplotlib", "jinja2", "shapely", "scikit-fem", "meshio",
            "dask", "distributed", "tqdm", "pypardiso")


@dataclass
class Section:
    name: str
    summary: str
    counts: str
    tables: list = field(default_factory=list)     # (title, html, csv path relative to DIR)
    figures: list = field(default_factory=list)    # Figure
    reading: list = field(default_factory=list)    # sentences
    failed: str = ""
    heading: str = ""                              # defaults to "Sweep: <name>"

    @property
    def title(self) -> str:
        return self.heading or f"Sweep: {self.name}"


@dataclass
class Figure:
    title: str
    uri: str          # data:image/png;base64,... (the page's copy)
    png: str          # the full-colour file, relative to DIR
    how: str          # one line: how to read this figure
    width: int = 0    # pixels of the embedded image (0: unknown)
    height: int = 0


# One line under every figure, by kind: what is drawn and which way is better.
_FAILED = "red crosses on the bottom edge are failed cases"
READING = {
    "error-vs-h": ("each line one series, one panel per error measure; lower is better; the dotted guides have "
                   "slopes 1 and 2, so a line parallel to one converges at that order; " + _FAILED),
    "error-vs-angle": ("each line one series, one panel per error measure; lower is better; a flat line means the "
                       "error does not depend on how the body is inclined to the grid; " + _FAILED),
    "error-vs": "each line one series, one panel per error measure; lower is better; " + _FAILED,
    "cond-vs": ("each line one series; lower means a better-conditioned linear system (1-norm estimate of the "
                "equilibrated matrix); " + _FAILED),
    "error-vs-placement": ("one column per series: each dot one random placement of the body in the grid, the bar "
                           "their median; lower is better, a tall spread means the error depends on where the body "
                           "sits; " + _FAILED),
    "error-maps": ("one column per case, each square one material point coloured by its error (log scale, yellow "
                   "worst), displacement on top and stress below; the outline shows the boundary kind (blue roller, "
                   "black fixed, orange traction, grey free) over the background grid"),
    "error-vs-step": ("each line one case, one panel per error measure; lower is better; a line that climbs with the "
                      "step means the error builds up as the body deforms"),
    "newton-iterations": ("each line one case: the Newton iterations a load step needed (its step cuts included); "
                          "flat and low means every step converged easily, spikes mark the hard steps"),
    "error-vs-h-peer": ("each line one series; lower is better; open circles (where AMPLE-m ran the same case) are "
                        "the peer's own errors, so a line through or below them matches it; the dotted guides have "
                        "slopes 1 and 2; " + _FAILED),
    "stress-profile": ("each marker one material point at the last step, its stress (x) against its initial height "
                       "(y); the black line is the exact solution, so markers on it are exact and scatter is error"),
    "snapshots": ("left to right the body at four load steps: its outline (coloured by boundary kind), the "
                  "background grid, and the points coloured by stress error over the largest exact stress (log "
                  "scale, yellow worst)"),
    "scaling": ("log-log, one line per phase (left) and for memory (right); the fitted exponent p in the legend is "
                "the slope: p = 1 means cost grows in proportion to the unknowns, lower is better"),
}


def how_to_read(kind: str) -> str:
    """The one-line caption of a figure kind ("error-vs-delta" falls back to "error-vs")."""
    for key in (kind, "error-vs" if kind.startswith("error-vs-") else "", "cond-vs" if kind.startswith("cond-vs-") else ""):
        if key in READING:
            return READING[key] + "."
    raise KeyError(f"no how-to-read caption for figure kind {kind!r}")


def page_png(path: Path) -> tuple[bytes, int, int]:
    """The PNG the page embeds and its size in pixels: a 256-colour (adaptive octree palette, no dither)
    optimised copy of the figure, about a third of the full-colour file; the file itself when Pillow cannot load it
    or the copy would not be smaller."""
    data = path.read_bytes()
    try:
        from PIL import Image
    except ImportError:       # matplotlib depends on Pillow, so this is only a guard
        return data, 0, 0
    try:
        with Image.open(io.BytesIO(data)) as image:
            image.load()
            size = image.size
            if image.mode in ("RGBA", "LA", "P"):
                image = image.convert("RGBA")
                flat = Image.new("RGB", image.size, "white")
                flat.paste(image, mask=image.getchannel("A"))
            else:
                flat = image.convert("RGB")
            small = io.BytesIO()
            flat.quantize(256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE).save(
                small, "PNG", optimize=True)
    except OSError:
        return data, 0, 0
    packed = small.getvalue()
    return (packed if len(packed) < len(data) else data), *size


def write_report(out: str | Path, lock: bool = True) -> Path:
    """Build DIR/index.html (and the CSV and PNG files beside it); return its path.
    OutputFolderError (an InputError) if DIR, DIR/tables or DIR/figures cannot be written."""
    out = Path(out)
    if not (out / "spec.toml").exists():
        raise InputError(f"{str(out)!r} holds no study (spec.toml is missing); run `ibm-study run SPEC --out DIR` first")
    if lock:
        with folder_lock(out):
            return _write(out)
    return _write(out)


def _write(out: Path) -> Path:
    study = parse((out / "spec.toml").read_text(), source=str(out / "spec.toml"))
    results = read_results(out)
    for folder in (out, out / "tables", out / "figures"):
        output_folder(folder)
    sections = [_section(out, study, sweep, results) for sweep in study.sweeps] + [_scaling_section(out)]
    run_info = json.loads((out / "run.json").read_text()) if (out / "run.json").exists() else {}
    template = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
                                  autoescape=jinja2.select_autoescape(["html"]))
    values = dict(study=study, sections=sections, run=run_info, environment=environment(),
                  overview=_overview(study, results, run_info), spec_text=study.text,
                  generated=time.strftime("%Y-%m-%d %H:%M:%S"))
    images = sum(len(f.uri) for s in sections for f in s.figures)
    count = sum(len(s.figures) for s in sections)
    page, size = "", 0
    for _ in range(4):   # the footer states the page's own size: render until the number stops changing
        page = template.get_template("report.html").render(**values, page_size=page_size(size, images, count)).encode()
        if len(page) == size:
            break
        size = len(page)
    path = out / "index.html"
    atomic_write(path, lambda handle: handle.write(page))
    return path


def page_size(size: int, images: int, count: int) -> str:
    """'This page: 312 kB, of which 280 kB are its 9 figures ...' (kB = 1000 bytes)."""
    return (f"This page: {size:,} bytes ({size / 1000:.0f} kB), of which {images / 1000:.0f} kB are its {count} "
            f"embedded figure(s) (256-colour PNG; the full-colour files are in figures/).")


def sweep_rows(results: pd.DataFrame, sweep: Sweep) -> pd.DataFrame:
    """The stored rows of the sweep's cases, in sweep order (missing ones left out)."""
    ids = [case_id(c) for c in sweep.cases]
    indexed = results.set_index("case_id", drop=False)
    return indexed.loc[[i for i in ids if i in indexed.index]].reset_index(drop=True)


def _section(out: Path, study: Study, sweep: Sweep, results: pd.DataFrame) -> Section:
    rows = sweep_rows(results, sweep)
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
        _add_figures(out, section, kind, rows, sweep)
    section.reading = reading(sweep, rows)
    if n_failed:
        section.failed = tables.to_html(tables.failed_table(rows))
    return section


def _scaling_section(out: Path) -> Section:
    """Time and peak memory against unknowns, as stored by `make bench` beside the study folder."""
    from studies import scaling
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
    path = scaling.scaling_figure(table, out / "figures" / "scaling.png")
    _embed(out, section, "Time and peak memory against unknowns (log-log, fitted exponents)", path, "scaling")
    exponents = scaling.fitted_exponents(table)
    if exponents:
        section.reading = ["Fitted exponents (time or memory ~ unknowns^p): " + ", ".join(
            f"{key.replace('time_', '').replace('_mb', '')} {value:.2f}" for key, value in exponents.items()) + "."]
    return section


def _add_table(out: Path, section: Section, title: str, frame: pd.DataFrame, stem: str, index: bool = False) -> None:
    path = out / "tables" / f"{section.name}-{stem}.csv"
    path.parent.mkdir(exist_ok=True)
    csv = frame.to_csv(index=index)
    atomic_write(path, lambda handle: handle.write(csv.encode()))
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
    elif kind == "cases":
        _add_table(out, section, "Every case", tables.cases_table(rows, axes), "cases")


def _embed(out: Path, section: Section, title: str, path: Path, kind: str) -> None:
    packed, width, height = page_png(path)
    data = base64.b64encode(packed).decode()
    section.figures.append(Figure(title, f"data:image/png;base64,{data}", path.relative_to(out).as_posix(),
                                  how_to_read(kind), width, height))


def _add_figures(out: Path, section: Section, kind: str, rows: pd.DataFrame, sweep: Sweep) -> None:
    directory = out / "figures"
    stem = f"{section.name}-{kind}"
    axes = sweep.axes
    x = FIGURES[kind]
    if kind in LARGE_FIGURES:
        _add_large_figure(out, section, kind, rows, sweep, directory / f"{stem}.png")
    elif kind == "error-vs-placement":
        path = plots.error_vs_placement(rows, axes, directory / f"{stem}.png")
        _embed(out, section, "Errors over placements of the body in the grid", path, kind)
    elif kind.startswith("error-vs-"):
        path = plots.error_vs(rows, axes, x, directory / f"{stem}.png")
        _embed(out, section, f"Relative errors against {tables.AXIS_LABELS.get(x, x)}", path, kind)
    elif kind.startswith("cond-vs-"):
        path = plots.cond_vs(rows, axes, x, directory / f"{stem}.png")
        _embed(out, section, f"Condition estimate against {tables.AXIS_LABELS.get(x, x)}", path, kind)
    elif kind == "error-maps":
        others = tables.group_axes(axes, exclude=("method",))
        for method in axes["method"]:
            cases = []
            for case in sweep.cases:
                if case.method != method:
                    continue
                fields = load_fields(out, case_id(case))
                if fields is not None:
                    label = ", ".join(f"{_short(k)} = {_value(case, k)}" for k in others) or case.problem
                    cases.append((label, fields))
            if cases:
                path = plots.error_maps(cases, directory / f"{stem}-{method}.png", title=f"method {method}")
                _embed(out, section, f"Per-point relative errors, method {method} (log colour scale)", path, kind)


def _add_large_figure(out: Path, section: Section, kind: str, rows: pd.DataFrame, sweep: Sweep, path: Path) -> None:
    axes = sweep.axes
    if kind == "error-vs-step":
        _embed(out, section, "Relative errors against the load step", plots.error_vs_step(rows, axes, path), kind)
    elif kind == "newton-iterations":
        _embed(out, section, "Newton iterations per load step (tolerance 1e-9)",
               plots.newton_iterations(rows, axes, path), kind)
    elif kind == "error-vs-h-peer":
        peer = {basis: peer_data.ample_points(rows[rows["basis"] == basis], basis)
                for basis in sorted(set(rows["basis"].dropna()))}
        _embed(out, section, "AMPLE's column measure against h, with AMPLE-m's measured errors (circles)",
               plots.error_vs_h_with_peer(rows, axes, path, peer), kind)
    else:
        others = tables.group_axes(axes)
        cases = []
        for case in sweep.cases:
            fields = load_fields(out, case_id(case))
            if fields is not None and "outline" in fields:
                label = ", ".join(f"{_short(k)} = {_value(case, k)}" for k in others) or case.problem
                cases.append((label, fields))
        if not cases:
            return
        if kind == "stress-profile":
            _embed(out, section, "σ_ηη of every point at the last step against its initial height, and the exact curve",
                   plots.stress_profile(cases, path), kind)
        else:
            for index, (label, fields) in enumerate(cases[:6]):   # a few cases: snapshots are large figures
                figure = plots.snapshots(label, fields, path.with_name(f"{path.stem}-{index}.png"))
                _embed(out, section, f"Deformed body and points at chosen steps: {label}", figure, kind)


def _short(key: str) -> str:
    return {"angle": "θ", "cell": "h", "delta_rel": "δ/h", "beta0": "β₀", "gamma": "γ", "nu": "ν"}.get(key, key)


def _value(case, key: str) -> str:
    if key == "offset":
        return "(" + ", ".join(f"{o:.3g}" for o in case.offset) + ")"
    value = getattr(case, key) if hasattr(case, key) and key != "method_parameters" else case.method_parameters.get(key)
    return tables.fmt(value) + ("°" if key == "angle" else "")


# --- a short reading of the results ------------------------------------------------------------

def reading(sweep: Sweep, rows: pd.DataFrame) -> list[str]:
    """Plain sentences with the numbers that matter, generated from the rows."""
    good = tables.ok(rows)
    out = []
    if "seed" in sweep.tables:
        seed = tables.seed_table(rows)
        if len(seed):
            both = seed["at or below paper"].all()
            pairs = "; ".join(f"{tables.fmt(r['angle'])}°: {tables.fmt(r['err_u'])} / {tables.fmt(r['err_sigma'])} "
                              f"(paper {tables.fmt(r['paper err_u'])} / {tables.fmt(r['paper err_sigma'])})"
                              for _, r in seed.iterrows())
            out.append(f"Seed cases, err_u / err_sigma: {pairs}. "
                       + ("All six are at or below the paper's numbers." if both
                          else "Not all six are at or below the paper's numbers."))
    if "convergence" in sweep.tables:
        _, fitted = tables.convergence_tables(rows, sweep.axes)
        groups = tables.group_columns(sweep.axes, exclude=("cell",))
        for _, fit in fitted.iterrows():
            rates = ", ".join(f"{c.removeprefix('fitted rate ')} {tables.fmt(fit[c])}"
                              for c in fitted.columns if c.startswith("fitted rate") and np.isfinite(fit[c]))
            label = tables.series_label(tuple(fit[g] for g in groups), groups) if groups else "all cases"
            out.append(f"Fitted rates against h for {label}: {rates or 'not enough levels'}.")
    if ("method-angle" in sweep.tables or "error-vs-angle" in sweep.figures) and len(good):
        by = ["problem", "method"] if len(sweep.axes["problem"]) > 1 else ["method"]
        for error in tables.error_columns(rows)[:2]:
            worst = good.groupby(by)[error].max().sort_values()
            text = ", ".join(f"{tables.series_label(k, by)} {tables.fmt(v)}" for k, v in worst.items())
            out.append(f"Worst {error} over the angles {tables.fmt(min(sweep.axes['angle']))}–"
                       f"{tables.fmt(max(sweep.axes['angle']))}° (best first): {text}.")
    for axis in ("delta_rel", "beta0", "gamma"):
        if axis in sweep.axes and len(sweep.axes[axis]) > 1:
            groups = tables.group_columns(sweep.axes, exclude=(axis,))
            for key, series in tables._groups(good, groups):
                series = series.dropna(subset=[axis]).sort_values(axis)
                if len(series) < 2:
                    continue
                lo, hi = series.iloc[0], series.iloc[-1]
                text = (f"{tables.series_label(key, groups)}: from {axis} = {tables.fmt(lo[axis])} to "
                        f"{tables.fmt(hi[axis])}, err_u goes from {tables.fmt(lo['err_u'])} to {tables.fmt(hi['err_u'])}")
                if "cond_est" in series and series["cond_est"].notna().all():
                    text += f" and the condition estimate from {tables.fmt(lo['cond_est'])} to {tables.fmt(hi['cond_est'])}"
                best = series.loc[series["err_u"].idxmin()]
                out.append(text + f"; the smallest err_u, {tables.fmt(best['err_u'])}, is at {axis} = {tables.fmt(best[axis])}.")
    if "offset" in sweep.axes and len(sweep.axes["offset"]) > 1 and len(good):
        groups = tables.group_columns(sweep.axes, exclude=("offset",)) or ["method"]
        for key, series in tables._groups(good, groups):
            values = series["err_u"].to_numpy(float)
            if len(values) > 1 and values.min() > 0:
                out.append(f"{tables.series_label(key, groups)}: over {len(values)} placements err_u ranges from "
                           f"{tables.fmt(values.min())} to {tables.fmt(values.max())} "
                           f"(a factor {tables.fmt(values.max() / values.min())}).")
    bad = rows[rows["status"] != "ok"]
    if len(bad):
        kinds = tables.error_kind(bad["error"]).value_counts()
        by_method = bad.groupby("method").size()
        out.append(f"{len(bad)} case(s) failed and show no numbers ("
                   + ", ".join(f"{m}: {n}" for m, n in by_method.items()) + "; "
                   + ", ".join(f"{k} ×{n}" for k, n in kinds.items()) + "); their messages are listed below.")
    return out


def _overview(study: Study, results: pd.DataFrame, run: dict) -> list[str]:
    ids = {case_id(c) for c in study.cases()}
    rows = results[results["case_id"].isin(ids)]
    times = rows["time_s"].dropna() if "time_s" in rows else pd.Series(dtype=float)
    out = [f"{len(ids)} distinct cases in {len(study.sweeps)} sweeps; {int((rows['status'] == 'ok').sum())} solved, "
           f"{int((rows['status'] != 'ok').sum())} failed, {len(ids) - len(rows)} not run yet."]
    if len(times):
        out.append(f"Solver time summed over cases {times.sum():.1f} s (median {times.median() * 1e3:.0f} ms per case).")
    if run:
        where = f"on the dask scheduler {run['scheduler']}" if run.get("scheduler") else f"with {run.get('jobs')} worker processes"
        out.append(f"Last run: {run.get('run')} cases run, {run.get('reused')} reused from earlier runs, {where}, "
                   f"wall time {run.get('wall_s')} s, finished {run.get('finished')}"
                   + (" (interrupted)" if run.get("interrupted") else "") + ".")
    return out


def environment() -> dict:
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    try:
        root = Path(__file__).resolve().parents[1]
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
