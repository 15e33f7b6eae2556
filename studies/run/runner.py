"""Run a study: expand the spec into cases, solve them in parallel, store each one at once.

Output folder layout (DIR):
    spec.toml          the spec as run
    results.parquet    one row per finished case, keyed by case_id (a hash of its settings)
    results.log        the cases finished since the table was last written (compacted at the end)
    fields/ID.npz      per-point fields of the cases whose sweep keeps fields
    vtk/ID_*.vtu       ParaView files, when asked for
    checkpoints/ID.npz the last converged load step of a big load-step case while it runs
                       (CHECKPOINT_ABOVE); deleted once its row is stored
    run.json           how the last run went (workers, wall time, counts)
    .lock              held while a run or report writes here

results.parquet, results.log, fields/ and .lock are the results store (studies.run.store: the table, the
fields files, atomic writes and the folder lock); its names that callers use (FolderBusy,
folder_lock, read_results, timing_columns, ...) are importable from here as well.

Guarantees: a finished case is in the store as soon as the runner has it (one line appended
to the log, O(1); the table is rewritten only when the run ends, through a temporary file
renamed over it, so a kill never leaves a half-written table);
a resumed or changed spec runs only the cases whose id is not stored yet; the table is kept
sorted by case_id with a fixed column order, so the same spec gives the same table
(timing columns aside) whatever the number of workers. Cases that fail by design (e.g.
SolveError) are stored as rows with status "failed" and the message, and no numbers.
A worker process that dies mid-case (killed, out of memory) costs the cases it was solving a rerun
alone; one that kills that process too is a failed row (WorkerDied), the others are kept.
SIGTERM stops a run as Ctrl-C does (finished cases kept, lock released); an output folder that
cannot be written, a full disk or an unreachable scheduler give one-line errors (studies.run.store).
A big load-step case (large kinematics, von Mises, a collapse problem; steps x estimated points
> CHECKPOINT_ABOVE) run on local workers
saves each converged load step in checkpoints/ID.npz, so a killed run resumes it from its last step
rather than from the start; the result is bit-identical either way (ibm.large.checkpoint).
"""
from __future__ import annotations

import json
import multiprocessing
import multiprocessing.connection
import os
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ibm.exceptions import CheckpointError, FolderBusy, InputError, OutputFolderError, RunError, StoreUnreadable
from studies.problems.registry import problem_of
from studies.run.case import CaseSpec, load_stepped, run_case
from studies.run.identity import case_id
from studies.run.interrupts import terminate_as_interrupt
from studies.run.spec import Study, load, load_registries
from studies.run.store import (
    LOCK, LOG, RESULTS, SETTING_COLUMNS, TIMING_PREFIX, Store, atomic_write, column_order, folder_lock, frame_of,
    load_fields, output_folder, read_results, reason, row_of, save_fields, timing_columns
)

__all__ = ["BLAS_VARIABLES", "CHECKPOINT_ABOVE", "SCHEDULER_TIMEOUT", "RunSummary", "checkpointed", "execute",
           "point_fields", "run_study",
           # re-exported from studies.run.store
           "LOCK", "LOG", "RESULTS", "SETTING_COLUMNS", "TIMING_PREFIX", "FolderBusy", "OutputFolderError", "RunError",
           "Store", "StoreUnreadable", "atomic_write", "column_order", "folder_lock", "frame_of", "load_fields",
           "output_folder", "read_results", "reason", "row_of", "save_fields", "timing_columns"]

BLAS_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                  "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
SCHEDULER_TIMEOUT = 10.0    # seconds to wait for a --scheduler to answer before giving up
# Load-step cases with steps x estimated points (area / cell^2 x ppc^2) above this
# are checkpointed after every load step: ~ a minute of solving and more, where losing the run to
# a kill costs more than the writes (a few percent of a step). Smaller cases just run again.
CHECKPOINT_ABOVE = 2e5
CHECKPOINTS = "checkpoints"


@dataclass
class RunSummary:
    total: int
    reused: int
    run: int
    failed: int
    interrupted: bool
    wall_s: float
    out: Path


# --- one case (runs in a worker) ------------------------------------------------------------

def checkpointed(case: CaseSpec) -> bool:
    """Whether a study checkpoints `case`: load steps on the grid (studies.run.case.load_stepped) with
    steps x estimated points above CHECKPOINT_ABOVE."""
    return load_stepped(case) and case.steps * estimated_points(case) > CHECKPOINT_ABOVE


def estimated_points(case: CaseSpec) -> float:
    """The material points of a case: its body's area / cell^2 x ppc^2 (its volume / cell^3 x ppc^3 in 3D;
    the problem's own body, Problem.area; clipped boundary cells make the count a little smaller)."""
    return problem_of(case).area(case) / case.cell ** case.dim * case.ppc ** case.dim


def execute(task: tuple) -> tuple[str, dict, dict | None]:
    """Solve one case; never raises for a failing case: returns a failed row instead.

    task: (key, case, keep_fields) or (key, case, keep_fields, checkpoint file or None); a
    checkpoint that cannot be used (damaged by a crash of the machine) is deleted and the case
    runs from the start."""
    key, case, keep_fields, *rest = task
    checkpoint = rest[0] if rest else None
    load_registries()
    try:
        try:
            record = run_case(case, keep_fields=keep_fields, **({"checkpoint": checkpoint} if checkpoint else {}))
        except CheckpointError:
            if not checkpoint:
                raise
            Path(checkpoint).unlink(missing_ok=True)
            record = run_case(case, keep_fields=keep_fields, checkpoint=checkpoint)
    except Exception as error:   # a failing case is a result, not a crash of the study
        message = " ".join(str(error).split()) or type(error).__name__
        return key, {"status": "failed", "error": f"{type(error).__name__}: {message}"}, None
    fields = point_fields(record.pop("fields")) if keep_fields else None
    return key, {"status": "ok", "error": "", **record}, fields


def point_fields(fields: dict) -> dict[str, np.ndarray]:
    """The arrays maps and VTK files need, from run_case's "fields" entry (plain numpy only).
    Large kinematics gives its arrays already (studies.run.large.large_fields)."""
    if "model" not in fields:
        return fields
    model, instance, solution = fields["model"], fields["instance"], fields["solution"]
    u, sigma, zz = fields["exact"]
    return {
        "x": model.points.x, "volume": model.points.volume,                 # (n, 2), (n,)
        "u_h": solution.u, "sigma_h": solution.sigma, "zz_h": solution.sigma_zz,   # (n, 2), (n, 2, 2), (n,)
        "u": u, "sigma": sigma, "zz": zz,
        "direction": np.asarray(instance.direction, float),               # (2,) loaded direction
        "vertices": model.body.vertices, "kinds": np.array(model.body.kinds),
        **dict(zip(("outline_points", "outline_piece"), model.body.polyline())),    # arcs drawn as arcs
        "grid_h": np.array(model.grid.h), "grid_lower": np.array(model.grid.lower),
        "grid_shape": np.array(model.grid.shape),
    }


def _init_worker(started=None) -> None:
    """Set up a local worker process; `started` (a queue) hears the id of each case it begins."""
    global _started
    for name in BLAS_VARIABLES:
        os.environ[name] = "1"
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # the parent handles Ctrl-C and stops us
    _started = started
    threading.Thread(target=_exit_with_parent, daemon=True).start()


def _exit_with_parent() -> None:
    """End this worker when the parent dies (SIGKILL): its cases could no longer be stored, and an
    executor's idle worker would otherwise wait on its task queue for ever, holding the parent's pipes."""
    multiprocessing.connection.wait([multiprocessing.parent_process().sentinel])
    os._exit(1)


_started = None     # in a local worker: the queue _announced tells (set once per process by _init_worker)


def _announced(run, task: tuple):
    """run(task) in a local worker, after telling the parent which case it starts, so that a worker
    that dies (killed, out of memory) can be matched to the case it was solving."""
    if _started is not None:
        _started.put(task[0])
    return run(task)


# --- running ---------------------------------------------------------------------------------

@contextmanager
def _single_threaded_blas():
    """Workers inherit the environment when they start (also replacements started mid-run):
    pin their BLAS pools to one thread while the pool lives."""
    saved = {name: os.environ.get(name) for name in BLAS_VARIABLES}
    os.environ.update({name: "1" for name in BLAS_VARIABLES})
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _results_local(tasks, jobs: int):
    """Yield (key, result, fields) as cases finish, on a pool of `jobs` spawned processes.

    A worker that dies (SIGKILL, the out-of-memory killer) breaks the pool. The cases being solved
    then are run again one by one, each in a process of its own; one whose process dies again is a
    failed row naming the death. The other unfinished cases go on in a new pool."""
    context = multiprocessing.get_context("spawn")
    pending = {task[0]: task for task in tasks}
    with _single_threaded_blas():
        while pending:
            started = context.SimpleQueue()
            # no max_tasks_per_child: on Python 3.11 the executor deadlocks when a worker retires
            # (every worker stopped after 200 cases, and `make study` hung at 400 of 1037)
            pool = ProcessPoolExecutor(min(jobs, len(pending)), mp_context=context, initializer=_init_worker,
                                       initargs=(started,))
            broken = False
            try:
                futures = [pool.submit(_announced, execute, task) for task in pending.values()]
                for future in as_completed(futures):
                    try:
                        key, result, fields = future.result()
                    except BrokenProcessPool:
                        broken = True
                        continue
                    del pending[key]
                    yield key, result, fields
            except BaseException:
                _terminate(pool)    # interrupted: drop the unfinished cases, they rerun next time
                raise
            finally:
                pool.shutdown(wait=True, cancel_futures=True)
            if broken:
                began = set()
                while not started.empty():
                    began.add(started.get())
                # a pool that broke before any case began (a failed start) gives no suspect: try each alone
                for key in sorted(began & pending.keys() or pending.keys()):
                    yield _alone(pending.pop(key), context)
            started.close()


def _alone(task: tuple, context) -> tuple[str, dict, dict | None]:
    """Solve one case in a process of its own; a failed row if that process dies too."""
    pool = ProcessPoolExecutor(1, mp_context=context, initializer=_init_worker)
    try:
        return pool.submit(execute, task).result()
    except BrokenProcessPool:
        return task[0], {"status": "failed",
                         "error": "WorkerDied: the worker process solving this case died (killed by a signal, "
                                  "or out of memory), and again when the case was run alone"}, None
    except BaseException:
        _terminate(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop a pool's worker processes at once (the executor's own shutdown waits for running cases)."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        process.terminate()


SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")        # dask's network protocols


def check_address(address: str) -> None:
    """Raise InputError unless `address` reads [SCHEME://]HOST:PORT, SCHEME one of SCHEMES (tcp when
    left out) and PORT 1 to 65535; dask would wait its timeout on some malformed ones."""
    scheme, separator, rest = address.partition("://")
    if not separator:
        scheme, rest = "tcp", address
    host, colon, port = rest.rpartition(":")
    if not (scheme in SCHEMES and colon and host and "/" not in host and port.isdigit() and 1 <= int(port) <= 65535):
        raise InputError(f"scheduler address {address!r} is not allowed; give it as SCHEME://HOST:PORT, e.g. "
                         f"tcp://127.0.0.1:8786 (scheme {', '.join(SCHEMES)}; port 1 to 65535)")


def _connect(address: str):
    """A dask.distributed client of the scheduler at `address`; RunError if it does not answer
    within SCHEDULER_TIMEOUT seconds."""
    from distributed import Client
    try:
        return Client(address, timeout=SCHEDULER_TIMEOUT)
    except ValueError as error:
        raise InputError(f"scheduler address {address!r} is not allowed ({error}); "
                         f"give it as tcp://HOST:PORT") from None
    except OSError as error:
        why = reason(error)
        why = "" if why.startswith("timed out") else f" ({why})"
        raise RunError(f"no dask scheduler answered at {address} within {SCHEDULER_TIMEOUT:g} s{why}: "
                       f"is a dask scheduler running there? start one with `dask scheduler`, "
                       f"and check the host and port") from None


def _results_dask(tasks, client):
    """The same on a dask.distributed cluster (its nanny pins BLAS threads to one per worker).

    The scheduler reruns the cases of a worker that dies on another worker, and gives up on a case
    that was on allowed-failures + 1 dying workers, the case that killed them or one queued beside
    it. Those run again one at a time at the end; one that kills its workers then too is a failed
    row naming the deaths."""
    from distributed import KilledWorker, as_completed
    futures, suspects = [], []
    try:
        futures = [client.submit(execute, task, pure=False, key=f"case-{task[0]}") for task in tasks]
        cases = {future.key: task for future, task in zip(futures, tasks)}
        for future in as_completed(futures):
            try:
                yield future.result()
            except KilledWorker:
                suspects.append(cases[future.key])
        for task in suspects:
            futures.append(client.submit(execute, task, pure=False, key=f"case-{task[0]}-alone"))
            try:
                yield futures[-1].result()
            except KilledWorker as error:
                yield task[0], {"status": "failed",
                                "error": f"WorkerDied: every dask worker that ran this case died, also when it "
                                         f"ran alone ({' '.join(str(error).split())})"}, None
    finally:
        client.cancel(futures)


def run_study(spec: str | Path | Study, out: str | Path, jobs: int | None = None, scheduler: str | None = None,
              progress: bool = True, retry_failed: bool = False, report: bool = True) -> RunSummary:
    """Run every case of `spec` not yet stored in `out`, then (optionally) write the report."""
    study = spec if isinstance(spec, Study) else load(spec)
    out = Path(out)
    jobs = (os.cpu_count() or 1) if jobs is None else jobs
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"jobs {jobs!r} is not allowed; it must be an integer >= 1")
    if scheduler is not None:
        check_address(scheduler)
    start = time.perf_counter()
    with terminate_as_interrupt(), folder_lock(out):
        store = Store(out)
        atomic_write(out / "spec.toml", lambda handle: handle.write(study.text.encode()))
        fields_ids, vtk_ids = study.ids_with("fields"), study.ids_with("vtk") if study.vtk else set()
        for name, ids in (("fields", fields_ids), ("vtk", vtk_ids)):
            if ids:
                output_folder(out / name)
        cases = study.cases()
        tasks = []
        for case in cases:
            key = case_id(case)
            status = store.status(key)
            wants_fields = key in fields_ids
            stored = status == "ok" or (status == "failed" and not retry_failed)
            if stored and wants_fields and status == "ok" and not (out / "fields" / f"{key}.npz").exists():
                stored = False
            written = out / "vtk" / (f"{key}.pvd" if case.kinematics == "large" else f"{key}_points.vtu")
            if stored and key in vtk_ids and status == "ok" and not written.exists():
                stored = False
            if not stored:
                tasks.append((key, case, wants_fields))
        by_key = {case_id(c): c for c in cases}
        tasks = _with_checkpoints(tasks, out, local=not scheduler)
        client = _connect(scheduler) if scheduler and tasks else None    # before any case runs
        where = f"on {scheduler}" if scheduler else f"with {min(jobs, max(len(tasks), 1))} worker process(es)"
        _say(progress, f"{study.title}: {len(cases)} cases, {len(cases) - len(tasks)} already stored, "
                       f"running {len(tasks)} {where}")
        ran = failed = 0
        interrupted, by = False, ""
        bar = _progress_bar(len(tasks), progress)
        results = _results_dask(tasks, client) if client else _results_local(tasks, min(jobs, len(tasks)) or 1)
        try:
            if tasks:
                for key, result, fields in results:
                    if fields is not None:
                        save_fields(out, key, fields)
                        if key in vtk_ids:
                            _write_vtk(fields, out / "vtk", key)
                    store.add(key, row_of(key, by_key[key], result))
                    (out / CHECKPOINTS / f"{key}.npz").unlink(missing_ok=True)
                    ran += 1
                    failed += result["status"] == "failed"
                    bar.update(1)
        except KeyboardInterrupt as stop:
            interrupted, by = True, f" by {stop}" if str(stop) else ""
        finally:
            results.close()     # a write that failed stops the workers at once
            bar.close()
            if client is not None:
                client.close()
            store.close()
        if store.log.exists():  # the cases of this run, appended one line each, into the table
            store.compact()
        wall = time.perf_counter() - start
        summary = RunSummary(len(cases), len(cases) - len(tasks), ran, failed, interrupted, wall, out)
        _write_run_info(out, study, summary, jobs, scheduler)
        if interrupted:
            _say(True, f"interrupted{by}: {ran} of {len(tasks)} cases of this run are stored in {out / RESULTS}; "
                       f"run the same command again to finish the rest")
            return summary
        stored_failed = sum(1 for c in cases if store.status(case_id(c)) == "failed")
        _say(progress, f"done in {wall:.1f} s: {ran} cases run, {stored_failed} failed (stored with their message)")
        if report:
            from studies.report.page import write_report
            path = write_report(out, lock=False)
            _say(progress, f"report: {path}")
    return summary


def _with_checkpoints(tasks: list, out: Path, local: bool) -> list:
    """The tasks with their checkpoint file (None for small cases, and on a --scheduler, whose
    workers need not see this folder); checkpoints of cases no longer to run, and temporaries a
    killed worker left, are deleted."""
    folder = out / CHECKPOINTS
    wanted = {key for key, case, _ in tasks if local and checkpointed(case)}
    if folder.is_dir():
        for stale in [*folder.glob(".*.tmp"), *(p for p in folder.glob("*.npz") if p.stem not in wanted)]:
            stale.unlink(missing_ok=True)
    if wanted:
        output_folder(folder)
    return [(key, case, fields, str((folder / f"{key}.npz").resolve()) if key in wanted else None)
            for key, case, fields in tasks]


def _write_vtk(fields: dict, directory: Path, key: str) -> None:
    from studies.report import vtk
    try:
        vtk.write_case(fields, directory, key)
    except OSError as error:
        raise RunError(f"cannot write the VTK files of case {key} in {str(directory)!r}: {reason(error)}; "
                       f"run again to finish the rest") from None


def _progress_bar(total: int, enabled: bool):
    return tqdm(total=total, unit="case", desc="cases", disable=not enabled or total == 0,
                file=sys.stderr, dynamic_ncols=True, mininterval=0.5,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} "
                           "[{elapsed}<{remaining}, {rate_fmt}]")


def _say(enabled: bool, message: str) -> None:
    if enabled:
        print(message, file=sys.stderr, flush=True)


def _write_run_info(out: Path, study: Study, summary: RunSummary, jobs: int, scheduler: str | None) -> None:
    source = str(Path(study.source).resolve()) if study.source != "<spec>" else study.source
    info = {"title": study.title, "spec": source, "jobs": jobs, "scheduler": scheduler,
            "cases": summary.total, "reused": summary.reused, "run": summary.run, "failed": summary.failed,
            "interrupted": summary.interrupted, "wall_s": round(summary.wall_s, 3),
            "finished": time.strftime("%Y-%m-%d %H:%M:%S"), "python": sys.version.split()[0],
            "cpus": os.cpu_count()}
    atomic_write(out / "run.json", lambda handle: handle.write(json.dumps(info, indent=1).encode()))
