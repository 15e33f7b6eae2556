"""Checkpoints of a large-deformation run: the whole ibm.large.loadsteps.Progress after a converged
load step, in one .npz file, so a run that is killed resumes where it stopped and ends with
exactly the numbers of an uninterrupted run.

File layout (numpy .npz, never pickled): `meta`, UTF-8 JSON as uint8 bytes,
    {"format": FORMAT, "version": VERSION, "fingerprint": ..., "progress": tree, "extra": tree}
and one entry `a<i>` per array. In a tree an array is {"__array__": i} (stored as it is: dtype,
shape, memory order), a numpy scalar {"__scalar__": dtype, "value": v}, a tuple {"__tuple__": [...]};
dicts (string keys), lists, str, int, float (repr round-trips exactly, NaN and inf included), bool
and None are plain JSON. So the per-step records come back with their exact values and types.

Writes are atomic (a temporary file beside the target, fsynced, then os.replace), so a kill at
any moment leaves either the previous checkpoint or the new one, never half of one.
The fingerprint hashes what the numbers depend on (the setup: body, material, loading, h, ppc,
basis, steps, margin, sliver; the treatment's and Newton control's repr): a checkpoint of
another setup is refused (CheckpointError), as is a file that is no readable checkpoint. It does
not hash the source code: callers that may resume across code changes put a code version in
the file name (studies.run.identity.case_id does).
"""
from __future__ import annotations

import hashlib
import io
import json
import os
from contextlib import suppress
from pathlib import Path

import numpy as np

from ibm.models.constitutive import State
from ibm.large.progress import Progress
from ibm.large.walls import WallLines, outline_from_tree
from ibm.exceptions import CheckpointError

FORMAT = "ibm-mpm load-step checkpoint"
VERSION = 1
_TAGS = ("__array__", "__scalar__", "__tuple__")



def fingerprint(setup, treatment, control) -> str:
    """A short hash of everything a run's numbers depend on (see the module doc)."""
    body, loading = setup.body, setup.loading
    digest = hashlib.sha256()

    def add(name: str, value) -> None:
        if isinstance(value, np.ndarray):
            value = np.ascontiguousarray(value, dtype=float)
            text = f"{value.shape}:".encode() + value.tobytes()
        else:
            text = repr(value).encode()
        digest.update(name.encode() + b"=" + text + b";")

    add("version", VERSION)
    add("vertices", body.vertices)
    add("kinds", tuple(body.kinds))
    add("frame", body.frame)
    add("material", setup.material)
    add("body_force", np.asarray(loading.body_force, float))
    add("pressures", sorted((int(k), float(v)) for k, v in loading.pressures.items()))
    add("wall_motion", None if loading.wall_motion is None else np.asarray(loading.wall_motion, float))
    if loading.wall_path is not None:      # added only when given: older setups keep their fingerprints
        add("wall_path", loading.wall_path.key())
    for edge, path in sorted(loading.traction_path.items()):
        add(f"traction_path {int(edge)}", path.key())
    for edge, law in sorted(setup.contact.items()):
        add(f"contact {int(edge)}", law)
    for edge, obstacle in sorted(setup.obstacles.items()):
        add(f"obstacle {int(edge)}", obstacle.key())
    for name in ("h", "ppc", "basis", "steps", "margin", "sliver", "locking"):
        add(name, getattr(setup, name))
    add("treatment", treatment)
    add("control", control)
    return digest.hexdigest()[:16]


# --- trees of plain values and arrays ------------------------------------------------------------

def _encode(value, arrays: list):
    if isinstance(value, np.ndarray):
        if value.dtype.hasobject:
            raise TypeError("a checkpoint cannot hold object arrays")
        arrays.append(value)
        return {"__array__": len(arrays) - 1}
    if isinstance(value, np.generic):
        return {"__scalar__": value.dtype.str, "value": value.item()}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, tuple):
        return {"__tuple__": [_encode(v, arrays) for v in value]}
    if isinstance(value, list):
        return [_encode(v, arrays) for v in value]
    if isinstance(value, dict):
        for key in value:
            if not isinstance(key, str) or key in _TAGS:
                raise TypeError(f"a checkpoint's dict keys must be strings other than {_TAGS}, got {key!r}")
        return {key: _encode(v, arrays) for key, v in value.items()}
    raise TypeError(f"a checkpoint cannot hold {type(value).__name__} values")


def _decode(value, arrays):
    if isinstance(value, list):
        return [_decode(v, arrays) for v in value]
    if isinstance(value, dict):
        if "__array__" in value:
            return arrays[f"a{value['__array__']}"]
        if "__scalar__" in value:
            return np.dtype(value["__scalar__"]).type(value["value"])
        if "__tuple__" in value:
            return tuple(_decode(v, arrays) for v in value["__tuple__"])
        return {key: _decode(v, arrays) for key, v in value.items()}
    return value


def _progress_tree(progress) -> dict:
    state, outline, lines = progress.state, progress.outline, progress.lines
    if type(state) is not State:
        raise TypeError(f"a checkpoint holds ibm.models.constitutive.State, not {type(state).__name__}")
    return {"X": progress.X, "V0": progress.V0, "x": progress.x, "volume": progress.volume,
            "state": {"F": state.F, "be": state.be, "internal": dict(state.internal)},
            "sigma": progress.sigma,
            "outline": outline.to_tree(),
            "lines": {"points": lines.points, "normals": lines.normals},
            "t": progress.t, "steps": progress.steps, "vertex_owner": progress.vertex_owner,
            **({"contact": progress.contact} if progress.contact else {})}


def _progress_of(tree: dict):
    state, outline, lines = tree["state"], tree["outline"], tree["lines"]
    if not isinstance(tree["t"], float) or not isinstance(tree["steps"], list):
        raise TypeError("t or steps has the wrong type")
    return Progress(tree["X"], tree["V0"], tree["x"], tree["volume"],
                    State(state["F"], state["be"], dict(state["internal"])), tree["sigma"],
                    outline_from_tree(outline),
                    WallLines(lines["points"], lines["normals"]), tree["t"], tree["steps"], tree["vertex_owner"],
                    dict(tree.get("contact", {})))


# --- files ---------------------------------------------------------------------------------------

def save(path: str | Path, progress, extra: dict | None = None, fingerprint: str = "") -> None:
    """Write `progress` (and the caller's `extra` tree) to `path` atomically."""
    path = Path(path)
    arrays: list[np.ndarray] = []
    meta = {"format": FORMAT, "version": VERSION, "fingerprint": fingerprint,
            "progress": _encode(_progress_tree(progress), arrays), "extra": _encode(dict(extra or {}), arrays)}
    text = json.dumps(meta, separators=(",", ":"), allow_nan=True)
    entries = {f"a{i}": a for i, a in enumerate(arrays)}
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(temporary, "wb") as handle:
            np.savez(handle, meta=np.frombuffer(text.encode(), np.uint8), **entries)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:
        with suppress(OSError):
            temporary.unlink(missing_ok=True)
        raise


def load(path: str | Path, fingerprint: str | None = None):
    """(progress, extra) from the checkpoint at `path`; CheckpointError (one line) if it is not a
    readable checkpoint or, given `fingerprint`, was written for another setup."""
    path = Path(path)
    try:
        data = path.read_bytes()          # one read: a writer replaces the file, never edits it
        with np.load(io.BytesIO(data), allow_pickle=False) as stored:
            meta = json.loads(bytes(stored["meta"]).decode())
            if not isinstance(meta, dict) or meta.get("format") != FORMAT:
                raise ValueError("no checkpoint header")
            if meta.get("version") != VERSION:
                raise ValueError(f"format version {meta.get('version')!r}, this code reads {VERSION}")
            arrays = {name: stored[name] for name in stored.files if name != "meta"}
        if fingerprint is not None and meta["fingerprint"] != fingerprint:
            raise CheckpointError(f"checkpoint {str(path)!r} was written for another setup (fingerprint "
                                  f"{meta['fingerprint']}, this run's is {fingerprint}); delete it or give "
                                  f"another checkpoint file")
        progress = _progress_of(_decode(meta["progress"], arrays))
        extra = _decode(meta["extra"], arrays)
        if not isinstance(extra, dict):
            raise ValueError("its extra data is no dict")
    except CheckpointError:
        raise
    except OSError as error:
        raise CheckpointError(f"cannot read checkpoint {str(path)!r}: {error.strerror or error}") from None
    except Exception as error:      # zip, npy, JSON and layout errors of a damaged or foreign file
        why = " ".join(str(error).split()) or type(error).__name__
        raise CheckpointError(f"{str(path)!r} is not a readable checkpoint ({why}); delete it to start "
                              f"the run afresh") from None
    return progress, extra


def remove_stale_temporaries(path: str | Path) -> None:
    """Delete the temporaries of `path` that killed writers left (those of live processes stay)."""
    path = Path(path)
    for temporary in path.parent.glob(f".{path.name}.*.tmp"):
        pid = temporary.name[len(path.name) + 2:-len(".tmp")]
        if pid.isdigit() and int(pid) != os.getpid():
            try:
                os.kill(int(pid), 0)
                continue                  # its writer still runs
            except ProcessLookupError:
                pass
            except PermissionError:
                continue
        with suppress(OSError):
            temporary.unlink()


def steps_stored(path: str | Path) -> int:
    """How many load steps the checkpoint at `path` holds (CheckpointError as load)."""
    return len(load(path)[0].steps)
