"""The results store of an output folder: the results table (parquet), per-case fields (npz),
atomic writes and the folder lock.

Its part of the output folder (the whole layout is in studies.runner):
    results.parquet    one row per finished case, keyed by case_id (a hash of its settings)
    fields/ID.npz      per-point fields of the cases whose sweep keeps fields
    .lock              held while a run or report writes here

Every file is written to a temporary file beside it and renamed over it (atomic_write), so a
kill never leaves a half-written table or fields file; Store removes the temporaries a killed
run left. The table is kept sorted by case_id with a fixed column order (frame_of), so the same
cases give the same table whatever order they finished in. The runner writes here through
Store; the report reads through read_results and load_fields; both hold folder_lock meanwhile.
"""
from __future__ import annotations

import dataclasses
import errno
import fcntl
import io
import json
import os
import platform
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd

from ibm.geometry import InputError
from studies.case import CaseSpec
from studies.spec import case_settings

RESULTS = "results.parquet"
LOCK = ".lock"
SETTING_COLUMNS = ("case_id", "status", "error")
TIMING_PREFIX = "time"


class FolderBusy(InputError):
    """Another run holds the output folder."""


# --- rows and the results table ---------------------------------------------------------------

def row_of(key: str, case: CaseSpec, result: dict) -> dict:
    """One flat row: identity, status, the case's settings, then its results."""
    settings = case_settings(case)
    row = {"case_id": key, "status": result["status"], "error": result["error"]}
    for name, value in settings.items():
        if name == "offset":
            row["offset_x"], row["offset_y"] = value
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
    lead = list(SETTING_COLUMNS) + settings[:5] + ["offset_x", "offset_y"] + settings[5:] + ["parameters"]
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
    with open(temporary, "wb") as handle:
        write(handle)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(temporary, path)


class Store:
    """The results table of one output folder (call only while holding its lock)."""

    def __init__(self, out: Path):
        self.path = Path(out) / RESULTS
        for pattern in (f".{RESULTS}.*.tmp", "fields/.*.tmp", "vtk/.*.tmp.vtu", "vtk/.*.tmp.pvd"):
            for stale in Path(out).glob(pattern):
                stale.unlink()      # left by a killed run; the files they were to replace are intact
        self.rows: dict[str, dict] = {}
        if self.path.exists():
            table = pd.read_parquet(self.path)
            for row in table.to_dict("records"):
                self.rows[row["case_id"]] = {k: v for k, v in row.items() if not _missing(v)}

    def add(self, key: str, row: dict) -> None:
        self.rows[key] = row
        frame = frame_of(self.rows)
        atomic_write(self.path, lambda handle: frame.to_parquet(handle, index=False))

    def status(self, key: str) -> str | None:
        row = self.rows.get(key)
        return None if row is None else row.get("status")


def _missing(value) -> bool:
    return value is None or (isinstance(value, float) and np.isnan(value))


def read_results(out: str | Path) -> pd.DataFrame:
    path = Path(out) / RESULTS
    if not path.exists():
        raise InputError(f"no results in {str(out)!r}: {RESULTS} is missing (run a study there first)")
    # One read through one handle: the writer replaces the file atomically, but a reader that
    # opens the path twice (pyarrow reads the footer, then the pages) can mix two versions.
    return pd.read_parquet(io.BytesIO(path.read_bytes()))


def save_fields(out: Path, key: str, fields: dict) -> Path:
    path = out / "fields" / f"{key}.npz"
    path.parent.mkdir(exist_ok=True)
    atomic_write(path, lambda handle: np.savez_compressed(handle, **fields))
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
    """Hold an exclusive lock on `out` (released by the OS even if this process is killed)."""
    out.mkdir(parents=True, exist_ok=True)
    handle = open(out / LOCK, "a+")
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
