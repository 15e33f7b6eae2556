"""A worker process that dies mid-case (SIGKILL, the out-of-memory killer): the case is run again
alone, or on another dask worker, and reported failed by name if it kills that one too; every
other case finishes and is stored as if nothing had happened.

Each study runs in a Python process of its own (`scenario`), so that a kill that went astray
would fail its test with the child's exit and output instead of taking the test process down."""
import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from studies.run import runner
from studies.run.runner import read_results, run_study
from studies.run.spec import parse

HERE = Path(__file__).resolve().parent
real_execute = runner.execute

SPEC = textwrap.dedent("""
    title = "worker death"
    [base]
    cell = 10.0
    [[sweep]]
    name = "angles"
    angle = {from = 0, to = 25, step = 5}
    """)
KILLER = 10.0     # the angle of the case that kills its worker


def dying_execute(task):
    """execute, except that the KILLER case kills its own process: every time, or only the first
    time when FAULT_ONCE names a folder (a marker file there remembers that it happened)."""
    once = os.environ.get("FAULT_ONCE")
    if os.getpid() == int(os.environ["STUDY_PARENT"]):
        raise RuntimeError("a case ran in the study's own process, not in a worker")
    if task[1].angle == KILLER:
        marker = Path(once) / "died" if once else None
        if marker is None or not marker.exists():
            if marker is not None:
                marker.touch()
            os.kill(os.getpid(), signal.SIGKILL)
    return real_execute(task)


def scenario(where: str, out: str) -> None:
    """In a child process: the study with dying_execute on local workers or a dask cluster; the
    summary as JSON on stdout."""
    os.environ["STUDY_PARENT"] = str(os.getpid())     # cases must run in workers, never here
    runner.execute = dying_execute
    if where == "local":
        summary = run_study(parse(SPEC), Path(out), jobs=2, progress=False, report=False)
    else:
        import dask
        import distributed
        with dask.config.set({"distributed.scheduler.allowed-failures": 1}), \
                distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                         silence_logs=50) as cluster:
            summary = run_study(parse(SPEC), Path(out), scheduler=cluster.scheduler_address, progress=False,
                                report=False)
    print(json.dumps({"run": summary.run, "failed": summary.failed, "interrupted": summary.interrupted}))


def run_scenario(where: str, out: Path, **environment) -> dict:
    script = f"import sys; sys.path.insert(0, {str(HERE)!r}); import test_worker_death; " \
             f"test_worker_death.scenario({where!r}, {str(out)!r})"
    child = subprocess.run([sys.executable, "-c", script], cwd=HERE.parents[2], capture_output=True, text=True,
                           timeout=600, env={**os.environ, **environment})
    assert child.returncode == 0, f"the study's process ended with {child.returncode}: {child.stderr[-3000:]}"
    return json.loads(child.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("uninterrupted")
    run_study(parse(SPEC), out, jobs=1, progress=False, report=False)
    return read_results(out).set_index("case_id")


def numbers(table):
    return table[[c for c in table.columns if c.startswith("err_")]]


def test_a_case_that_kills_its_worker_is_a_failed_row_and_the_rest_finish(reference, tmp_path):
    summary = run_scenario("local", tmp_path)
    assert summary == {"run": 6, "failed": 1, "interrupted": False}
    table = read_results(tmp_path).set_index("case_id")
    dead = table[table.angle == KILLER]
    assert list(dead.status) == ["failed"]
    assert dead.error.iloc[0].startswith("WorkerDied: the worker process solving this case died")
    alive = table[table.angle != KILLER]
    assert (alive.status == "ok").all() and len(alive) == 5
    assert numbers(alive).equals(numbers(reference.loc[alive.index]))


def test_a_worker_that_dies_once_costs_nothing(reference, tmp_path):
    summary = run_scenario("local", tmp_path / "out", FAULT_ONCE=str(tmp_path))
    assert (tmp_path / "died").exists()
    assert (summary["run"], summary["failed"]) == (6, 0)
    table = read_results(tmp_path / "out").set_index("case_id")
    assert (table.status == "ok").all()
    assert numbers(table).equals(numbers(reference.loc[table.index]))


def test_a_case_that_kills_its_dask_workers_is_a_failed_row(reference, tmp_path):
    pytest.importorskip("distributed")
    summary = run_scenario("dask", tmp_path)
    assert (summary["run"], summary["failed"]) == (6, 1)
    table = read_results(tmp_path).set_index("case_id")
    dead = table[table.angle == KILLER]
    assert dead.error.iloc[0].startswith("WorkerDied: every dask worker that ran this case died, also when it ran alone")
    alive = table[table.angle != KILLER]
    assert (alive.status == "ok").all()
    assert numbers(alive).equals(numbers(reference.loc[alive.index]))
