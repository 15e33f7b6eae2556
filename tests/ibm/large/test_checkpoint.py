"""Checkpoints of large-deformation runs: a run stopped after a step (or killed with SIGKILL)
resumes from its last checkpoint and ends bit-identical to an uninterrupted run; a checkpoint of
another setup, or a damaged one, is refused with one line."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from baselines.registry import treatment
from ibm.large import checkpoint as checkpoints
from ibm.exceptions import CheckpointError
from ibm.large.loadsteps import run
from studies.run import runner
from studies.run.case import CaseSpec, run_case
from studies.cli import main
from studies.problems.registry import problem_of
from studies.run.identity import case_id

ROOT = Path(__file__).resolve().parents[3]

# the inclined GIMP column: walls cut the grid, the outline bends, 12 steps
COLUMN = CaseSpec(problem="column", method="nitsche", angle=30, cell=50 / 16, ppc=2, offset=(0.3, 0.2), nu=0.0,
                  E=1e4, load=40000, width=10, height=50, kinematics="large", steps=12)
COMPARED = ("err_u", "err_sigma", "err_sigma_ample", "newton_iterations", "history", "height_final",
            "height_exact", "max_penetration", "step_cuts", "npoints", "ndof")


class Stop(BaseException):
    """A kill between a step's solve and its checkpoint (not an Exception: nothing catches it)."""


@pytest.fixture(scope="module")
def uninterrupted() -> dict:
    return run_case(COLUMN, keep_fields=True)


def _same_record(a: dict, b: dict, compared=COMPARED) -> None:
    """The same keys and, fields and time aside, the same values of the same types (`compared` first)."""
    assert {k for k in a if k != "time_s"} == {k for k in b if k != "time_s"}
    for key in compared:
        assert a[key] == b[key], key
    for key in a:
        if key not in ("time_s", "fields"):
            assert a[key] == b[key] and type(a[key]) is type(b[key]), key


def run_killed_before_step(spec: CaseSpec, path: Path, step: int, monkeypatch, keep_fields: bool = True) -> None:
    """Run `spec` checkpointing to `path`, stopped (as a kill would stop it) when it comes to save
    `step`; the real checkpoints.save is back afterwards."""
    save = checkpoints.save

    def save_until(target, progress, extra=None, fingerprint=""):
        if len(progress.steps) == step:
            raise Stop(f"killed before step {step} was saved")
        save(target, progress, extra, fingerprint)

    monkeypatch.setattr(checkpoints, "save", save_until)
    with pytest.raises(Stop):
        run_case(spec, keep_fields=keep_fields, checkpoint=path)
    monkeypatch.setattr(checkpoints, "save", save)


def test_resumed_run_is_bit_identical_to_an_uninterrupted_one(uninterrupted, tmp_path, monkeypatch):
    path = tmp_path / "column.npz"
    run_killed_before_step(COLUMN, path, 6, monkeypatch)
    assert checkpoints.steps_stored(path) == 5
    _, extra = checkpoints.load(path)
    assert len(extra["snapshots"]) == 5                    # the snapshots taken so far survive

    resumed = run_case(COLUMN, keep_fields=True, checkpoint=path)
    _same_record(resumed, uninterrupted)
    a, b = resumed["fields"], uninterrupted["fields"]
    assert a.keys() == b.keys() and len(a["step"]) == COLUMN.steps
    for name in a:
        assert a[name].dtype == b[name].dtype and a[name].shape == b[name].shape, name
        assert np.array_equal(a[name], b[name]), name
        assert a[name].tobytes() == b[name].tobytes(), name

    # the final checkpoint stays; a rerun returns the stored result at once
    assert checkpoints.steps_stored(path) == COLUMN.steps
    start = time.perf_counter()
    again = run_case(COLUMN, keep_fields=True, checkpoint=path)
    assert time.perf_counter() - start < 0.5 * uninterrupted["time_s"] + 0.2
    _same_record(again, uninterrupted)
    assert not list(tmp_path.glob(".*.tmp"))


def _solve(directory: Path) -> list[str]:
    return [sys.executable, "-m", "studies.cli", "solve", "--problem", "column", "--method", "nitsche", "--angle",
            "30", "--cell", str(50 / 24), "--ppc", "2", "--offset", "0.3", "0.2", "--nu", "0", "--E", "1e4",
            "--load", "40000", "--width", "10", "--height", "50", "--kinematics", "large", "--steps", "30",
            "--checkpoint", str(directory), "--json"]


def _json_of(stdout: str) -> dict:
    record = json.loads(stdout)
    record.pop("time_s")
    return record


def started_until_stored(command: list[str], directory: Path, steps: int) -> tuple[subprocess.Popen, int]:
    """Start `command`; return it and the steps its checkpoint in `directory` holds once they reach `steps`
    (or the process ended, or 60 s went by)."""
    process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline, stored = time.monotonic() + 60, 0
    while stored < steps and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.02)
        for path in directory.glob("*.npz"):
            try:
                stored = checkpoints.steps_stored(path)
            except CheckpointError:                     # being written
                pass
    return process, stored


def killed_and_resumed(command_of, tmp_path: Path, steps: int) -> tuple[dict, dict, Path]:
    """Run command_of(folder) to its end, then again killed (SIGKILL) once 3 of its `steps` steps are
    checkpointed, then again to resume; return the reference and resumed JSON (time aside) and the
    killed run's checkpoint folder."""
    reference = subprocess.run(command_of(tmp_path / "reference"), cwd=ROOT, capture_output=True, text=True,
                               timeout=120)
    assert reference.returncode == 0, reference.stderr
    assert [checkpoints.steps_stored(p) for p in (tmp_path / "reference").glob("*.npz")] == [steps]
    directory = tmp_path / "killed"
    process, stored = started_until_stored(command_of(directory), directory, 3)
    assert process.poll() is None and 3 <= stored < steps, "the kill must land half-way"
    os.kill(process.pid, signal.SIGKILL)
    process.communicate(timeout=30)
    assert process.returncode == -signal.SIGKILL
    files = list(directory.glob("*.npz"))
    assert len(files) == 1 and 3 <= checkpoints.steps_stored(files[0]) < steps
    resumed = subprocess.run(command_of(directory), cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert resumed.returncode == 0, resumed.stderr
    assert "resumed from checkpoint" in resumed.stderr
    return _json_of(reference.stdout), _json_of(resumed.stdout), directory


def test_run_killed_with_sigkill_resumes_to_the_same_json(tmp_path):
    reference, resumed, directory = killed_and_resumed(_solve, tmp_path, 30)
    assert resumed == reference
    assert len(list(directory.iterdir())) == 1                          # no temporary left

SMALL = COLUMN.with_(steps=2, cell=50 / 8)


def _one_line_error(arguments: list[str], capsys) -> str:
    code = main(arguments)
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in captured.err, captured.err
    assert captured.out == ""
    return lines[0]


def _cli(spec: CaseSpec, directory: Path) -> list[str]:
    return ["solve", "--problem", spec.problem, "--method", spec.method, "--angle", str(spec.angle), "--cell",
            repr(spec.cell), "--ppc", str(spec.ppc), "--offset", *map(str, spec.offset), "--nu", str(spec.nu),
            "--E", str(spec.E), "--load", str(spec.load), "--width", str(spec.width), "--height",
            str(spec.height), "--kinematics", "large", "--steps", str(spec.steps), "--checkpoint", str(directory),
            "--json"]


def test_checkpoint_of_another_setup_is_refused(tmp_path, capsys):
    assert main(_cli(SMALL, tmp_path)) == 0
    capsys.readouterr()
    other = SMALL.with_(load=30000)
    written = tmp_path / f"{case_id(SMALL)}.npz"
    target = tmp_path / f"{case_id(other)}.npz"
    written.rename(target)
    line = _one_line_error(_cli(other, tmp_path), capsys)
    assert "another setup" in line and str(target) in line
    # the core refuses it as well
    setup, _, _ = problem_of(other).setup(other)
    with pytest.raises(CheckpointError, match="another setup"):
        run(setup, treatment("ibm", {}), checkpoint=target)


def test_damaged_checkpoint_is_refused(tmp_path, capsys):
    target = tmp_path / f"{case_id(SMALL)}.npz"
    for content in (b"", b"not a checkpoint at all", b"PK\x03\x04" + bytes(100)):
        target.write_bytes(content)
        line = _one_line_error(_cli(SMALL, tmp_path), capsys)
        assert "is not a readable checkpoint" in line and str(target) in line and "delete it" in line
    # a real checkpoint cut short (a crash of the machine mid-write)
    assert main(_cli(SMALL, tmp_path / "whole")) == 0
    capsys.readouterr()
    whole = (tmp_path / "whole" / target.name).read_bytes()
    target.write_bytes(whole[: len(whole) // 2])
    assert "is not a readable checkpoint" in _one_line_error(_cli(SMALL, tmp_path), capsys)


def test_checkpoint_needs_large_kinematics_and_a_writable_folder(tmp_path, capsys):
    line = _one_line_error(["solve", "--checkpoint", str(tmp_path)], capsys)
    assert "--checkpoint is for load steps" in line
    with pytest.raises(Exception, match="--checkpoint is for load steps"):
        run_case(CaseSpec(), checkpoint=tmp_path / "x.npz")
    blocker = tmp_path / "file"
    blocker.write_text("")
    line = _one_line_error(_cli(SMALL, blocker), capsys)
    assert "cannot write to output folder" in line and str(blocker) in line
    line = _one_line_error(_cli(SMALL.with_(method="fem"), tmp_path), capsys)
    assert "not available for method 'fem'" in line


def test_fields_snapshots_are_refused_when_the_checkpoint_lacks_them(tmp_path):
    path = tmp_path / "c.npz"
    run_case(SMALL, checkpoint=path)                 # kept no fields
    with pytest.raises(CheckpointError, match="did not keep snapshots"):
        run_case(SMALL, keep_fields=True, checkpoint=path)


def test_study_checkpoints_only_big_large_cases():
    big = COLUMN.with_(cell=0.5, steps=40)                     # 10 x 50 / 0.5^2 x 4 = 8000 points x 40
    assert runner.checkpointed(big)
    assert not runner.checkpointed(COLUMN)                     # ~ 200 points x 12
    assert not runner.checkpointed(big.with_(method="fem"))
    assert not runner.checkpointed(CaseSpec(cell=0.1))         # small kinematics


def test_study_resumes_a_case_from_its_checkpoint(tmp_path, monkeypatch):
    """execute() with a checkpoint: a damaged one is deleted and the case runs afresh; the
    runner deletes it once the row is stored."""
    key = case_id(SMALL)
    path = tmp_path / f"{key}.npz"
    path.write_bytes(b"garbage")
    _, result, _ = runner.execute((key, SMALL, False, str(path)))
    expected = run_case(SMALL)
    assert result["status"] == "ok" and result["history"] == expected["history"]
    assert checkpoints.steps_stored(path) == SMALL.steps
    # a study run with every large case checkpointed leaves no checkpoint behind
    monkeypatch.setattr(runner, "CHECKPOINT_ABOVE", 0)
    spec = tmp_path / "study.toml"
    spec.write_text('title = "t"\n[[sweep]]\nname = "c"\nproblems = ["column"]\nmethods = ["nitsche"]\n'
                    'kinematics = "large"\nsteps = 2\nE = 1e4\nnu = 0.0\nload = 40000\nwidth = 10\nheight = 50\n'
                    'cell = 6.25\nppc = 2\nangle = 30\noffset = [0.3, 0.2]\n')
    out = tmp_path / "out"
    (out / runner.CHECKPOINTS).mkdir(parents=True)
    (out / runner.CHECKPOINTS / "0123456789abcdef.npz").write_bytes(b"stale")
    summary = runner.run_study(spec, out, jobs=1, progress=False, report=False)
    assert (summary.run, summary.failed) == (1, 0)
    assert list((out / runner.CHECKPOINTS).iterdir()) == []
    table = runner.read_results(out)
    assert table["err_u"].iloc[0] == expected["err_u"]


# the collapse problems' load steps: the footing at large strain (runs through), Hill's cylinder
# with F-bar (stopped at step 5 past its collapse; a resumed run solves that step again)
FOOTING = CaseSpec(problem="footing", method="penalty", cell=40.0, ppc=2, steps=6, kinematics="large")
HILL = CaseSpec(problem="hill-cylinder", method="ibm", cell=25.0, ppc=2, steps=5, basis="mpm", locking="fbar")


@pytest.mark.parametrize("spec", [FOOTING, HILL], ids=["footing-large", "hill-stopped"])
def test_collapse_problem_resumes_bit_identical(spec, tmp_path, monkeypatch):
    uninterrupted = run_case(spec, keep_fields=True)
    assert len(uninterrupted["newton_iterations"]) == (6 if spec is FOOTING else 4)
    assert (uninterrupted["stopped"] is None) == (spec is FOOTING)
    path = tmp_path / "collapse.npz"
    run_killed_before_step(spec, path, 3, monkeypatch)
    assert checkpoints.steps_stored(path) == 2
    assert len(checkpoints.load(path)[1]["curve"]) == 2            # the curve so far is saved with the steps

    resumed = run_case(spec, keep_fields=True, checkpoint=path)
    assert resumed.keys() == uninterrupted.keys()
    _same_record(resumed, uninterrupted, compared=())
    a, b = resumed["fields"], uninterrupted["fields"]
    assert a.keys() == b.keys() and len(a["x"]) > 0
    for name in a:
        assert np.asarray(a[name]).tobytes() == np.asarray(b[name]).tobytes(), name
    assert checkpoints.steps_stored(path) == len(uninterrupted["newton_iterations"])


def solve_footing(directory: Path) -> list[str]:
    return [sys.executable, "-m", "studies.cli", "solve", "--problem", "footing", "--kinematics", "large", "--method",
            "penalty", "--cell", "40", "--ppc", "2", "--steps", "20", "--checkpoint", str(directory), "--json"]


def test_footing_killed_with_sigkill_resumes_to_the_same_json(tmp_path):
    """--checkpoint reached the collapse problems' loop (it was dropped before, while the CLI said
    every step was saved)."""
    reference, resumed, _ = killed_and_resumed(solve_footing, tmp_path, 20)
    assert resumed == reference and len(resumed["q"]) == 20

def test_collapse_checkpoint_refusals(tmp_path, capsys):
    line = _one_line_error(["solve", "--problem", "footing", "--method", "fem", "--steps", "5",
                            "--checkpoint", str(tmp_path)], capsys)
    assert "--checkpoint is not available for method 'fem'" in line
    line = _one_line_error(["solve", "--problem", "ample-collapse", "--checkpoint", str(tmp_path)], capsys)
    assert line.endswith("--checkpoint is not available for 'ample-collapse' yet")
    assert not any(tmp_path.iterdir())


def test_study_checkpoint_estimate_counts_the_collapse_bodies():
    """The footing's 5 B x 3 B body (B = 160) and the cylinder's quarter ring, not width x height."""
    footing = CaseSpec(problem="footing", ppc=2, steps=40)              # 80 x 48 cells x 4 = 15360 points x 40
    assert runner.estimated_points(footing) == 15360
    assert runner.checkpointed(footing)
    assert runner.checkpointed(footing.with_(kinematics="large"))
    assert not runner.checkpointed(footing.with_(cell=40.0))           # 960 points x 40
    assert not runner.checkpointed(footing.with_(method="fem"))
    hill = CaseSpec(problem="hill-cylinder", ppc=2, steps=20, cell=2.0)
    assert runner.estimated_points(hill) == pytest.approx(np.pi / 4 * 3e4 / 4 * 4)
    assert runner.checkpointed(hill)
    assert not runner.checkpointed(CaseSpec(problem="ample-collapse", kinematics="large", cell=0.01, steps=100))
    assert runner.checkpointed(CaseSpec(problem="confined-block", load_type="settlement", material="von-mises",
                                        yield_stress=20.0, steps=40, cell=0.5, load=1.0))
