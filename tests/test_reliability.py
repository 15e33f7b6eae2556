"""Ill-posed systems are reported, tiny cut cells are remedied, bad parameters are rejected; faults
of the environment (an output folder that cannot be written, a corrupt results store, an unreachable
scheduler, SIGTERM, a full disk) give one line on stderr and the right exit code, never a traceback."""
import errno
import json
import os
import re
import shutil
import signal
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ibm import Elastic, Loads, build_model, solve_ibm
from ibm.geometry.outline import rectangle
from ibm.exceptions import InputError, SolveError
from ibm.discretise.support import support_fractions
from studies.run import runner, store
from studies.run.case import CaseSpec, run_case
from studies.cli import main
from studies.run.runner import RunError, folder_lock, read_results, run_study
from studies.run.identity import case_id
from studies.run.spec import parse

MATERIAL = Elastic(1e4, 0.3)


def _pressed_block(kinds, angle=30.0):
    body = rectangle(100.0, 100.0, kinds, angle, np.array([3.7, 2.9]))
    direction = body.frame[:, 1]
    loads = Loads(tractions={2: lambda x: np.broadcast_to(-10.0 * direction, (len(x), 2))})
    return build_model(body, MATERIAL, loads, 10.0, 1)


@pytest.mark.parametrize("kinds,mode", [
    (("roller", "free", "traction", "free"), "translation"),         # slides along the base
    (("free", "free", "traction", "free"), "translation"),           # nothing holds it
    (("roller", "free", "traction", "roller"), None),                  # base + one side: held
])
def test_free_rigid_body_motion_is_reported(kinds, mode):
    model = _pressed_block(kinds)
    if mode is None:
        assert np.isfinite(solve_ibm(model).u).all()
        return
    with pytest.raises(SolveError, match=f"rigid-body motion is not constrained.*{mode}"):
        solve_ibm(model)


@pytest.mark.parametrize("gap", [1e-2, 1e-6, 1e-9, 1e-11])
def test_tiny_cut_cells_are_extended_and_stay_well_conditioned(gap):
    """The left edge a distance gap*h past a grid line leaves nodes with support ~gap^2."""
    spec = CaseSpec(angle=90.0, offset=(1 - gap, 0.29))
    remedied = run_case(spec)
    assert remedied["n_extended"] > 0 and remedied["min_support"] < 1e-4
    assert remedied["cond_est"] < 1e7, remedied["cond_est"]
    assert remedied["err_u"] < 3e-7 and remedied["err_sigma"] < 1.4e-6 and remedied["err_sigma_max"] < 1e-5
    bare = run_case(spec.with_(method_parameters={"support_threshold": 0.0}))
    assert bare["n_extended"] == 0
    if gap <= 1e-9:   # without the remedy the system is numerically singular
        assert bare["cond_est"] > 1e15


def test_extension_keeps_linear_fields():
    """The tied nodes extrapolate bilinearly, so the IBM's patch error stays O(delta)."""
    for threshold in (0.0, 0.3):
        record = run_case(CaseSpec(angle=30.0, method_parameters={"support_threshold": threshold}))
        assert record["err_u"] < 3e-7 and record["err_sigma"] < 1.4e-6
        if threshold:
            assert record["n_extended"] > 10


def test_support_fractions_of_full_nodes_are_one():
    model = _pressed_block(("roller", "roller", "traction", "roller"), angle=90.0)
    fraction = support_fractions(model.grid, model.points)
    assert fraction.max() == pytest.approx(1.0, abs=1e-12)
    assert abs(fraction.sum() * 100.0 - 1e4) < 1e-9   # sum_I int N_I = area


@pytest.mark.parametrize("parameters,needle", [
    ({"beta0": 10.0}, "beta0 is not a parameter of method 'ibm'"),
    ({"support_threshold": -0.1}, "support-threshold -0.1"),
    ({"support_threshold": 0.7}, "support-threshold 0.7"),
    ({"delta_rel": float("inf")}, "delta-rel inf"),
])
def test_bad_method_parameters_are_rejected(parameters, needle):
    with pytest.raises(InputError, match=needle):
        run_case(CaseSpec(method_parameters=parameters))


def test_condition_estimate_is_deterministic_and_leaves_the_global_generator_alone():
    np.random.seed(1)
    first = run_case(CaseSpec(angle=30.0))["cond_est"]
    after_first = np.random.random()
    np.random.seed(2)
    np.random.random(size=17)
    assert run_case(CaseSpec(angle=30.0))["cond_est"] == first
    np.random.seed(1)
    run_case(CaseSpec(angle=30.0))
    assert np.random.random() == after_first


def test_extension_reduce_equals_the_general_product():
    from ibm.discretise.assembly import restrict
    from ibm.quadrature.bands import band_quadrature
    from ibm import dirichlet
    from ibm.small import forms
    from ibm.solvers.linear import active_dofs
    from ibm.discretise.support import extension
    from studies.run.case import instance_of
    instance = instance_of(CaseSpec(angle=90.0, offset=(1 - 1e-6, 0.29)))
    model = build_model(instance.body, MATERIAL, instance.loads, 10.0, 1)
    delta = 1e-5 * model.grid.h
    points, band = model.points.quadrature(), band_quadrature(model.body, model.grid, delta)
    K = forms.corrected_stiffness(model, points, band, lambda x: dirichlet.matrix(model.body, x, delta))
    dofs = active_dofs(model.grid, points.cells, band.cells)
    K = restrict(K, dofs)
    f = np.random.default_rng(0).random(len(dofs))
    tie = extension(model.grid, model.points, dofs, 1e-4)
    assert len(tie.extended) > 0
    reduced, g = tie.reduce(K, f)
    general = tie.T.T @ K @ tie.T
    assert abs(reduced - general).max() <= 1e-12 * abs(general).max()
    assert np.abs(g - tie.T.T @ f).max() <= 1e-12 * np.abs(f).max()
    # the same straight from the grid matrix's slots (what solve_ibm does): identical
    grid_matrix = forms.corrected_stiffness(model, points, band, lambda x: dirichlet.matrix(model.body, x, delta),
                                            assemble=False)
    f_grid = np.zeros(2 * model.grid.n_nodes)
    f_grid[dofs] = f
    from_slots, g_slots = tie.reduce(grid_matrix, f_grid, dofs)
    assert abs(from_slots - reduced).max() == 0 and np.array_equal(g_slots, g)


# --- faults of the environment: one line, the right exit code, never a traceback ------------------

TINY = """
title = "reliability test"
[base]
cell = 50.0
[[sweep]]
name = "angles"
methods = ["ibm"]
angle = [90, 30]
"""


def one_line(captured) -> str:
    """The only line on stderr (and no traceback)."""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    return lines[0]


@pytest.fixture
def tiny(tmp_path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    """The tiny study run to the end, report included (copy it before changing it)."""
    folder = tmp_path_factory.mktemp("finished")
    summary = run_study(parse(TINY), folder / "out", jobs=1, progress=False)
    assert (summary.run, summary.failed) == (2, 0)
    return folder / "out"


def _blocked(tmp_path) -> Path:
    """A folder that cannot be created, by root too: its parent is a regular file."""
    (tmp_path / "file.txt").write_text("not a folder")
    return tmp_path / "file.txt" / "sub"


@pytest.mark.parametrize("command", ["solve", "run"])
def test_output_folder_under_a_file_is_one_line_exit_2(command, tiny, tmp_path, capsys):
    out = _blocked(tmp_path)
    arguments = ["solve", "--vtk", str(out)] if command == "solve" else ["run", str(tiny), "--out", str(out), "--quiet"]
    assert main(arguments) == 2
    assert one_line(capsys.readouterr()) == f"ibm-study: error: cannot write to output folder {str(out)!r}: not a directory"


def test_output_folder_that_is_a_file_is_one_line_exit_2(tiny, tmp_path, capsys):
    out = tmp_path / "results.txt"
    out.write_text("")
    assert main(["run", str(tiny), "--out", str(out), "--quiet"]) == 2
    assert one_line(capsys.readouterr()) == (f"ibm-study: error: cannot write to output folder {str(out)!r}: "
                                             f"it is a file, not a folder")


def test_report_into_a_folder_it_cannot_write_is_one_line_exit_2(finished, tmp_path, capsys):
    out = Path(shutil.copytree(finished, tmp_path / "study"))
    shutil.rmtree(out / "tables")
    (out / "tables").write_text("in the way")
    assert main(["report", str(out)]) == 2
    assert one_line(capsys.readouterr()) == (f"ibm-study: error: cannot write to output folder "
                                             f"{str(out / 'tables')!r}: it is a file, not a folder")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
@pytest.mark.parametrize("command", ["solve", "run", "report"])
def test_read_only_output_folder_is_one_line_exit_2(command, finished, tiny, tmp_path, capsys):
    study = Path(shutil.copytree(finished, tmp_path / "study"))
    locked = tmp_path / "locked"
    locked.mkdir()
    out = {"solve": locked / "vtk", "run": locked / "out", "report": study}[command]
    arguments = {"solve": ["solve", "--vtk", str(out)], "run": ["run", str(tiny), "--out", str(out), "--quiet"],
                 "report": ["report", str(out)]}[command]
    for folder in (locked, study):
        folder.chmod(0o500)
    try:
        assert main(arguments) == 2
    finally:
        for folder in (locked, study):
            folder.chmod(0o700)
    line = one_line(capsys.readouterr())
    assert line.startswith(f"ibm-study: error: cannot write to output folder {str(out)!r}: permission denied")


def _foreign_parquet(path: Path) -> None:
    pd.DataFrame({"x": [1.0, 2.0], "label": ["a", "b"]}).to_parquet(path)


@pytest.mark.parametrize("make", [lambda p: p.write_bytes(b"\x00garbage\xff" * 50), lambda p: p.write_bytes(b""),
                                  _foreign_parquet], ids=["garbage", "empty", "foreign"])
def test_corrupt_store_is_moved_aside_and_its_cases_run_again(make, tiny, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    make(out / runner.RESULTS)
    before = (out / runner.RESULTS).read_bytes()
    assert main(["run", str(tiny), "--out", str(out), "--quiet", "--no-report"]) == 0
    line = one_line(capsys.readouterr())
    [aside] = out.glob(f"{runner.RESULTS}.corrupt-*")
    assert re.fullmatch(rf"{re.escape(runner.RESULTS)}\.corrupt-\d{{8}}-\d{{6}}", aside.name)
    assert aside.read_bytes() == before                      # kept as it was, for a look
    assert line.startswith(f"ibm-study: warning: {str(out / runner.RESULTS)!r} is ")
    assert f"moved it to {str(aside)!r}" in line and "its cases run again" in line
    results = read_results(out)
    assert sorted(results["case_id"]) == sorted(case_id(c) for c in parse(TINY).cases())
    assert (results["status"] == "ok").all()


def test_a_store_that_reads_is_kept(finished, tiny, tmp_path, capsys):
    out = Path(shutil.copytree(finished, tmp_path / "study"))
    table = read_results(out)
    table["column_of_a_later_version"] = 1.0                 # unknown columns do not make it foreign
    table.to_parquet(out / runner.RESULTS)
    summary = run_study(tiny, out, jobs=1, progress=False, report=False)
    assert (summary.reused, summary.run) == (2, 0)
    assert capsys.readouterr().err == "" and not list(out.glob("*.corrupt-*"))


@pytest.mark.parametrize("make", [lambda p: p.write_bytes(b"PAR1 not really"), _foreign_parquet],
                         ids=["garbage", "foreign"])
def test_report_of_a_corrupt_store_is_one_line_exit_2(make, finished, tmp_path, capsys):
    out = Path(shutil.copytree(finished, tmp_path / "study"))
    make(out / runner.RESULTS)
    assert main(["report", str(out)]) == 2
    line = one_line(capsys.readouterr())
    assert line.startswith(f"ibm-study: error: {str(out / runner.RESULTS)!r} is no")
    assert "moves it aside" in line and (out / runner.RESULTS).exists()    # the report moves nothing


def test_unreachable_scheduler_is_a_bounded_wait_then_one_line_exit_3(tiny, tmp_path, capfd, monkeypatch):
    pytest.importorskip("distributed")
    assert runner.SCHEDULER_TIMEOUT <= 10
    monkeypatch.setattr(runner, "SCHEDULER_TIMEOUT", 1.0)
    start = time.monotonic()
    assert main(["run", str(tiny), "--out", str(tmp_path / "out"), "--scheduler", "tcp://127.0.0.1:9", "--quiet"]) == 3
    assert time.monotonic() - start < 8
    line = one_line(capfd.readouterr())
    assert line == ("ibm-study: run failed: no dask scheduler answered at tcp://127.0.0.1:9 within 1 s: "
                    "is a dask scheduler running there? start one with `dask scheduler`, and check the host and port")
    with folder_lock(tmp_path / "out"):                      # released
        pass


def test_sigterm_stops_a_run_like_ctrl_c(tmp_path):
    from tests.studies.run.test_runner import SPEC, _interrupt
    spec = tmp_path / "runner.toml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    code, before, stderr = _interrupt(spec, out, signal.SIGTERM)
    assert code == 130 and "Traceback" not in stderr
    assert "interrupted by SIGTERM" in stderr and "run the same command again" in stderr
    assert 3 <= len(before) < 36 and before["case_id"].is_unique
    with folder_lock(out):                                   # released
        pass
    summary = run_study(spec, out, jobs=2, progress=False, report=False)
    assert (summary.reused, summary.run) == (len(before), 36 - len(before))
    assert len(read_results(out)) == 36 and not list(out.glob(".*.tmp"))


_WRITE_LINE = store.write_line      # the real one, before any test patches it


def _full_disk_on_call(monkeypatch, number: int) -> None:
    """The store's appended line fails as on a full disk from call `number` on, half-way through."""
    calls, real = [], _WRITE_LINE

    def write(handle, line):
        calls.append(line)
        if len(calls) < number:
            return real(handle, line)
        handle.write(line[:len(line) // 2])
        handle.flush()
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(store, "write_line", write)


def test_full_disk_stops_the_run_and_keeps_the_cases_stored_before(tiny, tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    _full_disk_on_call(monkeypatch, 2)
    with pytest.raises(SolveError, match=r"results\.log'?: no space left on device") as caught:
        run_study(tiny, out, jobs=1, progress=False, report=False)
    assert isinstance(caught.value, RunError)
    kept = read_results(out)                                 # readable, with the case finished before
    assert len(kept) == 1 and (kept["status"] == "ok").all()   # the half-written line is dropped
    assert not list(out.glob(".*.tmp"))                      # no half-written copy left
    with folder_lock(out):                                   # released
        pass

    other = tmp_path / "other"
    _full_disk_on_call(monkeypatch, 2)
    assert main(["run", str(tiny), "--out", str(other), "--quiet", "--no-report"]) == 3
    assert one_line(capsys.readouterr()) == (
        f"ibm-study: run failed: cannot write {str(other / runner.LOG)!r}: no space left on device; "
        f"it keeps the 1 case(s) stored before, run again to finish the rest")
    assert len(read_results(other)) == 1

    monkeypatch.undo()                                       # space again: the run finishes
    summary = run_study(tiny, out, jobs=1, progress=False, report=False)
    assert (summary.reused, summary.run) == (1, 1) and len(read_results(out)) == 2


def test_a_finished_case_is_one_appended_line_and_the_table_is_written_once(tiny, tmp_path):
    from studies.run.store import LOG, RESULTS, Store
    out = tmp_path / "out"
    run_study(tiny, out, jobs=1, progress=False, report=False)
    table = (out / RESULTS).read_bytes()
    assert not (out / LOG).exists()                          # compacted when the run ended
    stored = Store(out)
    rows = dict(stored.rows)
    for number, (key, row) in enumerate(sorted(rows.items())):
        stored.add(f"{key[:-1]}x{number}", {**row, "case_id": f"{key[:-1]}x{number}"})
        assert (out / RESULTS).read_bytes() == table         # the table is not rewritten
        assert (out / LOG).read_bytes().count(b"\n") == number + 1
    stored.close()
    assert len(read_results(out)) == 2 * len(rows)           # readers merge table and log
    stored.compact()
    assert not (out / LOG).exists() and len(read_results(out)) == 2 * len(rows)


def test_a_log_line_cut_short_by_a_kill_is_dropped_and_a_corrupt_log_moved_aside(tiny, tmp_path, capsys):
    from studies.run.store import LOG, RESULTS, Store
    out = tmp_path / "out"
    run_study(tiny, out, jobs=1, progress=False, report=False)
    rows = Store(out).rows
    (out / RESULTS).unlink()
    lines = [json.dumps(row, default=lambda value: value.item()) for row in rows.values()]
    (out / LOG).write_text("\n".join(lines) + "\n" + lines[0][:20])            # torn: no newline at its end
    assert len(read_results(out)) == len(rows)
    summary = run_study(tiny, out, jobs=1, progress=False, report=False)
    assert (summary.reused, summary.run) == (len(rows), 0) and not (out / LOG).exists()
    assert capsys.readouterr().err == ""                                       # nothing to warn about
    (out / RESULTS).unlink()
    (out / LOG).write_text(lines[0] + "\n" + "garbage\n" + "\n".join(lines[1:]) + "\n")
    summary = run_study(tiny, out, jobs=1, progress=False, report=False)
    assert (summary.reused, summary.run) == (len(rows), 0)                      # every readable row kept
    [aside] = out.glob(f"{LOG}.corrupt-*")
    line = one_line(capsys.readouterr())
    assert line.startswith(f"ibm-study: warning: {str(out / LOG)!r} holds lines that are no results rows")
    assert str(aside) in line and "kept" in line


# --- Ctrl-C and SIGTERM in every subcommand: one line, exit 130 ----------------------------------

def _stop_by(how: str):
    """A stand-in for a subcommand's work that is stopped: Ctrl-C, or a SIGTERM to this process."""
    def stopped(*args, **kwargs):
        if how == "SIGINT":
            raise KeyboardInterrupt
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)                                        # the handler raises before this ends
        raise AssertionError("SIGTERM did not stop the command")
    return stopped


def _unhandled(signum, frame):
    raise AssertionError("SIGTERM reached the caller's handler, not the command's")


INTERRUPTED = {      # subcommand -> (its arguments, the module and function its work is in)
    "solve": (["solve"], "studies.cli", "run_case"),
    "converge": (["converge", "--levels", "2"], "studies.run.convergence", "converge"),
    "report": (["report", "DIR"], "studies.report.page", "write_report"),
    "seed": (["seed"], "studies.run.seed", "report"),
    "compare": (["compare"], "studies.run.comparison", "report"),
    "run": (["run", "SPEC", "--quiet"], "studies.run.runner", "run_study"),
}


@pytest.mark.parametrize("how", ["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("command", sorted(INTERRUPTED))
def test_every_subcommand_stops_on_ctrl_c_and_sigterm_with_one_line_exit_130(command, how, tmp_path, capsys,
                                                                             monkeypatch):
    import importlib
    arguments, module, function = INTERRUPTED[command]
    monkeypatch.setattr(importlib.import_module(module), function, _stop_by(how))
    arguments = [str(tmp_path) if a in ("DIR", "SPEC") else a for a in arguments]
    before = signal.signal(signal.SIGTERM, _unhandled)     # a SIGTERM main lets through fails the test
    try:
        code = main(arguments)
    except KeyboardInterrupt:
        pytest.fail(f"{how} escaped `ibm-study {command}`")
    finally:
        assert signal.signal(signal.SIGTERM, before) is _unhandled      # main put the handler back
    captured = capsys.readouterr()
    by = " by SIGTERM" if how == "SIGTERM" else ""
    tail = "; finished cases are stored, run again to resume" if command == "run" else ""
    assert code == 130 and one_line(captured) == f"ibm-study: interrupted{by}{tail}"
    assert captured.out == ""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_solve_stopped_mid_run_is_one_line_exit_130_naming_its_checkpoint(sig, tmp_path):
    """A large-strain footing (20 load steps, ~4 s) stopped once its first step is saved."""
    from ibm.large import checkpoint as checkpoints
    from tests.ibm.large.test_checkpoint import solve_footing, started_until_stored
    process, stored = started_until_stored(solve_footing(tmp_path), tmp_path, 1)
    assert process.poll() is None and stored >= 1, "the signal must land mid-run"
    start = time.monotonic()
    process.send_signal(sig)
    out, err = process.communicate(timeout=60)
    assert time.monotonic() - start < 5                      # within the step it was solving
    [path] = tmp_path.glob("*.npz")
    by = " by SIGTERM" if sig == signal.SIGTERM else ""
    assert process.returncode == 130 and out == ""
    assert one_line(type("Captured", (), {"err": err})) == (
        f"ibm-study: interrupted{by}; checkpoint {str(path)!r} keeps the finished load steps, run the same "
        f"command again to resume")
    assert 1 <= checkpoints.steps_stored(path) < 20
