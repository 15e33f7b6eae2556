"""The results store of an output folder: the results table (parquet), per-case fields (npz),
atomic writes and the folder lock.

Its part of the output folder (the whole layout is in studies.run.runner):
    results.parquet    one row per finished case, keyed by case_id (a hash of its settings)
    results.log        the cases finished since the table was last written, one JSON line each
    fields/ID.npz      per-point fields of the cases whose sweep keeps fields
    .lock              held while a run or report writes here

A finished case costs one appended line (O(1), flushed to the system at once, synced to disk at
most once a second), not a rewrite of the table; the run compacts the log into the table when
it ends (also when interrupted), and every reader merges table and log, so a killed run loses
no finished case. A line a kill cut short is the log's last and is dropped (its case runs
again). The table and fields files are written to a temporary file beside them and renamed
over them (atomic_write), so a kill never leaves half of one; Store removes the temporaries a
killed run left. The table is kept sorted by case_id with a fixed column order (frame_of), so
the same cases give the same table whatever order they finished in. The runner writes here through
Store; the report reads through read_results and load_fields; both hold folder_lock meanwhile.

Faults of the environment are one-line errors: a folder that cannot be created or written is an
OutputFolderError (an InputError: the user picks another), a write that fails during a run
(disk full) a RunError (a SolveError) naming the file; the table keeps every case stored before.
A results.parquet that is no results table (garbage bytes, other columns) is moved aside to
results.parquet.corrupt-TIME with a warning, and its cases run again; so is a log with lines
that are no rows (its readable rows are kept).
"""
from __future__ import annotations

import dataclasses
import errno
import fcntl
import io
import json
import os
import platform
import sys
import time
from contextlib import contextmanager, suppress
from pathlib import Path

import numpy as np
import pandas as pd

from ibm.exceptions import FolderBusy, InputError, OutputFolderError, RunError, StoreUnreadable
from studies.run.case import CaseSpec
from studies.run.identity import case_settings

RESULTS = "results.parquet"
LOG = "results.log"
LOCK = ".lock"
SYNC_SECONDS = 1.0
SETTING_COLUMNS = ("case_id", "status", "error")
TIMING_PREFIX = "time"






def reason(error: OSError) -> str:
    """Why an OSError happened, in lower case ("no space left on device"), however it was raised."""
    code = error.errno if error.errno is not None else next((a for a in error.args if isinstance(a, int)), None)
    text = error.strerror or (os.strerror(code) if code is not None else " ".join(str(error).split()))
    return text[:1].lower() + text[1:]


def output_folder(path: str | Path) -> Path:
    """Create the folder `path` if needed and check that a file can be written in it."""
    path = Path(path)
    try:
        if path.exists() and not path.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, "it is a file, not a folder")
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".write-test.{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError as error:
        raise OutputFolderError(f"cannot write to output folder {str(path)!r}: {reason(error)}") from None
    return path


# --- rows and the results table ---------------------------------------------------------------

def row_of(key: str, case: CaseSpec, result: dict) -> dict:
    """One flat row: identity, status, the case's settings, then its results."""
    settings = case_settings(case)
    row = {"case_id": key, "status": result["status"], "error": result["error"]}
    for name, value in settings.items():
        if name == "offset":                     # (x, y), or (x, y, z) in 3D
            row.update(zip(("offset_x", "offset_y", "offset_z"), value))
        elif name == "method_parameters":
            row["parameters"] = json.dumps(value, sort_keys=True)
            row.update(value)
        else:
            row[name] = value
    for name, value in result.items():
        if name in row or name in ("status", "error", "offset"):
            continue
        row[name] = value if value is None or np.isscalar(value) else json.dumps(value)
    return row


def column_order(columns) -> list[str]:
    settings = [f.name for f in dataclasses.fields(CaseSpec) if f.name not in ("offset", "method_parameters")]
    lead = list(SETTING_COLUMNS) + settings[:5] + ["offset_x", "offset_y", "offset_z"] + settings[5:] + ["parameters"]
    present = [c for c in lead if c in columns]
    return present + sorted(c for c in columns if c not in present)


def timing_columns(columns) -> list[str]:
    return [c for c in columns if c.startswith(TIMING_PREFIX)]


def frame_of(rows: dict[str, dict]) -> pd.DataFrame:
    """Rows (id -> row) as a table sorted by case_id, in a fixed column order."""
    frame = pd.DataFrame([rows[k] for k in sorted(rows)])
    if frame.empty:
        return pd.DataFrame(columns=list(SETTING_COLUMNS))
    return frame[column_order(frame.columns)].reset_index(drop=True)


def atomic_write(path: Path, write) -> None:
    """write(file_object) into a temporary file beside `path`, then rename it over `path`."""
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(temporary, "wb") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:
        with suppress(OSError):
            temporary.unlink(missing_ok=True)     # a full disk keeps no half-written copy
        raise


class Store:
    """The results of one output folder, table and log (call only while holding its lock)."""

    def __init__(self, out: Path):
        self.path = Path(out) / RESULTS
        self.log = Path(out) / LOG
        for pattern in (f".{RESULTS}.*.tmp", "fields/.*.tmp", "vtk/.*.tmp.vtu", "vtk/.*.tmp.pvd"):
            for stale in Path(out).glob(pattern):
                stale.unlink()      # left by a killed run; the files they were to replace are intact
        self.rows: dict[str, dict] = {}
        self._handle = None
        self._synced = 0.0
        if self.path.exists():
            try:
                table = _table(self.path)
            except StoreUnreadable as error:    # kept beside, never deleted: its cases run again
                aside = _move_aside(self.path)
                print(f"ibm-study: warning: {error}; moved it to {str(aside)!r}, its cases run again",
                      file=sys.stderr, flush=True)
                table = None
            if table is not None:
                for row in table.to_dict("records"):
                    self.rows[row["case_id"]] = {k: v for k, v in row.items() if not _missing(v)}
        if self.log.exists():
            rows, problem = _log_rows(self.log)
            self.rows.update(rows)
            if problem == "corrupt":            # kept beside; its readable rows are in the table
                aside = _move_aside(self.log)
                print(f"ibm-study: warning: {str(self.log)!r} holds lines that are no results rows; moved it to "
                      f"{str(aside)!r}, its {len(rows)} readable case(s) kept, the others run again",
                      file=sys.stderr, flush=True)
                self.compact()
            elif problem == "torn":             # a kill cut the last line short: drop it, keep the rest
                self.compact()

    def add(self, key: str, row: dict) -> None:
        """Store `row` at once (one appended line); RunError naming the log if it cannot be written
        (everything stored before stays)."""
        line = (json.dumps({"case_id": key, **row}, default=_plain, allow_nan=True) + "\n").encode()
        try:
            if self._handle is None:
                self._handle = open(self.log, "ab")
            write_line(self._handle, line)
            now = time.monotonic()
            if now - self._synced >= SYNC_SECONDS:
                os.fsync(self._handle.fileno())
                self._synced = now
        except OSError as error:
            raise RunError(f"cannot write {str(self.log)!r}: {reason(error)}; it keeps the {len(self.rows)} "
                           f"case(s) stored before, run again to finish the rest") from None
        self.rows[key] = row

    def compact(self) -> None:
        """Write every row into the table (atomically), then drop the log; RunError if it cannot."""
        self.close()
        frame = frame_of(self.rows)
        try:
            atomic_write(self.path, lambda handle: frame.to_parquet(handle, index=False))
            self.log.unlink(missing_ok=True)     # a kill just before: its rows are the table's too
        except OSError as error:
            raise RunError(f"cannot write {str(self.path)!r}: {reason(error)}; the {len(self.rows)} stored "
                           f"case(s) stay in {str(self.log)!r}, run again to finish") from None

    def close(self) -> None:
        if self._handle is not None:
            with suppress(OSError):
                self._handle.close()
            self._handle = None

    def status(self, key: str) -> str | None:
        row = self.rows.get(key)
        return None if row is None else row.get("status")


def write_line(handle, line: bytes) -> None:
    """Append one line and hand it to the system (a killed process loses nothing written)."""
    handle.write(line)
    handle.flush()


def _plain(value):
    """numpy scalars as Python ones for JSON."""
    return value.item() if hasattr(value, "item") else str(value)


def _log_rows(path: Path) -> tuple[dict[str, dict], str | None]:
    """Rows of the log by case_id (later lines win), and what was wrong: None, "torn" (a last line
    cut short, as a kill leaves it) or "corrupt" (other lines that are no rows)."""
    try:
        data = path.read_bytes()
    except OSError as error:
        raise InputError(f"cannot read {str(path)!r}: {reason(error)}") from None
    lines = data.split(b"\n")
    rows, problem = {}, None
    for number, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
            if not isinstance(row, dict) or not isinstance(row.get("case_id"), str) or "status" not in row:
                raise ValueError("no results row")
        except ValueError:
            last = number == len(lines) - 1          # no newline after it: cut short by a kill
            problem = problem or ("torn" if last else "corrupt")
            if not last:
                problem = "corrupt"
            continue
        rows[row["case_id"]] = {k: v for k, v in row.items() if v is not None}
    if problem is None and data and not data.endswith(b"\n"):
        problem = "torn"
    return rows, problem


def _missing(value) -> bool:
    return value is None or (isinstance(value, float) and np.isnan(value))


def read_results(out: str | Path) -> pd.DataFrame:
    """The results table of `out`: the stored table and the cases its log holds since (a run
    that is going on, or was killed), sorted by case_id."""
    path, log = Path(out) / RESULTS, Path(out) / LOG
    if not path.exists() and not log.exists():
        raise InputError(f"no results in {str(out)!r}: {RESULTS} is missing (run a study there first)")
    try:
        table = _table(path) if path.exists() else None
    except StoreUnreadable as error:
        raise StoreUnreadable(f"{error}; `ibm-study run` with this --out moves it aside and runs its cases "
                              f"again") from None
    if not log.exists():
        return table
    rows, _ = _log_rows(log)
    if not rows:
        return table if table is not None else frame_of({})
    merged = {} if table is None else {row["case_id"]: {k: v for k, v in row.items() if not _missing(v)}
                                       for row in table.to_dict("records")}
    merged.update(rows)
    return frame_of(merged)


def _table(path: Path) -> pd.DataFrame:
    """The results table at `path`; StoreUnreadable if its bytes are no results table."""
    # One read through one handle: the writer replaces the file atomically, but a reader that
    # opens the path twice (pyarrow reads the footer, then the pages) can mix two versions.
    try:
        data = path.read_bytes()
    except OSError as error:
        raise InputError(f"cannot read {str(path)!r}: {reason(error)}") from None
    try:
        table = pd.read_parquet(io.BytesIO(data))
    except Exception as error:      # pyarrow's errors for bytes that are no parquet file
        raise StoreUnreadable(f"{str(path)!r} is not a readable parquet file "
                              f"({_said(error)})") from None
    missing = [c for c in ("case_id", "status") if c not in table.columns]
    if missing:
        raise StoreUnreadable(f"{str(path)!r} is no results table (it has no {' or '.join(missing)} column)")
    return table


def _said(error: Exception) -> str:
    """pyarrow's message on one line, without its "could not open the input buffer" preamble."""
    text = " ".join(str(error).split()).replace("Could not open Parquet input source '<Buffer>': ", "")
    return text or type(error).__name__


def _move_aside(path: Path) -> Path:
    """Rename `path` to PATH.corrupt-YYYYmmdd-HHMMSS (numbered if that is taken); return the new path."""
    stem = f"{path.name}.corrupt-{time.strftime('%Y%m%d-%H%M%S')}"
    aside, number = path.with_name(stem), 1
    while aside.exists():
        number += 1
        aside = path.with_name(f"{stem}-{number}")
    os.replace(path, aside)
    return aside


def save_fields(out: Path, key: str, fields: dict) -> Path:
    path = out / "fields" / f"{key}.npz"
    try:
        path.parent.mkdir(exist_ok=True)
        atomic_write(path, lambda handle: np.savez_compressed(handle, **fields))
    except OSError as error:
        raise RunError(f"cannot write {str(path)!r}: {reason(error)}; run again to finish the rest") from None
    return path


def load_fields(out: str | Path, key: str) -> dict[str, np.ndarray] | None:
    path = Path(out) / "fields" / f"{key}.npz"
    if not path.exists():
        return None
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


# --- the lock ----------------------------------------------------------------------------------

@contextmanager
def folder_lock(out: Path):
    """Hold an exclusive lock on `out` (released by the OS even if this process is killed);
    OutputFolderError if `out` cannot be created or written."""
    output_folder(out)
    try:
        handle = open(out / LOCK, "a+")
    except OSError as error:
        raise OutputFolderError(f"cannot write to output folder {str(out)!r}: {reason(error)}") from None
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as error:
        if error.errno not in (errno.EAGAIN, errno.EACCES):
            raise
        handle.seek(0)
        holder = handle.read().strip() or "unknown"
        handle.close()
        raise FolderBusy(f"output folder {str(out)!r} is in use by another run ({holder}); "
                         f"wait for it to finish or choose another --out") from None
    handle.seek(0)
    handle.truncate()
    handle.write(f"pid {os.getpid()} on {platform.node()}, since {time.strftime('%Y-%m-%d %H:%M:%S')}")
    handle.flush()
    try:
        yield
    finally:
        handle.seek(0)
        handle.truncate()
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()
