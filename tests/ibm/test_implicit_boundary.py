"""The IBM solver on the seed's confined block: seed gates, delta rate, grid symmetries, CLI."""
import json
import subprocess
import sys

import numpy as np
import pytest

from studies.run.case import CaseSpec, run_case
from studies.cli import main
from studies.run.seed import PAPER
from ibm.geometry.frames import frame_of_angle

# Recorded with the defaults of CaseSpec (delta/h = 1e-5, offset (0.37, 0.29)), ~1.5x margin.
SEED_THRESHOLDS = {90.0: (3e-7, 1.4e-6), 45.0: (3e-7, 1.5e-6), 30.0: (3e-7, 1.4e-6)}


@pytest.mark.parametrize("angle", sorted(PAPER))
def test_seed_table_at_or_below_paper_and_recorded_thresholds(angle):
    record = run_case(CaseSpec(angle=angle))
    paper_u, paper_sigma = PAPER[angle]
    max_u, max_sigma = SEED_THRESHOLDS[angle]
    assert record["err_u"] <= paper_u and record["err_sigma"] <= paper_sigma
    assert record["err_u"] <= max_u, f"seed {angle} deg: err_u {record['err_u']:.3g} > threshold {max_u:.3g}"
    assert record["err_sigma"] <= max_sigma, \
        f"seed {angle} deg: err_sigma {record['err_sigma']:.3g} > threshold {max_sigma:.3g}"


@pytest.mark.parametrize("angle", [90.0, 30.0])
def test_error_is_linear_in_delta(angle):
    deltas = np.array([1e-3, 1e-4, 1e-5, 1e-6])     # the asymptotic range; 1e-2 is pre-asymptotic
    errors = [run_case(CaseSpec(angle=angle, method_parameters={"delta_rel": d})) for d in deltas]
    for key in ("err_u", "err_sigma"):
        slope = np.polyfit(np.log(deltas), np.log([e[key] for e in errors]), 1)[0]
        assert abs(slope - 1) < 0.05, f"{key} slope {slope:.3f}"


def _wrap(offset):
    """Offsets modulo whole cells, in [0, 1) (np.mod(-1e-300, 1.0) is exactly 1.0)."""
    offset = np.mod(offset, 1.0)
    return tuple(np.where(offset >= 1.0, 0.0, offset))


def _turned(angle, offset, h=10.0):
    """The same configuration turned by +90 degrees about a grid node."""
    c = np.array(offset) * h
    return angle + 90.0, _wrap(np.array([-c[1], c[0]]) / h)


def _mirrored(angle, offset, h=10.0, size=100.0):
    """The same configuration mirrored in a vertical grid line (x -> -x)."""
    far_corner = np.array(offset) * h + size * frame_of_angle(angle)[:, 0]
    return 180.0 - angle, _wrap(np.array([-far_corner[0], far_corner[1]]) / h)


@pytest.mark.parametrize("transform", [_turned, _mirrored])
@pytest.mark.parametrize("angle,offset", [(30.0, (0.37, 0.29)), (45.0, (0.1, 0.8)), (63.0, (0.55, 0.02))])
def test_grid_symmetries_leave_errors_unchanged(transform, angle, offset):
    base = CaseSpec(angle=angle, offset=offset, method_parameters={"delta_rel": 1e-3})
    other_angle, other_offset = transform(angle, offset)
    a = run_case(base)
    b = run_case(base.with_(angle=other_angle, offset=other_offset))
    assert a["ndof"] == b["ndof"] and a["npoints"] == b["npoints"]
    assert_same_errors(a, b)


def assert_same_errors(a, b):
    """Errors are relative to |u|, so round-off in u_h bounds their difference absolutely:
    ~1e-12 in the volume-weighted norms; up to cond * eps in the max norms, which see the
    single worst point. A configuration that is not the image differs by ~1e-7 or more."""
    rounding = 10 * np.finfo(float).eps * max(a["cond_est"], b["cond_est"])
    for key in ("err_u", "err_sigma"):
        assert abs(a[key] - b[key]) <= 1e-10, (key, a[key], b[key])
    for key in ("err_u_max", "err_sigma_max"):
        assert abs(a[key] - b[key]) <= max(1e-10, rounding), (key, a[key], b[key], rounding)


def test_cli_json_has_the_promised_keys(capsys):
    assert main(["solve", "--angle", "45", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    for key in ("problem", "method", "angle", "cell", "ppc", "delta_rel", "offset", "ndof", "npoints",
                "err_u", "err_sigma", "err_u_max", "err_sigma_max", "time_s"):
        assert key in record
    assert record["angle"] == 45.0 and record["delta_rel"] == 1e-5 and record["npoints"] > 0


@pytest.mark.parametrize("arguments,needle", [
    (["--angle", "nan"], "angle nan"),
    (["--ppc", "1.5"], "'1.5'"),
])
def test_cli_bad_arguments_exit_2_with_one_line(arguments, needle):
    """The real process: exit code 2, one line on stderr, no traceback (more cases in test_bad_input)."""
    result = subprocess.run([sys.executable, "-m", "studies.cli", "solve", *arguments],
                            capture_output=True, text=True)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], result.stderr
    assert "Traceback" not in result.stderr and result.stdout == ""


@pytest.mark.parametrize("angle,offset", [(90.0, (0.0, 0.0)), (45.0, (0.1, 0.9)), (90.0, (0.5, 0.0))])
def test_edges_on_grid_lines_give_no_rounding_slivers(angle, offset):
    """Edges lying on grid lines once gave nodes outside the body a support of ~1e-15
    (cond ~1e22); the band geometry now drops slivers of rounding."""
    record = run_case(CaseSpec(angle=angle, offset=offset))
    assert record["cond_est"] < 1e11, f"cond_est {record['cond_est']:.3g}"
    assert record["err_u"] < 3e-7
