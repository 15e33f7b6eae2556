"""The frictional block: pressed on an inclined rigid wall, then sheared; Coulomb and Tresca stick then
slip, exact at every step. The penalty reproduces it to O(1/beta0), with the wall's forces, the
contact and slip lengths and no more penetration than p / beta; bad input is one line; a killed run
resumes bit-identically."""
import json
import subprocess
import sys

import numpy as np
import pytest

from ibm.exceptions import InputError
from studies.run.case import CaseSpec, run_case, validate
from tests.ibm.large.test_checkpoint import _same_record, run_killed_before_step

BLOCK = CaseSpec(problem="frictional-block", method="penalty", angle=30.0, ppc=2, steps=8, friction=0.3)


def _beta(record):
    return record["beta0"] * (1e4 / ((1 + 0.3) * (1 - 2 * 0.3)) * (1 - 0.3)) / record["cell"]


@pytest.mark.parametrize("angle, offset", [(30.0, (0.37, 0.29)), (0.0, (0.5, 0.0)), (77.0, (0.11, 0.83)),
                                           (90.0, (0.0, 0.0))])
def test_penalty_reproduces_coulomb_stick_then_slip(angle, offset):
    record = run_case(BLOCK.with_(angle=angle, offset=offset))
    # every error of the penalty is O(1/beta0): measured 3.3e-7 and 8.1e-7 at beta0 = 1e6, 30 degrees
    assert record["err_u"] < 1e-6 and record["err_sigma"] < 2e-6
    assert record["P"] == pytest.approx(record["P_exact"], rel=2e-6) and record["P_exact"] == 1000.0
    assert record["T"] == pytest.approx(record["T_exact"], rel=2e-6) and record["T_exact"] == 300.0
    assert record["active_length"] == pytest.approx(100.0, rel=1e-12) == record["active_length_exact"]
    assert record["slip_length"] == pytest.approx(100.0, rel=1e-12) == record["slip_length_exact"]
    history = record["history"]
    # pressed (steps 1-4), stuck (5: t = 0.625), slipping from t = 1/sqrt(2) on (6-8)
    assert [s["slip_length_exact"] for s in history] == [0.0] * 5 + [100.0] * 3
    assert [s["slip_length"] for s in history] == pytest.approx([0.0] * 5 + [100.0] * 3, rel=1e-12)
    assert history[4]["T"] == pytest.approx(300.0 * (1 + 2 ** 0.5) / 4, rel=2e-6)      # stick: tau = G s / H
    assert history[4]["T_exact"] == pytest.approx(300.0 * (1 + 2 ** 0.5) / 4, rel=1e-14)
    # the penetration is the penalty's p / beta, never more
    assert record["max_penetration"] == pytest.approx(10.0 / _beta(record), rel=1e-3)
    # only the step that crosses from stick to slip may cut (an iterate that holds the whole base tips the
    # block); every step in stick or in slip converges in at most three iterations
    assert all(s["cuts"] == 0 and s["newton_iterations"] <= 3 for k, s in enumerate(history) if k != 5)
    assert history[5]["cuts"] <= 2
    # every wall point makes contact in step 1 and goes from stick to slip in step 6, and only then
    changes = [s["active_set_changes"] for s in history]
    assert changes[0] > 0 and changes == [changes[0], 0, 0, 0, 0, changes[0], 0, 0]


@pytest.mark.parametrize("angle, offset, friction, adhesion", [
    (30.0, (0.37, 0.29), 0.3, 0.0), (77.0, (0.11, 0.83), 0.3, 0.0), (0.0, (0.5, 0.0), 0.0, 2.0),
    (30.0, (0.37, 0.29), 0.0, 0.0)])
@pytest.mark.parametrize("method", ["nitsche", "lagrange"])
def test_consistent_methods_reproduce_it_to_round_off(method, angle, offset, friction, adhesion):
    """Nitsche and the multipliers are consistent: exact to round-off at every step (measured err_u 8.7e-12
    and 1.5e-13 at 30 degrees), no penetration beyond round-off, no step cut."""
    record = run_case(BLOCK.with_(method=method, angle=angle, offset=offset, friction=friction, adhesion=adhesion))
    assert max(s["err_u"] for s in record["history"]) < 1e-10
    assert max(s["err_sigma"] for s in record["history"]) < 1e-10
    for s in record["history"]:
        assert s["P"] == pytest.approx(s["P_exact"], rel=1e-10)
        assert abs(s["T"] - s["T_exact"]) <= 1e-10 * s["P_exact"]
        assert s["slip_length"] == pytest.approx(s["slip_length_exact"], abs=1e-9)
    assert record["max_penetration"] < 1e-12 and record["step_cuts"] == 0
    if method == "lagrange":       # each round of the active set is one linear solve: Coulomb's coupling is exact
        assert all(s["newton_iterations"] == s["active_set_rounds"] + 1 for s in record["history"][1:])


def test_penalty_error_falls_as_one_over_beta():
    errors = [run_case(BLOCK.with_(method_parameters={"beta0": beta}))["err_u"] for beta in (1e5, 1e7)]
    assert errors[0] / errors[1] == pytest.approx(100, rel=0.1)


def test_tresca_and_frictionless_walls():
    tresca = run_case(BLOCK.with_(friction=0.0, adhesion=2.0))
    assert tresca["friction_law"] == "tresca" and tresca["T_exact"] == 200.0
    assert tresca["T"] == pytest.approx(200.0, rel=2e-6) and tresca["err_sigma"] < 2e-6
    smooth = run_case(BLOCK.with_(friction=0.0))
    assert smooth["friction_law"] == "frictionless" and smooth["T_exact"] == 0.0
    assert abs(smooth["T"]) < 1e-9 * smooth["P"] and smooth["err_u"] < 1e-6
    assert smooth["slip_length"] == pytest.approx(100.0)


def test_one_step_lands_on_the_path_end():
    """Compressed and sheared in one step: the return map slips to the same end state."""
    record = run_case(BLOCK.with_(steps=1))
    assert record["T"] == pytest.approx(300.0, rel=2e-6) and record["err_u"] < 1e-6


@pytest.mark.parametrize("changes, words", [
    ({"friction": -0.1}, "friction -0.1 is not allowed"),
    ({"friction": float("nan")}, "friction nan is not allowed"),
    ({"adhesion": 1.0}, "not both"),
    ({"kinematics": "large"}, "kinematics 'large' is not allowed for problem 'frictional-block'"),
    ({"material": "von-mises", "yield_stress": 5.0}, "material 'von-mises' is not allowed"),
    ({"method": "ibm"}, "method 'ibm' refuses contact walls"),
    ({"load": -10.0}, "must be > 0"),
    ({"problem": "confined-block", "steps": 1}, "friction 0.3 is for a problem with a contact wall"),
])
def test_bad_input_is_one_line(changes, words):
    with pytest.raises(InputError, match=words):
        validate(BLOCK.with_(**changes))


def test_command_line_reports_the_contact_and_refuses_bad_friction():
    command = [sys.executable, "-m", "studies.cli", "solve", "--problem", "frictional-block", "--method", "penalty",
               "--angle", "30", "--steps", "4", "--ppc", "2", "--friction", "0.3", "--json"]
    record = json.loads(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
    for key in ("contact_force", "active_length", "slip_length", "P", "P_exact", "T", "T_exact", "history",
                "max_penetration", "active_set_changes"):
        assert key in record, key
    assert len(record["history"]) == 4 and np.hypot(*record["contact_force"]) == pytest.approx(np.hypot(1000, 300))
    bad = subprocess.run(command[:-3] + ["--friction=-1"], capture_output=True, text=True)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "friction -1" in bad.stderr


def test_killed_run_resumes_bit_identical(tmp_path, monkeypatch):
    """The contact history is part of the checkpoint: a run killed mid-way resumes to the same record."""
    uninterrupted = run_case(BLOCK)
    path = tmp_path / "block.npz"
    run_killed_before_step(BLOCK, path, 6, monkeypatch, keep_fields=False)     # killed in the stick-to-slip step
    resumed = run_case(BLOCK, checkpoint=path)
    _same_record(resumed, uninterrupted, compared=())


def test_exact_state_is_the_elastic_state_of_its_displacement():
    """sympy: Hooke's law of u gives the stated stress (plane strain), and the top plate's translation is u at
    eta = H, in stick and in slip."""
    import sympy

    from ibm.models.small_strain import LinearElastic
    from studies.problems.frictional_block import FrictionalBlock

    material = LinearElastic(1e4, 0.3)

    xi, eta, p, tau, slip = sympy.symbols("xi eta p tau slip")
    lam, mu = sympy.nsimplify(material.lam), sympy.nsimplify(material.mu)
    M = lam + 2 * mu
    u = sympy.Matrix([tau / mu * eta + slip, -p / M * eta])
    grad = u.jacobian([xi, eta])
    strain = (grad + grad.T) / 2
    stress = lam * strain.trace() * sympy.eye(2) + 2 * mu * strain
    assert sympy.simplify(stress - sympy.Matrix([[-lam / M * p, tau], [tau, -p]])) == sympy.zeros(2)
    X = np.array([[3.0, 7.0], [50.0, 100.0]])
    for values in ((10.0, 1.5, 0.0), (10.0, 3.0, 0.02)):
        u_h, stress_h = FrictionalBlock.exact_fields(X, material, *values)
        exact = [[float(c.subs({p: values[0], tau: values[1], slip: values[2], xi: x, eta: y})) for c in u]
                 for x, y in X]
        assert np.allclose(u_h, exact, rtol=1e-14, atol=1e-16)
        assert np.allclose(stress_h[0], np.array(stress.subs({p: values[0], tau: values[1]}), float), rtol=1e-14)


def test_a_study_tabulates_the_contact_and_refuses_the_table_elsewhere(tmp_path):
    """The report's contact table: each method's wall forces beside their exact values."""
    import pandas as pd

    from studies.run import runner
    from studies.run.spec import parse

    text = ('title = "t"\n[[sweep]]\nname = "block"\nproblems = ["frictional-block"]\n'
            'methods = ["penalty", "nitsche", "lagrange"]\nangle = 30\nfriction = 0.3\nsteps = 4\nppc = 2\n'
            'tables = ["contact"]\nfigures = ["contact-curves"]\n')
    spec = tmp_path / "study.toml"
    spec.write_text(text)
    summary = runner.run_study(spec, tmp_path / "out", jobs=1, progress=False)
    assert (summary.run, summary.failed) == (3, 0)
    table = pd.read_csv(tmp_path / "out" / "tables" / "block-contact-frictional-block.csv")
    assert list(table["method"]) == ["penalty", "nitsche", "lagrange"]
    assert (table["P rel. diff."].abs() < 2e-6).all() and (table["T rel. diff."].abs() < 2e-6).all()
    assert table["P exact"].tolist() == [1000.0] * 3
    assert (tmp_path / "out" / "figures" / "block-contact-curves-0.png").is_file()
    with pytest.raises(InputError, match="table contact is for the contact problems"):
        parse(text.replace('problems = ["frictional-block"]', 'problems = ["confined-block"]')
              .replace('friction = 0.3\n', '').replace('steps = 4\n', '').replace('figures = ["contact-curves"]\n', ''))
    with pytest.raises(InputError, match="figure contact-curves is for the contact problems"):
        parse(text.replace('problems = ["frictional-block"]', 'problems = ["confined-block"]')
              .replace('friction = 0.3\n', '').replace('steps = 4\n', '').replace('tables = ["contact"]\n', ''))
