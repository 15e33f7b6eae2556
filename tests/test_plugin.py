"""A method and a problem from another package (examples/plugin, the entry-point groups ibm_mpm.methods
and ibm_mpm.problems): installed into a folder of its own, they appear in the command line, its help,
a solve (the method in both kinematics), a study and its report, with no change to ibm-mpm."""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / ".venv" / "bin" / "ibm-study"


@pytest.fixture(scope="module")
def environment(tmp_path_factory):
    """Environment variables under which `ibm-study` sees the plug-in (pip install --target)."""
    folder = tmp_path_factory.mktemp("plugin")
    source = shutil.copytree(ROOT / "examples" / "plugin", folder / "source")
    site = folder / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--target", str(site), str(source)], check=True, capture_output=True)
    return {**os.environ, "PYTHONPATH": str(site)}


def study(environment, *arguments, cwd=None) -> subprocess.CompletedProcess:
    command = [str(STUDY) if STUDY.exists() else shutil.which("ibm-study"), *arguments]
    return subprocess.run(command, env=environment, capture_output=True, text=True, cwd=cwd)


def solve(environment, *arguments) -> dict:
    done = study(environment, "solve", *arguments, "--json")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_the_help_lists_the_plugin_and_its_parameters(environment):
    text = study(environment, "solve", "--help").stdout
    assert re.search(r"^  penalty-particles +penalty at boundary particles", text, re.MULTILINE)
    assert "--particles-per-cell" in text and "methods: penalty, penalty-particles" in " ".join(text.split())


def test_the_plugin_solves_and_its_particles_converge_to_the_penalty(environment):
    """Evenly spaced particles integrate the penalty term with an error that falls as they are refined,
    towards the penalty's own (Gauss points per piece between grid lines)."""
    penalty = solve(environment, "--method", "penalty", "--angle", "30")
    coarse, fine = (solve(environment, "--method", "penalty-particles", "--angle", "30", "--particles-per-cell", n)
                    for n in ("2", "8"))
    assert coarse["n_particles"] == 60 and fine["n_particles"] == 240
    assert 1e-2 < coarse["err_u"] < 2e-2 and fine["err_u"] < 5e-5 and fine["err_u"] > penalty["err_u"]
    assert fine["err_reaction"] < 2e-6                  # its own reaction definition balances the loads


def test_the_plugin_problem_is_listed_and_converges(environment):
    """two-wave's exact field is smooth: the IBM's displacement error falls by more than 2.5 as h halves
    (3.3 measured, 4.1 on the built-in manufactured field)."""
    text = study(environment, "solve", "--help").stdout
    assert re.search(r"^  two-wave +\S", text, re.MULTILINE)
    coarse, fine = (solve(environment, "--problem", "two-wave", "--method", "ibm", "--angle", "30", "--ppc", "2",
                          "--cell", cell) for cell in ("10", "5"))
    assert coarse["problem"] == "two-wave" and coarse["reference"] == "exact"
    assert 2.5 < coarse["err_u"] / fine["err_u"] < 6 and fine["err_u"] < 0.06     # manufactured: 0.113, 0.028


def test_the_plugin_runs_the_load_steps(environment):
    arguments = ("--problem", "column", "--kinematics", "large", "--steps", "5", "--angle", "30")
    penalty = solve(environment, "--method", "penalty", *arguments)
    particles = solve(environment, "--method", "penalty-particles", *arguments)
    assert particles["support_threshold"] == 0.1 and particles["max_penetration"] == 0.0
    assert abs(particles["err_u"] - penalty["err_u"]) < 0.2 * penalty["err_u"]


def test_the_plugin_refuses_in_one_line(environment):
    done = study(environment, "solve", "--method", "penalty-particles", "--dim", "3")
    assert done.returncode == 2 and done.stderr.strip().splitlines() == [
        "ibm-study: error: method 'penalty-particles' refuses 3D cases (dim = 3): its particles are placed along 2D "
        "edges; allowed: ibm, ibm-limit, penalty, nitsche, lagrange, nodal, fem"]
    done = study(environment, "solve", "--method", "penalty-particles", "--particles-per-cell", "-1")
    assert done.returncode == 2 and "particles-per-cell -1.0 is not allowed; it must be in (0, 64]" in done.stderr


def test_a_study_sweeps_the_plugin_beside_the_built_in_methods(environment, tmp_path):
    spec = tmp_path / "plugin.toml"
    spec.write_text('title = "Plug-in"\n[base]\nproblem = "confined-block"\n'
                    '[[sweep]]\nname = "angles"\nmethods = ["penalty", "penalty-particles"]\nangle = [90, 30]\n'
                    'tables = ["method-angle"]\nfigures = ["error-vs-angle"]\n'
                    '[[sweep]]\nname = "density"\nmethods = ["penalty-particles"]\nangle = 30\n'
                    'particles_per_cell = [1, 2, 4]\n'
                    '[[sweep]]\nname = "problem"\nproblems = ["two-wave"]\nmethods = ["penalty-particles"]\n'
                    'angle = 30\n')
    done = study(environment, "run", str(spec), "--out", str(tmp_path / "out"), "--jobs", "1", "--quiet")
    assert done.returncode == 0, done.stderr
    rows = pd.read_parquet(tmp_path / "out" / "results.parquet")
    assert (rows["status"] == "ok").all() and len(rows) == 7          # the density sweep's 2 is the angles' case
    assert rows[rows["problem"] == "two-wave"]["err_u"].iloc[0] < 0.1
    block = rows[(rows["problem"] == "confined-block") & (rows["angle"] == 30)]
    density = block[block["method"] == "penalty-particles"].sort_values("particles_per_cell")
    assert list(density["particles_per_cell"]) == [1.0, 2.0, 4.0] and density["err_u"].is_monotonic_decreasing
    assert "penalty-particles" in (tmp_path / "out" / "index.html").read_text()
