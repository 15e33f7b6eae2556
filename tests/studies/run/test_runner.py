"""The study runner: resume after SIGINT/SIGKILL, the folder lock, determinism across
worker counts and on dask, re-running only what changed, and failed cases as rows."""
from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ibm.exceptions import InputError, SolveError
from studies.run import runner
from studies.run.case import CaseSpec
from studies.run.runner import FolderBusy, folder_lock, read_results, run_study, timing_columns
from studies.run.identity import case_id
from studies.run.spec import parse

ROOT = Path(__file__).resolve().parents[3]

# 36 cases of ~0.05 s each: long enough to be killed half-way on two workers
# cell 5: cases slow enough (a few tenths of a second) that a kill after three stored cases lands
# half-way even on a quiet machine (at cell 10 the 36 cases could all finish inside one poll)
SPEC = textwrap.dedent("""
    title = "runner test"
    [base]
    cell = 5.0
    [[sweep]]
    name = "angles"
    angle = {from = 0, to = 85, step = 5}
    delta_rel = [1e-3, 1e-5]
    """)


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "runner.toml"
    path.write_text(SPEC)
    return path


@pytest.fixture(scope="module")
def reference(spec_file, tmp_path_factory) -> pd.DataFrame:
    """The uninterrupted run, on one worker."""
    out = tmp_path_factory.mktemp("reference")
    summary = run_study(spec_file, out, jobs=1, progress=False, report=False)
    assert (summary.total, summary.run, summary.failed, summary.interrupted) == (36, 36, 0, False)
    return read_results(out)


def without_timing(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.drop(columns=timing_columns(frame.columns))


def assert_same_table(a: pd.DataFrame, b: pd.DataFrame) -> None:
    """Equal to the bit, all columns but the timing ones."""
    a, b = without_timing(a), without_timing(b)
    assert list(a.columns) == list(b.columns)
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    for column in a.columns:
        if a[column].dtype.kind == "f":
            assert a[column].to_numpy().tobytes() == b[column].to_numpy().tobytes(), column


def test_table_is_one_row_per_case_sorted_by_id(reference, spec_file):
    ids = sorted(case_id(c) for c in parse(spec_file.read_text()).cases())
    assert reference["case_id"].tolist() == ids
    assert (reference["status"] == "ok").all()
    assert reference["err_u"].between(0, 1e-2).all()
    assert timing_columns(reference.columns) and "time_s" in reference.columns


def test_same_table_whatever_the_number_of_workers(reference, spec_file, tmp_path):
    run_study(spec_file, tmp_path, jobs=2, progress=False, report=False)
    assert_same_table(read_results(tmp_path), reference)


LARGE_SPEC = textwrap.dedent("""
    title = "large runner test"
    [[sweep]]
    name = "column"
    problems = ["column"]
    methods = ["nitsche", "ibm", "lagrange"]
    kinematics = "large"
    steps = 6
    nu = 0.0
    load = 40000
    width = 10
    height = 50
    cell = 6.25
    ppc = 2
    angle = [30, 90]
    offset = [0.3, 0.2]
    """)


def same_table_with_one_and_two_workers(spec_text: str, tmp_path: Path) -> pd.DataFrame:
    """Run the spec with one and with two workers, assert the tables equal to the bit, return it."""
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text)
    run_study(spec, tmp_path / "one", jobs=1, progress=False, report=False)
    run_study(spec, tmp_path / "two", jobs=2, progress=False, report=False)
    one = read_results(tmp_path / "one")
    assert_same_table(read_results(tmp_path / "two"), one)
    return one


def test_large_cases_give_the_same_table_whatever_the_number_of_workers(tmp_path):
    one = same_table_with_one_and_two_workers(LARGE_SPEC, tmp_path)
    assert len(one) == 6 and (one["status"] == "ok").all()


# a yielding block at small and large strain, a coarse 3D block and the footing (with step cuts):
# 8 cases, ~5 s on one worker
MIXED_SPEC = textwrap.dedent("""
    title = "mixed runner test"
    [[sweep]]
    name = "plastic"
    problems = ["confined-block"]
    methods = ["ibm", "nitsche"]
    load_type = "settlement"
    material = "von-mises"
    yield_stress = 5.0
    hardening = 100.0
    load = 20
    kinematics = ["small", "large"]
    steps = 4
    cell = 25
    ppc = 2
    angle = 30
    [[sweep]]
    name = "solid"
    dim = 3
    methods = ["penalty", "nitsche"]
    orientation = [[30, 20]]
    cell = 50
    [[sweep]]
    name = "footing"
    problems = ["footing"]
    methods = ["ibm", "lagrange"]
    angle = 90
    cell = 80
    steps = 5
    ppc = 2
    """)


def test_plastic_3d_and_footing_cases_give_the_same_table_whatever_the_number_of_workers(tmp_path):
    one = same_table_with_one_and_two_workers(MIXED_SPEC, tmp_path)
    assert len(one) == 8 and (one["status"] == "ok").all()
    plastic = one[one["material"] == "von-mises"]
    assert sorted(plastic["kinematics"]) == ["large", "large", "small", "small"]
    assert (plastic["err_u"] < 1e-6).all()
    assert (one["dim"] == 3).sum() == 2 and (one.loc[one["dim"] == 3, "err_u"] < 1e-5).all()
    footing = one[one["problem"] == "footing"].set_index("method")
    assert footing.loc["ibm", "step_cuts"] == 4 and footing.loc["lagrange", "step_cuts"] == 1
    assert (footing["q_over_c"] > 2 + np.pi).all()


def _interrupt(spec_file: Path, out: Path, sig: int) -> tuple[int, pd.DataFrame, str]:
    """Start a run, wait until a few cases are stored, send `sig`; return (code, stored rows, stderr)."""
    command = [sys.executable, "-m", "studies.cli", "run", str(spec_file), "--out", str(out), "--jobs", "2",
               "--no-report"]
    process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    stored = 0
    while stored < 3 and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.02)
        if (out / runner.RESULTS).exists() or (out / runner.LOG).exists():
            stored = len(read_results(out))
    assert stored >= 3, "the run did not store cases in time"
    process.send_signal(sig)
    _, stderr = process.communicate(timeout=60)
    return process.returncode, read_results(out), stderr


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["SIGINT", "SIGKILL"])
def test_killed_run_resumes_without_loss_or_duplicates(sig, reference, spec_file, tmp_path):
    code, before, stderr = _interrupt(spec_file, tmp_path, sig)
    if sig == signal.SIGINT:
        assert code == 130 and "interrupted" in stderr and "run the same command again" in stderr
        assert "Traceback" not in stderr
    else:
        assert code == -signal.SIGKILL
    assert 3 <= len(before) < 36, "the kill must land half-way"
    assert before["case_id"].is_unique
    summary = run_study(spec_file, tmp_path, jobs=2, progress=False, report=False)
    assert summary.reused == len(before) and summary.run == 36 - len(before)
    after = read_results(tmp_path)
    assert after["case_id"].is_unique and len(after) == 36
    # the cases finished before the kill are kept as they were (not run again: same timings)
    kept = after.set_index("case_id").loc[before["case_id"], "time_s"].to_numpy()
    assert np.array_equal(kept, before["time_s"].to_numpy())
    assert_same_table(after, reference)
    assert not list(tmp_path.glob(".*.tmp"))


def test_second_run_on_a_busy_folder_is_refused(spec_file, tmp_path):
    with folder_lock(tmp_path):
        with pytest.raises(FolderBusy, match=r"is in use by another run \(pid \d+"):
            run_study(spec_file, tmp_path, jobs=1, progress=False, report=False)
        from studies.cli import main
        assert main(["run", str(spec_file), "--out", str(tmp_path), "--quiet"]) == 2
        assert main(["report", str(tmp_path)]) == 2
    assert not (tmp_path / runner.RESULTS).exists()      # nothing was written while locked
    with folder_lock(tmp_path):                          # and the lock is free again
        pass


def test_changed_spec_reruns_only_the_new_cases(tmp_path):
    small = SPEC.replace("cell = 5.0", "cell = 20.0").replace("to = 85", "to = 10")
    first = run_study(parse(small), tmp_path, jobs=1, progress=False, report=False)
    assert (first.total, first.run) == (6, 6)
    again = run_study(parse(small), tmp_path, jobs=1, progress=False, report=False)
    assert (again.reused, again.run) == (6, 0)
    grown = run_study(parse(small.replace("[1e-3, 1e-5]", "[1e-3, 1e-5, 1e-4]")), tmp_path, jobs=1,
                      progress=False, report=False)
    assert (grown.total, grown.reused, grown.run) == (9, 6, 3)
    assert len(read_results(tmp_path)) == 9


def test_dask_scheduler_gives_the_same_table(reference, spec_file, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster:
        summary = run_study(spec_file, tmp_path, scheduler=cluster.scheduler_address, progress=False,
                            report=False)
    assert (summary.run, summary.failed) == (36, 0)
    assert_same_table(read_results(tmp_path), reference)


def test_failing_case_is_a_row_with_its_message_and_no_numbers(monkeypatch):
    def fail(spec, keep_fields=False):
        raise SolveError("the Nitsche system is indefinite:\n gamma is too small")
    monkeypatch.setattr(runner, "run_case", fail)
    case = CaseSpec(angle=30.0)
    key, result, fields = runner.execute((case_id(case), case, True))
    assert result == {"status": "failed", "error": "SolveError: the Nitsche system is indefinite: gamma is too small"}
    assert fields is None
    row = runner.row_of(key, case, result)
    assert row["status"] == "failed" and not any(k.startswith("err_") for k in row)
    assert row["angle"] == 30.0 and row["case_id"] == key


def test_bad_jobs_and_missing_results_are_input_errors(spec_file, tmp_path):
    with pytest.raises(InputError, match="jobs 0 is not allowed"):
        run_study(spec_file, tmp_path, jobs=0, progress=False, report=False)
    with pytest.raises(InputError, match="results.parquet is missing"):
        read_results(tmp_path / "empty")
