"""The study report: tables (CSV + HTML), figures (PNG) and DIR/index.html from a jinja2 template.

The HTML is self-contained: figures are embedded (base64 PNG, a 256-colour copy to keep the page
light) as well as written beside it in full colour under figures/, tables are inline and also
written as CSV under tables/. Every figure carries a one-line "how to read" caption (READING), a
table of contents at the top links every section, and the footer states the page's own size. It reads only the
output folder (spec.toml, results.parquet, fields/, run.json), so it can be rebuilt any time
with `ibm-study report DIR`. Each sweep is a section, except the 3D sweeps (dim = 3 in every case):
they share one section, "Three dimensions", where the first of them stands.

Figures are cached by the content they show: each one's key hashes its kind, the rows (timing columns
left out: no figure shows them) and field files it draws, its axes and labels, and the source of the
code that draws it (VERSION). figures/.cache.json maps each PNG to its key and the digests of the
PNG and of its embedded copy (figures/.cache/NAME); a figure whose key and files match is reused,
the others are drawn in worker processes (spawned, one per CPU) and the page is assembled in the
same order as a serial build, so it is the same byte for byte. A rebuild whose page comes out the
same leaves index.html untouched ("Generated" keeps the time its content was first written).
"""
from __future__ import annotations

import base64
import concurrent.futures
import contextlib
import gc
import hashlib
import html
import importlib.metadata
import io
import json
import multiprocessing
import os
import platform
import signal
import subprocess
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import jinja2
import numpy as np
import pandas as pd

from ibm.exceptions import InputError
from studies.problems.registry import collapse_names, get as get_problem
from studies.report import peer as peer_data, tables
from studies.run import scaling
from studies.run.seed import SEED_METHOD
from studies.run.spec import COLLAPSE_FIGURES, FIGURES, LARGE_FIGURES, Study, Sweep, case_id, locking_pairs, parse
from studies.run.store import TIMING_PREFIX, atomic_write, folder_lock, output_folder, read_results

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
    "error-vs-orientation": ("each line one series, one panel per error measure, the orientations (angle θ about "
                             "z, then tilt ψ about the body's own ξ axis) along x in the sweep's order; lower is "
                             "better; a flat line means the error does not depend on how the body sits in the grid; "
                             + _FAILED),
    "error-view-3d": ("the material points of one case in perspective, each dot coloured by its error (log scale, "
                      "yellow worst), displacement left and loaded-direction stress right, inside the box's edges "
                      "(grey), its faces tinted by boundary kind (blue roller, orange traction, grey free)"),
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
    "load-settlement": ("one panel per angle and B/h, one colour per method (dashed: locked, locking none; a method "
                        "listed earlier is drawn wider, so equal curves show as stripes); each dot a converged load "
                        "step; a curve that levels off on the dashed 2 + π line has found Prandtl's collapse pressure, "
                        "one above it overshoots, one still climbing has not collapsed"),
    "pressure-expansion": ("one panel per angle and h, one colour per method (dashed: locked, locking none; a method "
                           "listed earlier is drawn wider, so equal curves show as stripes); each dot a converged load "
                           "step; the thick grey curve is Hill's, so dots on it are right, and a curve that stops at "
                           "the dashed p_lim line has collapsed where it should"),
    "locking": ("one panel per case run both ways: dashed without a remedy for locking (none), solid with B-bar "
                "(fbar), the exact limit dashed black; the gap between the two is what locking adds"),
    "plastic-zones": ("one panel per case (at the sweep's finest h) at its last converged step, each square a "
                      "material point (fem: each triangle, its Gauss points' mean) coloured by the equivalent plastic "
                      "strain on a log scale (dark: most), grey where it stayed elastic; the coloured region is the "
                      "collapse mechanism"),
}


def how_to_read(kind: str) -> str:
    """The one-line caption of a figure kind ("error-vs-delta" falls back to "error-vs")."""
    for key in (kind, "error-vs" if kind.startswith("error-vs-") else "", "cond-vs" if kind.startswith("cond-vs-") else ""):
        if key in READING:
            return READING[key] + "."
    raise KeyError(f"no how-to-read caption for figure kind {kind!r}")


def page_png(path: Path | bytes, pixels: np.ndarray | None = None) -> tuple[bytes, int, int]:
    """The PNG the page embeds and its size in pixels: a 256-colour (adaptive octree palette, no dither)
    optimised copy of the figure (a path or its bytes), about a third of the full-colour file; the file itself
    when Pillow cannot load it or the copy would not be smaller. `pixels`, the figure's (height, width, 3)
    RGB when at hand (studies.report.plots keeps those of the figure it has just written), spare decoding the file."""
    data = path if isinstance(path, bytes) else Path(path).read_bytes()
    try:
        from PIL import Image
    except ImportError:       # matplotlib depends on Pillow, so this is only a guard
        return data, 0, 0
    try:
        flat = Image.fromarray(pixels) if pixels is not None else _opaque(Image, data)
        small = io.BytesIO()
        flat.quantize(256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE).save(
            small, "PNG", optimize=True)
    except OSError:
        return data, 0, 0
    packed = small.getvalue()
    return (packed if len(packed) < len(data) else data), *flat.size


def _opaque(Image, data: bytes):
    """The PNG `data` decoded, as RGB over white."""
    with Image.open(io.BytesIO(data)) as image:
        image.load()
        if image.mode in ("RGBA", "LA", "P"):
            image = image.convert("RGBA")
            flat = Image.new("RGB", image.size, "white")
            flat.paste(image, mask=image.getchannel("A"))
            return flat
        return image.convert("RGB")


# --- figures: planned while the sections are built, drawn (or reused) afterwards ------------------

CACHE = ".cache.json"          # in figures/: PNG name -> its key and the digests of its two files
PAGE_COPIES = ".cache"         # in figures/: the embedded 256-colour copies, one per PNG, same name
GENERATED = "%Y-%m-%d %H:%M:%S"
_STAMP = "@@generated-stamp@@"                      # as long as a GENERATED time: the page size is unchanged
# The code that decides what a figure looks like: a change to any of it draws every figure again.
_DRAWING_SOURCES = ("studies/report/plots.py", "studies/report/page.py", "studies/run/scaling.py", "studies/report/tables.py",
                    "ibm/norms.py")
# Rough drawing cost, so the slow figures start first and the workers finish together.
_COST = {"error_maps": 0, "snapshots": 1, "error_view_3d": 1, "error_vs": 2, "error_vs_step": 3, "cond_vs": 4}

# What the last write_report did with the figures (names): tests and benchmarks read it.
LAST_BUILD: dict = {}


def _version() -> str:
    """A digest of the drawing code and of the libraries that render it."""
    root = Path(__file__).resolve().parents[2]
    digest = hashlib.sha256()
    for name in _DRAWING_SOURCES:
        digest.update(name.encode() + b"\0" + (root / name).read_bytes() + b"\0")
    for package in ("matplotlib", "numpy", "pillow"):
        try:
            digest.update(f"{package} {importlib.metadata.version(package)}\0".encode())
        except importlib.metadata.PackageNotFoundError:
            digest.update(f"{package} -\0".encode())
    return digest.hexdigest()


VERSION = _version()


@dataclass(frozen=True)
class Fields:
    """A reference to fields/ID.npz, loaded only where the figure is drawn; keyed by the file's bytes."""
    path: Path


class _Path:
    """Where the figure's own path goes in the arguments of its drawing function (compared by type: a
    worker process gets a copy)."""


PATH = _Path()


@dataclass
class Job:
    name: str           # the PNG's file name under figures/
    function: str       # "plots.error_vs" or "scaling.scaling_figure"
    args: tuple         # with PATH for the output path and Fields for field files
    kwargs: dict
    figure: "Figure"    # its entry in the page, completed when the figure is drawn or reused
    key: str = ""


class Plan:
    """The figures of the page in page order, and the digests of the field files (each read once)."""

    def __init__(self, out: Path):
        self.out = out
        self.jobs: list[Job] = []
        self._files: dict[Path, str] = {}

    def add(self, section: "Section", caption: str, kind: str, name: str, function: str, /, *args, **kwargs) -> None:
        """Put figure `name` (drawn by function(*args, **kwargs)) next in `section`, captioned `caption`."""
        figure = Figure(caption, "", f"figures/{name}", how_to_read(kind))
        section.figures.append(figure)
        job = Job(name, function, args, kwargs, figure)
        digest = hashlib.sha256(f"{VERSION}\0{kind}\0{name}\0{function}\0".encode())
        self._feed(digest, (args, kwargs))
        job.key = digest.hexdigest()
        self.jobs.append(job)

    def _feed(self, digest, value) -> None:
        """Feed a canonical, typed encoding of `value` (the arguments of a drawing function) to `digest`."""
        update = digest.update
        if isinstance(value, pd.DataFrame):
            shown = [c for c in value.columns if not str(c).startswith(TIMING_PREFIX)]
            update(b"frame" + repr([(str(c), str(value[c].dtype)) for c in shown]).encode())
            update(pd.util.hash_pandas_object(value.index).to_numpy().tobytes())
            for column in shown:
                update(pd.util.hash_pandas_object(value[column], index=False).to_numpy().tobytes())
        elif isinstance(value, Fields):
            if value.path not in self._files:
                self._files[value.path] = hashlib.sha256(value.path.read_bytes()).hexdigest()
            update(b"fields" + self._files[value.path].encode())
        elif isinstance(value, _Path):
            update(b"path")
        elif isinstance(value, np.ndarray):
            update(f"array {value.dtype} {value.shape}".encode() + np.ascontiguousarray(value).tobytes())
        elif isinstance(value, dict):
            update(f"dict {len(value)}".encode())
            for key, item in value.items():          # in order: the order of the axes is drawn too
                self._feed(digest, key)
                self._feed(digest, item)
        elif isinstance(value, (list, tuple)):
            update(f"{type(value).__name__} {len(value)}".encode())
            for item in value:
                self._feed(digest, item)
        elif value is None or isinstance(value, (str, bool, int, float, np.generic)):
            update(f"{type(value).__name__} {value!r}\0".encode())
        else:
            raise TypeError(f"cannot key a figure on a {type(value).__name__}")


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _draw(out: Path, job: Job) -> dict:
    """Draw one figure (here or in a worker): the PNG, its embedded copy; return its cache entry."""
    if job.function.startswith("scaling."):
        module = scaling
    else:
        from studies.report import plots as module
    path = out / "figures" / job.name
    target = path
    if job.function.startswith("scaling."):     # it writes its file itself: atomically through a temporary
        target = path.with_name(f".{path.stem}.{os.getpid()}.tmp.png")

    def resolve(value):
        if isinstance(value, _Path):
            return target
        if isinstance(value, Fields):
            return _Arrays(value.path)
        if isinstance(value, (list, tuple)):
            return type(value)(resolve(v) for v in value)
        return value

    try:
        with _collected_after():
            getattr(module, job.function.split(".", 1)[1])(*resolve(job.args), **job.kwargs)
        if target != path:
            os.replace(target, path)
    finally:
        if target != path:
            target.unlink(missing_ok=True)
    from studies.report.plots import DRAWN

    # the PNG studies.report.plots has just written to `path` and its pixels; a figure that writes itself
    # (studies.run.scaling) is read back
    data, pixels = DRAWN.pop(path, None) or (path.read_bytes(), None)
    packed, width, height = page_png(data, pixels)
    copy = out / "figures" / PAGE_COPIES / job.name
    copy.parent.mkdir(exist_ok=True)
    atomic_write(copy, lambda handle: handle.write(packed))
    return {"key": job.key, "png": _sha(data), "page": _sha(packed), "width": width, "height": height}


class _Arrays(Mapping):
    """The arrays of a fields file, each read when first asked for: a figure needs a few of them (the
    column's profile, the last step's stress of 36 cases of 18 arrays)."""

    def __init__(self, path: Path):
        self._file = np.load(io.BytesIO(path.read_bytes()))
        self._read: dict[str, np.ndarray] = {}

    def __getitem__(self, key: str) -> np.ndarray:
        if key not in self._read:
            self._read[key] = self._file[key]
        return self._read[key]

    def __contains__(self, key) -> bool:
        return key in self._file.files

    def __iter__(self):
        return iter(self._file.files)

    def __len__(self) -> int:
        return len(self._file.files)


@contextlib.contextmanager
def _collected_after():
    """Python's cyclic garbage collector held off while a figure is drawn, and run once after it on what
    the drawing allocated (the closed figure's cycles): matplotlib allocates objects by the hundred
    thousand, and the collector's passes over all that is alive took a tenth of the drawing time."""
    if not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.enable()
        gc.collect(0)


def _quiet_worker() -> None:
    """A figure worker leaves Ctrl-C to the report's process, which stops the pool."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _draw_in_worker(out: str, job: Job) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    return _draw(Path(out), job)


def _reused(out: Path, job: Job, entry: dict | None) -> bytes | None:
    """The embedded copy of a figure whose cache entry matches its key and both of its files, else None."""
    if not entry or entry.get("key") != job.key:
        return None
    try:
        if _sha((out / "figures" / job.name).read_bytes()) != entry.get("png"):
            return None
        packed = (out / "figures" / PAGE_COPIES / job.name).read_bytes()
    except OSError:
        return None
    return packed if _sha(packed) == entry.get("page") else None


def _plots_patched() -> bool:
    """Whether studies.report.plots has been patched in this process (workers would not see the patch)."""
    plots = sys.modules.get("studies.report.plots")
    return plots is not None and any(getattr(plots, name, None) is not value
                                     for name, value in getattr(plots, "PRISTINE", {}).items())


def _render_figures(out: Path, plan: Plan, jobs: int | None) -> None:
    """Reuse every cached figure, draw the rest (in `jobs` worker processes when more than one is to be
    drawn), and complete each Figure of the page; the cache file lists exactly this page's figures."""
    folder = out / "figures"
    for stale in folder.glob(".*.tmp.png"):
        stale.unlink(missing_ok=True)                   # left by a killed build
    try:
        cache = json.loads((folder / CACHE).read_text())
        entries = cache.get("figures", {}) if isinstance(cache, dict) else {}
    except (OSError, ValueError):
        entries = {}
    fresh: dict[str, dict] = {}
    packed: dict[str, bytes] = {}
    todo = []
    for job in plan.jobs:
        copy = _reused(out, job, entries.get(job.name))
        if copy is None:
            todo.append(job)
        else:
            fresh[job.name], packed[job.name] = entries[job.name], copy
    workers = min(jobs or os.cpu_count() or 1, len(todo))
    if workers > 1 and _plots_patched():
        workers = 1
    LAST_BUILD.clear()
    LAST_BUILD.update(drawn=[j.name for j in todo], reused=[j.name for j in plan.jobs if j.name in fresh],
                      workers=workers if todo else 0)
    try:
        if workers > 1:
            order = sorted(todo, key=lambda j: _COST.get(j.function.split(".", 1)[1], 9))
            context = multiprocessing.get_context("spawn")
            pool = concurrent.futures.ProcessPoolExecutor(workers, mp_context=context, initializer=_quiet_worker)
            try:
                futures = {job.name: pool.submit(_draw_in_worker, str(out), job) for job in order}
                for job in todo:
                    fresh[job.name] = futures[job.name].result()
            finally:     # stopped (Ctrl-C) or failed: the figures not begun are dropped, not drawn first
                pool.shutdown(wait=True, cancel_futures=True)
        else:
            for job in todo:
                fresh[job.name] = _draw(out, job)
    finally:      # what was drawn stays cached even when a later figure failed
        kept = {name: fresh[name] for name in dict.fromkeys(j.name for j in plan.jobs) if name in fresh}
        text = json.dumps({"version": VERSION, "figures": kept}, indent=1, sort_keys=True).encode()
        atomic_write(folder / CACHE, lambda handle: handle.write(text))
    copies = folder / PAGE_COPIES
    for stale in (copies.glob("*.png") if copies.is_dir() else ()):
        if stale.name not in kept:
            stale.unlink(missing_ok=True)
    for job in plan.jobs:
        entry = fresh[job.name]
        data = packed.get(job.name)
        if data is None:
            data = (copies / job.name).read_bytes()
        job.figure.uri = "data:image/png;base64," + base64.b64encode(data).decode()
        job.figure.width, job.figure.height = entry["width"], entry["height"]


def write_report(out: str | Path, lock: bool = True, jobs: int | None = None) -> Path:
    """Build DIR/index.html (and the CSV and PNG files beside it); return its path. Figures not cached
    are drawn in `jobs` worker processes (default: one per CPU; 1 draws them in this process).
    OutputFolderError (an InputError) if DIR, DIR/tables or DIR/figures cannot be written."""
    out = Path(out)
    if not (out / "spec.toml").exists():
        raise InputError(f"{str(out)!r} holds no study (spec.toml is missing); run `ibm-study run SPEC --out DIR` first")
    if lock:
        with folder_lock(out):
            return _write(out, jobs)
    return _write(out, jobs)


def _now() -> str:
    return time.strftime(GENERATED)


def _spec_source(out: Path) -> str:
    """Where the spec was run from (run.json), so that the problem files it names resolve as they did."""
    try:
        source = json.loads((out / "run.json").read_text()).get("spec", "")
    except (OSError, ValueError, AttributeError):
        source = ""
    return source if source and Path(source).parent.is_dir() else str(out / "spec.toml")


def _write(out: Path, jobs: int | None = None) -> Path:
    study = parse((out / "spec.toml").read_text(), source=_spec_source(out))
    results = read_results(out)
    for folder in (out, out / "tables", out / "figures"):
        output_folder(folder)
    plan = Plan(out)
    sections = _sweep_sections(out, plan, study, results) + [_scaling_section(out, plan)]
    _render_figures(out, plan, jobs)
    run_info = json.loads((out / "run.json").read_text()) if (out / "run.json").exists() else {}
    template = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
                                  autoescape=jinja2.select_autoescape(["html"]))
    values = dict(study=study, sections=sections, run=run_info, environment=environment(),
                  overview=_overview(study, results, run_info), spec_text=study.text, generated=_STAMP)
    images = sum(len(f.uri) for s in sections for f in s.figures)
    count = sum(len(s.figures) for s in sections)
    page, size = "", 0
    for _ in range(4):   # the footer states the page's own size: render until the number stops changing
        page = template.get_template("report.html").render(**values, page_size=page_size(size, images, count)).encode()
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


def page_size(size: int, images: int, count: int) -> str:
    """'This page: 312 kB, of which 280 kB are its 9 figures ...' (kB = 1000 bytes)."""
    return (f"This page: {size:,} bytes ({size / 1000:.0f} kB), of which {images / 1000:.0f} kB are its {count} "
            f"embedded figure(s) (256-colour PNG; the full-colour files are in figures/).")


def sweep_rows(results: pd.DataFrame, sweep: Sweep) -> pd.DataFrame:
    """The stored rows of the sweep's cases, in sweep order (missing ones left out)."""
    ids = [case_id(c) for c in sweep.cases]
    indexed = results.set_index("case_id", drop=False)
    return indexed.loc[[i for i in ids if i in indexed.index]].reset_index(drop=True)


def _section(out: Path, plan: Plan, study: Study, sweep: Sweep, results: pd.DataFrame) -> Section:
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
        _add_figures(out, plan, section, kind, rows, sweep)
    section.reading = reading(sweep, rows)
    if n_failed:
        section.failed = tables.to_html(tables.failed_table(rows))
    return section


def solid(sweep: Sweep) -> bool:
    """Whether every case of the sweep is 3D (dim = 3)."""
    return all(case.dim == 3 for case in sweep.cases)


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
    section = Section("three-dimensions", summary.strip(), "; ".join(f"{p.name}: {p.counts}" for p in parts),
                      heading="Three dimensions")
    for part in parts:
        section.tables += [(f"{part.name}: {title}", table, csv) for title, table, csv in part.tables]
        for figure in part.figures:
            figure.title = f"{part.name}: {figure.title}"
            section.figures.append(figure)
        section.reading += [f"{part.name}: {line}" for line in part.reading]
        section.failed += part.failed
    return section


def view_case(sweep: Sweep):
    """The case the sweep's error-view-3d shows: the IBM's (else the first method's) at the finest h, at
    the most oblique orientation (the largest tilt, then the angle farthest from the grid's axes)."""
    method = SEED_METHOD if SEED_METHOD in sweep.axes["method"] else sweep.axes["method"][0]
    mine = [c for c in sweep.cases if c.method == method]
    return min(mine, key=lambda c: (c.cell, -c.tilt, -min(c.angle % 90, 90 - c.angle % 90)))


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


def _fields(out: Path, key: str, needs: str = "") -> Fields | None:
    """The case's stored fields (None if it kept none, or none with the array `needs`)."""
    path = out / "fields" / f"{key}.npz"
    if not path.is_file():
        return None
    if needs:
        with np.load(path) as data:
            if needs not in data.files:
                return None
    return Fields(path)


def _add_figures(out: Path, plan: Plan, section: Section, kind: str, rows: pd.DataFrame, sweep: Sweep) -> None:
    stem = f"{section.name}-{kind}"
    axes = sweep.axes
    x = FIGURES[kind]
    if kind in LARGE_FIGURES:
        _add_large_figure(out, plan, section, kind, rows, sweep, f"{stem}.png")
    elif kind in COLLAPSE_FIGURES:
        _add_collapse_figure(out, plan, section, kind, rows, sweep, stem)
    elif kind == "error-vs-placement":
        plan.add(section, "Errors over placements of the body in the grid", kind, f"{stem}.png",
                 "plots.error_vs_placement", rows, axes, PATH)
    elif kind == "error-vs-orientation":
        plan.add(section, "Relative errors against the orientation (angle θ, tilt ψ)", kind, f"{stem}.png",
                 "plots.error_vs_orientation", rows, axes, PATH)
    elif kind == "error-view-3d":
        case = view_case(sweep)
        fields = _fields(out, case_id(case), needs="faces")
        if fields is not None:
            label = _view_label(case)
            plan.add(section, f"Per-point relative errors in 3D, {label} (log colour scale)", kind, f"{stem}.png",
                     "plots.error_view_3d", label, fields, PATH)
    elif kind.startswith("error-vs-"):
        plan.add(section, f"Relative errors against {tables.AXIS_LABELS.get(x, x)}", kind, f"{stem}.png",
                 "plots.error_vs", rows, axes, x, PATH)
    elif kind.startswith("cond-vs-"):
        plan.add(section, f"Condition estimate against {tables.AXIS_LABELS.get(x, x)}", kind, f"{stem}.png",
                 "plots.cond_vs", rows, axes, x, PATH)
    elif kind == "error-maps":
        others = tables.group_axes(axes, exclude=("method",))
        for method in axes["method"]:
            cases = []
            for case in sweep.cases:
                if case.method != method:
                    continue
                fields = _fields(out, case_id(case))
                if fields is not None:
                    label = ", ".join(f"{_short(k)} = {_value(case, k)}" for k in others) or case.problem
                    cases.append((label, fields))
            if cases:
                plan.add(section, f"Per-point relative errors, method {method} (log colour scale)", kind,
                         f"{stem}-{method}.png", "plots.error_maps", cases, PATH, title=f"method {method}")


def _add_collapse_figure(out: Path, plan: Plan, section: Section, kind: str, rows: pd.DataFrame, sweep: Sweep,
                         stem: str) -> None:
    drawing = [get_problem(p) for p in collapse_names() if get_problem(p).curve_figure[0] == kind]
    if drawing:         # one problem's load-displacement curves beside its exact limit
        plan.add(section, drawing[0].curve_figure[1], kind, f"{stem}.png", "plots.collapse_curves",
                 rows[rows["problem"] == drawing[0].name], PATH, ["angle", "cell"])
    elif kind == "locking":
        ids = [case_id(c) for pair in locking_pairs(sweep.cases) for c in pair]
        shown = rows[rows["case_id"].isin(ids)]
        if len(shown):
            plan.add(section, "Locked (locking none) beside remedied (B-bar, fbar), on the same axes", kind,
                     f"{stem}.png", "plots.collapse_curves", shown, PATH, ["problem", "method", "angle", "cell"])
    else:           # at the sweep's finest h, one figure per problem and angle
        finest = min(sweep.axes["cell"]) if "cell" in sweep.axes else sweep.cases[0].cell
        groups: dict[tuple, list] = {}
        for case in sweep.cases:
            fields = _fields(out, case_id(case), needs="alpha") if case.cell == finest else None
            if fields is not None:
                setting = (case.problem, case.angle, case.cell)
                groups.setdefault(setting, []).append((f"{case.method}, locking {case.locking}", fields))
        for index, ((problem, angle, cell), cases) in enumerate(groups.items()):
            label = f"{problem}, θ = {tables.fmt(angle)}°, h = {tables.fmt(cell)}"
            plan.add(section, f"Plastic zones at collapse: {label}", kind, f"{stem}-{index}.png",
                     "plots.plastic_zones", cases, PATH, title=label)


def _view_label(case) -> str:
    return (f"{case.method} on {case.problem} at (θ, ψ) = ({tables.fmt(case.angle)}°, {tables.fmt(case.tilt)}°), "
            f"h = {tables.fmt(case.cell)}")


def _add_large_figure(out: Path, plan: Plan, section: Section, kind: str, rows: pd.DataFrame, sweep: Sweep,
                      name: str) -> None:
    axes = sweep.axes
    if kind == "error-vs-step":
        plan.add(section, "Relative errors against the load step", kind, name, "plots.error_vs_step", rows, axes, PATH)
    elif kind == "newton-iterations":
        plan.add(section, "Newton iterations per load step (tolerance 1e-9)", kind, name,
                 "plots.newton_iterations", rows, axes, PATH)
    elif kind == "error-vs-h-peer":
        peer = {basis: peer_data.ample_points(rows[rows["basis"] == basis], basis)
                for basis in sorted(set(rows["basis"].dropna()))}
        plan.add(section, "AMPLE's column measure against h, with AMPLE-m's measured errors (circles)", kind, name,
                 "plots.error_vs_h_with_peer", rows, axes, PATH, peer)
    else:
        others = tables.group_axes(axes)
        cases = []
        for case in sweep.cases:
            fields = _fields(out, case_id(case), needs="outline")
            if fields is not None:
                label = ", ".join(f"{_short(k)} = {_value(case, k)}" for k in others) or case.problem
                cases.append((label, fields))
        if not cases:
            return
        if kind == "stress-profile":
            plan.add(section, "σ_ηη of every point at the last step against its initial height, and the exact curve",
                     kind, name, "plots.stress_profile", cases, PATH)
        else:
            stem = name.removesuffix(".png")
            for index, (label, fields) in enumerate(cases[:6]):   # a few cases: snapshots are large figures
                plan.add(section, f"Deformed body and points at chosen steps: {label}", kind, f"{stem}-{index}.png",
                         "plots.snapshots", label, fields, PATH)


def _short(key: str) -> str:
    symbols = {name: p.symbol for name, p in tables.PARAMETERS.items() if p.symbol}
    return {"angle": "θ", "tilt": "ψ", "orientation": "(θ, ψ)", "cell": "h", **symbols, "nu": "ν"}.get(key, key)


def _value(case, key: str) -> str:
    if key == "offset":
        return "(" + ", ".join(f"{o:.3g}" for o in case.offset) + ")"
    if key == "orientation":
        return f"({tables.fmt(case.angle)}°, {tables.fmt(case.tilt)}°)"
    if key == "problem_file":       # the file's name: its folder says where it was run, not what it is
        return Path(case.problem_file).name if case.problem_file else "-"
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
    for axis in tables.PARAMETERS:
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
    if ("method-orientation" in sweep.tables or "error-vs-orientation" in sweep.figures) and len(good):
        shown = ", ".join(tables.orientations(rows))
        for error in tables.error_columns(rows)[:2]:
            by = tables.group_columns(sweep.axes, exclude=tables.ORIENTATION_AXES) or ["method"]
            worst = good.groupby(by, sort=False)[error].max().sort_values()
            text = ", ".join(f"{tables.series_label(k, by)} {tables.fmt(v)}" for k, v in worst.items())
            out.append(f"Worst {error} over the orientations (θ, ψ) = {shown} (best first): {text}.")
    if "error-view-3d" in sweep.figures:
        case = view_case(sweep)
        row = rows[rows["case_id"] == case_id(case)]
        if len(row) and row["status"].iloc[0] == "ok":
            row = row.iloc[0]
            out.append(f"The 3D view shows {_view_label(case)}: {int(row['npoints'])} points, the largest "
                       f"|u_h − u| / max |u| {tables.fmt(row['err_u_max'])} (err_u {tables.fmt(row['err_u'])}), "
                       f"the largest stress error over max |σ_ηη| {tables.fmt(row['err_sigma_max'])}.")
    collapse_sweep = bool(set(sweep.axes["problem"]) & set(collapse_names()))
    if "offset" in sweep.axes and len(sweep.axes["offset"]) > 1 and len(good) and not collapse_sweep:
        groups = tables.group_columns(sweep.axes, exclude=("offset",)) or ["method"]
        for key, series in tables._groups(good, groups):
            values = series["err_u"].to_numpy(float)
            if len(values) > 1 and values.min() > 0:
                out.append(f"{tables.series_label(key, groups)}: over {len(values)} placements err_u ranges from "
                           f"{tables.fmt(values.min())} to {tables.fmt(values.max())} "
                           f"(a factor {tables.fmt(values.max() / values.min())}).")
    if collapse_sweep and len(good):
        out += collapse_reading(sweep, good)
    bad = rows[rows["status"] != "ok"]
    if len(bad):
        kinds = tables.error_kind(bad["error"]).value_counts()
        by_method = bad.groupby("method").size()
        out.append(f"{len(bad)} case(s) failed and show no numbers ("
                   + ", ".join(f"{m}: {n}" for m, n in by_method.items()) + "; "
                   + ", ".join(f"{k} ×{n}" for k, n in kinds.items()) + "); their messages are listed below.")
    return out


def collapse_reading(sweep: Sweep, good: pd.DataFrame) -> list[str]:
    """Sentences on the collapse cases (solved rows): per problem, angle and h, each method's collapse
    load against the exact one and which are close; then each locked case beside its remedied twin
    (the sentences are the problem's, studies.problems.collapse.CollapseProblem)."""
    out = []
    locked = ~good["method"].map(tables.body_fitted) & (good.apply(tables.setting, axis=1, args=("locking",)) == "none")
    for (problem, angle, cell), group in good[~locked].groupby(["problem", "angle", "cell"], sort=False):
        names = tables.case_names(group)
        own = get_problem(problem)
        text, ratio = own.reading(group, names, angle, cell)
        target, within = own.target, own.within
        close = names[(ratio - 1).abs() <= within].tolist()
        if close:
            text += f". Within {100 * within:g} % of {target}: {', '.join(close)}."
        else:
            best = int(np.argmin((ratio - 1).abs().to_numpy()))
            text += (f". None is within {100 * within:g} % of {target}; the closest is {names.iloc[best]} "
                     f"({100 * (ratio.iloc[best] - 1):+.1f} %).")
        out.append(text)
    by_id = good.set_index("case_id")
    for none, fbar in locking_pairs(sweep.cases):
        a, b = case_id(none), case_id(fbar)
        if a not in by_id.index or b not in by_id.index:
            continue
        out.append(get_problem(none.problem).locked_reading(none, by_id.loc[a], by_id.loc[b]))
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
