"""The passive wall: a smooth rigid wall pushed into a von Mises layer on a smooth base. Weightless, the
layer's state is linear and every consistent method reproduces it to round-off at every step (the penalty
to O(1/beta0)) at any angle and placement; with its weight the error norms fall with h and the wall's force
stays on the exact one; pushed on, the force reaches Rankine's gamma H^2 / 2 + 2 c H; bad input is one line;
a killed run resumes bit-identically."""
import json
import subprocess
import sys

import numpy as np
import pytest

from ibm.exceptions import InputError
from studies.run.case import CaseSpec, run_case, validate
from tests.ibm.large.test_checkpoint import _same_record, run_killed_before_step

WALL = CaseSpec(problem="passive-wall", method="lagrange", angle=30.0, ppc=2, steps=10, material="von-mises",
                yield_stress=100.0, load=5.0, load_type="settlement")
C = 100.0 / np.sqrt(3)


@pytest.mark.parametrize("angle, offset", [(30.0, (0.37, 0.29)), (0.0, (0.5, 0.0)), (77.0, (0.11, 0.83))])
@pytest.mark.parametrize("method, bound", [("lagrange", 1e-8), ("nitsche", 1e-8), ("penalty", 1e-5)])
def test_weightless_layer_is_reproduced_at_every_step(method, bound, angle, offset):
    """Exact to the Newton tolerance (a relative residual 1e-10 leaves err_u up to 1.7e-9, measured at 77
    degrees; lagrange 9.5e-15 at 30 where one more iteration ran), the penalty to O(1/beta0) (err_u 1.8e-7)."""
    record = run_case(WALL.with_(method=method, angle=angle, offset=offset))
    history = record["history"]
    assert max(s["err_u"] for s in history) < bound and max(s["err_sigma"] for s in history) < bound
    for s in history:
        assert s["P"] == pytest.approx(s["P_exact"], rel=bound)
        assert abs(s["shear_on_wall"]) < 1e-9 * s["P"]          # the smooth wall carries no shear
    # step 1 is elastic (uniaxial stress in plane strain): P = E / (1 - nu^2) (s / 10 / L) H
    assert history[0]["P_exact"] == pytest.approx(1e4 / (1 - 0.09) * 0.005 * 100, rel=1e-10)
    # 5 yield strains on, the force is Rankine's 2 c H (weightless) to 2.1e-5
    assert record["P_rankine"] == pytest.approx(2 * C * 100, rel=1e-14)
    assert record["P_exact"] / record["P_rankine"] - 1 == pytest.approx(-2.13e-5, rel=0.01)
    assert record["active_length"] == pytest.approx(100.0, rel=1e-12) and record["step_cuts"] == 0
    # no deeper than the displacement's own bound allows over the wall's travel of 5 (the Newton tolerance's
    # 2.3e-10 for lagrange at 30 degrees on one machine, 1e-14 where one more iteration ran); the penalty O(1/beta0)
    assert record["max_penetration"] < (1e-6 if method == "penalty" else bound * WALL.load)


def test_layer_with_its_weight_converges_on_the_exact_state_and_rankine():
    """gamma = 0.5 (gamma H = 50 against 2 c = 115): err_sigma 7.8e-3 and 4.0e-3 at h = 10 and 5 (the point
    stresses are O(h)); the force within 1e-6 of the exact one and 3.2e-4 below Rankine's gamma H^2 / 2 + 2 c H."""
    records = [run_case(WALL.with_(unit_weight=0.5, cell=h)) for h in (10.0, 5.0)]
    rate = np.log2(records[0]["err_sigma"] / records[1]["err_sigma"])
    assert rate > 0.9 and records[1]["err_sigma"] < 5e-3
    assert records[0]["err_u"] / records[1]["err_u"] > 3            # measured 6.2e-4 and 1.1e-4
    for record in records:
        assert record["P"] == pytest.approx(record["P_exact"], rel=2e-6)
        assert record["P_rankine"] == pytest.approx(0.5 * 100 ** 2 / 2 + 2 * C * 100, rel=1e-14)
        assert record["P"] / record["P_rankine"] - 1 == pytest.approx(-3.2e-4, rel=0.05)


@pytest.mark.parametrize("changes, words", [
    ({"material": "elastic", "yield_stress": 0.0}, "material 'elastic' is not allowed for problem 'passive-wall'"),
    ({"friction": 0.2}, "has a smooth wall"),
    ({"adhesion": 2.0}, "has a smooth wall"),
    ({"load": 11.0}, r"must be in \(0, width / 10 = 10\]"),
    ({"load": 0.0}, "is not allowed for problem 'passive-wall'"),
    ({"kinematics": "large"}, "kinematics 'large' is not allowed for problem 'passive-wall'"),
    ({"method": "ibm"}, "method 'ibm' refuses contact walls"),
    ({"unit_weight": -1.0}, "unit-weight -1.0 is not allowed"),
    ({"unit_weight": float("nan")}, "unit-weight nan is not allowed"),
    ({"problem": "hertz", "material": "elastic", "yield_stress": 0.0, "unit_weight": 1.0, "load": 1.0},
     "unit-weight 1 is for a problem with a soil's weight"),
])
def test_bad_input_is_one_line(changes, words):
    with pytest.raises(InputError, match=words):
        validate(WALL.with_(**changes))


def test_command_line_defaults_and_report():
    command = [sys.executable, "-m", "studies.cli", "solve", "--problem", "passive-wall", "--method", "nitsche",
               "--material", "von-mises", "--yield-stress", "100", "--steps", "4", "--ppc", "2", "--unit-weight",
               "0.5", "--json"]
    record = json.loads(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
    assert record["load"] == 5.0 and record["unit_weight"] == 0.5         # the default push: 0.05 L
    for key in ("contact_force", "active_length", "P", "P_exact", "P_rankine", "history", "max_penetration"):
        assert key in record, key
    assert len(record["history"]) == 4 and record["P"] == pytest.approx(record["P_exact"], rel=1e-5)
    bad = subprocess.run(command[:-3] + ["--unit-weight=-2"], capture_output=True, text=True)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "unit-weight -2" in bad.stderr


def test_killed_run_resumes_bit_identical(tmp_path, monkeypatch):
    """The exact state is integrated again over the resumed run's steps: the same record."""
    spec = WALL.with_(unit_weight=0.5, method="nitsche")
    uninterrupted = run_case(spec)
    path = tmp_path / "wall.npz"
    run_killed_before_step(spec, path, 5, monkeypatch, keep_fields=False)
    resumed = run_case(spec, checkpoint=path)
    _same_record(resumed, uninterrupted, compared=())
