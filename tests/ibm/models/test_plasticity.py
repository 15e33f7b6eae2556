"""J2 plasticity on Hencky elasticity (ibm.models.plasticity): the elastic limit, the return map's
consistency, isochoric flow, and the consistent tangent against finite differences."""
import numpy as np
import pytest

from ibm.models.constitutive import Hencky, undeformed
from ibm.exceptions import InputError
from ibm.models.plasticity import HenckyJ2
from tests.ibm.large.test_load_steps import tangent_error


def _tangent_error(model, dF, state) -> float:
    return tangent_error(model, dF, state, eps=1e-7)


def _von_mises(sigma, J):
    tau = sigma * J[:, None, None]
    s = tau - np.trace(tau, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    return np.sqrt(1.5 * np.sum(s * s, axis=(1, 2)))


RNG = np.random.default_rng(5)
STRETCH = np.eye(3) + 0.04 * RNG.standard_normal((6, 3, 3))


def test_below_yield_it_is_hencky():
    elastic, plastic = Hencky(1e4, 0.3), HenckyJ2(1e4, 0.3, yield_stress=1e9)
    a, b = elastic.update(STRETCH, undeformed(6)), plastic.update(STRETCH, plastic.initial(6))
    assert np.abs(a.sigma - b.sigma).max() <= 1e-12 * np.abs(a.sigma).max()
    assert np.abs(a.tangent - b.tangent).max() <= 1e-10 * np.abs(a.tangent).max()
    assert np.all(b.state.internal["alpha"] == 0)


@pytest.mark.parametrize("hardening", [0.0, 500.0])
def test_return_map_lands_on_the_yield_surface_and_flows_isochorically(hardening):
    model = HenckyJ2(1e4, 0.3, yield_stress=20.0, hardening=hardening)
    r = model.update(STRETCH, model.initial(6))
    alpha = r.state.internal["alpha"]
    assert np.all(alpha > 0)                                        # 4 % strains: every point yields
    J = np.linalg.det(r.state.F)
    q = _von_mises(r.sigma, J)
    assert np.abs(q - (20.0 + hardening * alpha)).max() <= 1e-10 * 20.0
    trial = STRETCH @ STRETCH.transpose(0, 2, 1)
    assert np.allclose(np.linalg.det(r.state.be), np.linalg.det(trial), rtol=1e-12)   # plastic flow keeps volume


@pytest.mark.parametrize("hardening", [0.0, 500.0])
def test_consistent_tangent_matches_finite_differences(hardening):
    model = HenckyJ2(1e4, 0.3, yield_stress=20.0, hardening=hardening)
    state = model.update(STRETCH, model.initial(6)).state          # already plastic
    increment = np.eye(3) + 0.02 * RNG.standard_normal((6, 3, 3))
    assert np.all(model.update(increment, state).state.internal["alpha"] > state.internal["alpha"])
    assert _tangent_error(model, increment, state) <= 1e-6


def test_bad_plastic_parameters_are_one_line():
    with pytest.raises(InputError, match="yield stress -1"):
        HenckyJ2(1e4, 0.3, yield_stress=-1.0)
    with pytest.raises(InputError, match="hardening modulus -2"):
        HenckyJ2(1e4, 0.3, yield_stress=10.0, hardening=-2.0)


def test_tangent_at_repeated_trial_eigenvalues():
    """Uniaxial compression (two equal trial stretches): the divided differences take their limit."""
    model = HenckyJ2(1e4, 0.3, yield_stress=20.0, hardening=100.0)
    dF = np.broadcast_to(np.diag([1.0, 0.95, 1.0]), (2, 3, 3)).copy()
    assert np.all(model.update(dF, model.initial(2)).state.internal["alpha"] > 0)
    assert _tangent_error(model, dF, model.initial(2)) <= 1e-6


@pytest.mark.parametrize("method", ["lagrange", "nitsche"])
@pytest.mark.parametrize("angle", [90, 30])
def test_plastic_patch_test_in_the_large_deformation_loop(method, angle):
    """The confined block settled by 30 % in 10 steps, J2 material yielding from the first step:
    every point's stress equals the model's own homogeneous response to the exact F, at every step."""
    import dataclasses

    from baselines.registry import treatment
    from ibm.large.loadsteps import run
    from ibm.large.newton import Control
    from studies.run.case import CaseSpec
    from studies.problems.registry import problem_of

    spec = CaseSpec(problem="confined-block", load_type="settlement", load=30.0, method=method, angle=angle,
                    cell=10.0, ppc=2, kinematics="large", steps=10)
    setup, corner, R = problem_of(spec).setup(spec)
    model = HenckyJ2(spec.E, spec.nu, yield_stress=20.0, hardening=200.0)
    setup = dataclasses.replace(setup, material=model)
    rotation = np.eye(3)
    rotation[:2, :2] = R
    exact = {"state": model.initial(1), "F": np.eye(3)}
    worst = []

    def check(progress):
        F = np.diag([1.0, 1 - progress.t * spec.load / spec.height, 1.0])
        response = model.update((F @ np.linalg.inv(exact["F"]))[None], exact["state"])
        exact.update(state=response.state, F=F)
        sigma = rotation @ response.sigma[0] @ rotation.T
        worst.append(np.abs(progress.sigma - sigma).max() / np.abs(sigma).max())
        return {}

    # Newton to 1e-12 (or its rounding floor): the plastic tangent is ~3 mu / H = 58 times softer than
    # the elastic one, so the default 1e-9 on the residual leaves ~1e-8 in the stress
    progress = run(setup, treatment(method, {}), Control(tolerance=1e-12), after_step=check)
    assert exact["state"].internal["alpha"][0] > 0.1                    # well into the plastic range
    print(f"{method} at {angle} degrees: worst stress error {max(worst):.1e}")
    assert max(worst) <= 1e-10
    assert np.allclose(progress.state.internal["alpha"], exact["state"].internal["alpha"][0], rtol=1e-10)
    assert max(s["newton_iterations"] for s in progress.steps) <= 10


def test_radial_return_is_exact_for_the_settlement_whatever_the_steps():
    """Uniaxial strain is coaxial and proportional: one return from the undeformed state gives the
    same stress as ten steps (the exact solution the study measures against)."""
    model = HenckyJ2(1e4, 0.3, yield_stress=20.0, hardening=200.0)
    state, F = model.initial(1), np.eye(3)
    for k in range(1, 11):
        target = np.diag([1.0, 1 - 0.03 * k, 1.0])
        response = model.update((target @ np.linalg.inv(F))[None], state)
        state, F = response.state, target
    once = model.update(F[None], model.initial(1))
    assert np.abs(once.sigma - response.sigma).max() <= 1e-12 * np.abs(once.sigma).max()
    assert abs(once.state.internal["alpha"][0] - state.internal["alpha"][0]) <= 1e-14


@pytest.mark.parametrize("method", ["lagrange", "nitsche"])
def test_j2_settlement_from_the_command_line(method, capsys):
    import json

    from studies.cli import main
    code = main(["solve", "--problem", "confined-block", "--load-type", "settlement", "--load", "30",
                 "--kinematics", "large", "--steps", "10", "--method", method, "--angle", "30", "--ppc", "2",
                 "--material", "j2", "--yield-stress", "20", "--hardening", "200", "--json"])
    record = json.loads(capsys.readouterr().out)
    assert code == 0 and record["material"] == "j2" and record["yield_stress"] == 20.0
    assert record["err_u"] <= 1e-9 and record["err_sigma"] <= 1e-9
    assert abs(record["height_final"] - record["height_exact"]) <= 1e-9 * 100


@pytest.mark.parametrize("arguments,message", [
    (["--material", "foo", "--kinematics", "large", "--steps", "2"], "material 'foo' is not allowed; allowed: elastic, von-mises, j2"),
    (["--material", "j2", "--yield-stress", "20", "--problem", "column", "--load-type", "pressure"],
     "material j2 has an exact solution only for the confined block's settlement; problem 'column'"),
    (["--steps", "3"], "steps 3 is not allowed with small kinematics (one linear step); use --kinematics large, or "
                       "--material von-mises"),
    (["--material", "j2", "--kinematics", "large", "--steps", "2"], "yield-stress 0.0 is not allowed for material j2"),
    (["--yield-stress", "5"], "yield-stress 5 is for --material von-mises (or j2), not material 'elastic'"),
    (["--material", "j2", "--yield-stress", "20", "--hardening", "-1", "--kinematics", "large", "--steps", "2"],
     "hardening -1.0 is not allowed"),
    (["--material", "j2", "--yield-stress", "20", "--kinematics", "large", "--steps", "2", "--load-type", "pressure"],
     "material j2 has an exact solution only for the confined block's settlement"),
])
def test_bad_material_options_are_one_line(arguments, message, capsys):
    from studies.cli import main
    base = ["solve", "--method", "nitsche", "--load-type", "settlement", "--load", "30"]
    assert main(base + arguments) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("method", ["ibm", "lagrange", "nitsche", "penalty", "fem"])
def test_small_strain_j2_settlement_runs_load_steps_on_the_initial_configuration(method):
    """At small kinematics j2 is the radial return (ibm.models.small_strain) in the same load-step loop,
    integrated on the initial configuration: the exact state is the model's homogeneous response to
    the uniaxial strain; consistent methods reach it to round-off (the IBM and penalty to their own
    O(delta), O(1/beta0): measured 9e-8 and 2e-7), nothing moves but x = X + u."""
    from studies.run.case import CaseSpec, run_case
    record = run_case(CaseSpec(problem="confined-block", load_type="settlement", load=2.0, kinematics="small",
                               steps=4, method=method, angle=30.0, ppc=2, material="j2", yield_stress=20.0,
                               hardening=200.0), keep_fields=True)
    gate = {"ibm": 3e-7, "penalty": 1e-6}.get(method, 1e-9)
    assert record["kinematics"] == "small" and record["err_u"] <= gate and record["err_sigma"] <= 3 * gate
    fields = record["fields"]
    assert np.array_equal(fields["outline"][0], fields["outline"][-1])    # the outline stays (small strain)
    assert np.array_equal(fields["volume"][-1], fields["V0"])
    assert np.abs(fields["x"][-1] - fields["X"]).max() > 1.0                  # the settlement shows in x


def test_von_mises_is_the_name_and_j2_its_synonym(capsys):
    """--material von-mises and --material j2 run the same model: the same record but its name."""
    import json

    from studies.cli import main
    records = []
    for name in ("von-mises", "j2"):
        assert main(["solve", "--problem", "confined-block", "--load-type", "settlement", "--load", "2",
                     "--steps", "4", "--method", "lagrange", "--angle", "30", "--ppc", "2", "--material", name,
                     "--yield-stress", "20", "--hardening", "200", "--json"]) == 0
        records.append(json.loads(capsys.readouterr().out))
    assert records[0]["material"] == "von-mises" and records[1]["material"] == "j2"
    assert records[0]["err_u"] == records[1]["err_u"] and records[0]["err_u"] <= 1e-9


def test_log_divided_differences_stay_finite_where_one_stretch_vanishes_to_rounding():
    """(ln x_a - ln x_b) / (x_a - x_b): the series near x_a = x_b, ln(1 + r) / r elsewhere, and the logarithms
    themselves where 1 + r rounds to 0 (x_a / x_b below 1e-16: a wild Newton iterate), never -inf."""
    from ibm.models.constitutive import PAIRS, log_divided_differences
    x = np.array([[1e-17, 1.0, 2.0], [1.0, 1.0 + 1e-9, 3.0], [0.25, 4.0, 4.0 * (1 + 1e-8)]])
    g = log_divided_differences(x)
    assert np.isfinite(g).all()
    for (a, b), column in zip(zip(*PAIRS), g):
        for point in range(3):
            xa, xb = x[point, a], x[point, b]
            expected = 1 / xa if abs(xa - xb) < 1e-6 * xb else (np.log(xa) - np.log(xb)) / (xa - xb)
            assert column[point] == pytest.approx(expected, rel=1e-8)
    assert g[0, 0] == pytest.approx(np.log(1e-17) / (1e-17 - 1), rel=1e-14)      # 39.14
