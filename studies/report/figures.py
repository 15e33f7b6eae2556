"""The page's figures: planned while the sections are built (Plan, one Job per PNG), then drawn or
reused, and the 256-colour copy of each that the page embeds (page_png).

Figures are cached by the content they show: each one's key hashes its kind, the rows (timing columns
left out: no figure shows them) and field files it draws, its axes and labels, and the source of the
code that draws it (VERSION). figures/.cache.json maps each PNG to its key and the digests of the
PNG and of its embedded copy (figures/.cache/NAME); a figure whose key and files match is reused,
the others are drawn in worker processes (spawned, one per CPU) and the page is assembled in the
same order as a serial build, so it is the same byte for byte.
"""
from __future__ import annotations

import base64
import concurrent.futures
import contextlib
import gc
import hashlib
import importlib.metadata
import io
import json
import multiprocessing
import os
import signal
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from studies.report.captions import how_to_read
from studies.report.content import Figure, Section
from studies.run import scaling
from studies.run.store import TIMING_PREFIX, atomic_write


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


CACHE = ".cache.json"          # in figures/: PNG name -> its key and the digests of its two files
PAGE_COPIES = ".cache"         # in figures/: the embedded 256-colour copies, one per PNG, same name
# The code that decides what a figure looks like: a change to any of it draws every figure again.
_DRAWING_SOURCES = (*(f"studies/report/{name}.py" for name in (
    "plots", "canvas", "panels", "sweep_lines", "maps", "large_deformation", "collapse_figures", "contact_figures",
    "figures", "sweep_figures", "page")), "studies/run/scaling.py", "studies/report/tables.py", "ibm/norms.py")
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
            update(pd.util.hash_pandas_object(value[shown], index=True).to_numpy().tobytes())   # rows and index
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


def render_figures(out: Path, plan: Plan, jobs: int | None) -> None:
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
