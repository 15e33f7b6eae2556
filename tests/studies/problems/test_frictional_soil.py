"""Frictional soil in the studies (studies.problems.materials): Mohr-Coulomb and Drucker-Prager named by a case,
their homogeneous patch tests in the load-step loop (the confined block's settlement on an edge of the prism or
the cone, the weightless passive wall on the prism's plane), the passive wall against Rankine's K_p, the
bearing-capacity factor against its table, the footing on frictional soil, and bad values in one line."""
import json
import subprocess
import sys

import numpy as np
import pytest

from studies.problems.footing import half_model, prandtl_mechanism, run_footing
from studies.problems.materials import bearing_capacity_factor
from studies.run.case import CaseSpec, run_case

SOIL = {"cohesion": 5.0, "friction_angle": 30.0, "dilation_angle": 10.0}
BLOCK = CaseSpec(problem="confined-block", load_type="settlement", load=30.0, angle=30.0, steps=10, **SOIL)


@pytest.mark.parametrize("kinematics", ["small", "large"])
@pytest.mark.parametrize("material", ["mohr-coulomb", "drucker-prager"])
@pytest.mark.parametrize("method", ["lagrange", "nitsche"])
def test_confined_settlement_is_reproduced_to_round_off(method, material, kinematics):
    """Uniaxial strain at 30 degrees, yielding from the first step on the prism's edge (the lateral stresses
    equal) or the cone, non-associated (psi = 10 < phi = 30): every point at the model's own homogeneous
    response (err 1e-15 to 5e-11 measured), in one or two Newton iterations a step (the return is piecewise
    linear in the strain, its tangent exact)."""
    record = run_case(BLOCK.with_(method=method, material=material, kinematics=kinematics))
    assert record["err_u"] < 1e-9 and record["err_sigma"] < 1e-9
    assert max(record["newton_iterations"]) <= 3


@pytest.mark.parametrize("material", ["mohr-coulomb", "drucker-prager"])
def test_weightless_passive_wall_reaches_rankine_with_k_p(material):
    """c = 20, phi = 30: the homogeneous passive state at every step to the Newton tolerance (err 6.9e-9 for the
    cone, measured; the prism's return is linear in the strain, 1e-12), and the wall's force at Rankine's
    2 c H sqrt(K_p) = 6,928.2 (the matched cone reaches the prism's limit with associated flow)."""
    spec = CaseSpec(problem="passive-wall", method="nitsche", angle=30.0, ppc=2, steps=10, material=material,
                    cohesion=20.0, friction_angle=30.0, load=5.0, load_type="settlement")
    record = run_case(spec)
    bound = 1e-11 if material == "mohr-coulomb" else 1e-8
    assert max(s["err_u"] for s in record["history"]) < bound
    assert max(s["err_sigma"] for s in record["history"]) < bound
    assert record["P_rankine"] == pytest.approx(2 * 20.0 * 100 * np.sqrt(3.0), rel=1e-14)     # K_p = 3 at 30
    assert record["P"] == pytest.approx(record["P_rankine"], rel=1e-6)


def test_passive_wall_with_weight_falls_on_the_exact_state_with_h():
    """gamma = 0.5: err_sigma 1.67e-2 and 8.3e-3 at h = 10 and 5 (measured: O(h)), the force within 1.0e-5 and
    2.2e-6 of the exact one, which is Rankine's gamma H^2 K_p / 2 + 2 c H sqrt(K_p) = 14,428.2 at this push."""
    spec = CaseSpec(problem="passive-wall", method="nitsche", angle=30.0, ppc=2, steps=10, material="mohr-coulomb",
                    cohesion=20.0, friction_angle=30.0, load=5.0, load_type="settlement", unit_weight=0.5)
    coarse, fine = run_case(spec), run_case(spec.with_(cell=5.0))
    assert np.log2(coarse["err_sigma"] / fine["err_sigma"]) > 0.95
    assert fine["err_sigma"] < 9e-3
    assert coarse["P_rankine"] == pytest.approx(0.5 * 100 ** 2 * 3 / 2 + 2 * 20 * 100 * np.sqrt(3), rel=1e-14)
    assert coarse["P_exact"] == pytest.approx(coarse["P_rankine"], rel=1e-9)
    assert abs(coarse["P"] / coarse["P_exact"] - 1) < 2e-5 and abs(fine["P"] / fine["P_exact"] - 1) < 5e-6


def test_bearing_capacity_factor_is_prandtl_and_reissner():
    """N_c against the tabulated values (Vesic's table of (N_q - 1) cot phi: 8.35, 14.83, 30.14, 75.31) and its
    limit 2 + pi as phi -> 0."""
    for phi, table in ((10, 8.35), (20, 14.83), (30, 30.14), (40, 75.31)):
        assert bearing_capacity_factor(phi) == pytest.approx(table, abs=0.006)
    assert bearing_capacity_factor(1e-7) == pytest.approx(2 + np.pi, rel=1e-6)
    assert bearing_capacity_factor(0.0) == 2 + np.pi


def test_prandtl_mechanism_sizes_the_half_model():
    """At phi = 0 the fan has radius B / sqrt(2) and meets the surface 1.5 B from the centre line; at 30 degrees
    the log spiral reaches 4.79 B, so the half model grows to 6 B."""
    reach, depth = prandtl_mechanism(0.0)
    assert reach == pytest.approx(1.5, rel=1e-12) and depth == pytest.approx(1 / np.sqrt(2), rel=1e-6)
    assert prandtl_mechanism(30.0)[0] == pytest.approx(4.7897, abs=1e-4)
    assert half_model(0.0) == (5.0, 3.0) and half_model(30.0) == (6.0, 3.0)


def test_footing_on_frictional_soil_comes_down_on_n_c_with_h():
    """phi = 20 (N_c = 14.83), the edge on a node, 3 B x 2 B, penalty: q / c 16.73 at B/h = 8 (+12.8 %), and the
    curve flat past its knee (the last five steps within 0.6 %)."""
    result = run_footing("penalty", 90.0, (0.0, 0.0), B_over_h=8, width_over_B=3, depth_over_B=2, steps=20,
                         material="mohr-coulomb", cohesion=57.735, friction_angle=20.0, settlement_over_B=0.05)
    assert result["q_over_c_exact"] == pytest.approx(14.835, abs=1e-3)
    assert result["q_over_c"] / result["q_over_c_exact"] - 1 == pytest.approx(0.128, abs=0.005)
    q = np.array(result["q"])
    assert q[-1] / q[-5] - 1 < 0.006 and result["step_cuts"] == 0


@pytest.mark.parametrize("arguments, words", [
    (["--material", "mohr-coulomb", "--cohesion", "5", "--friction-angle", "90"], "friction angle 90 is not allowed"),
    (["--material", "drucker-prager", "--cohesion", "5", "--friction-angle", "30", "--dilation-angle", "35"],
     "dilation angle 35 is not allowed; it must be in [0, friction angle 30]"),
    (["--material", "mohr-coulomb", "--cohesion", "nan", "--friction-angle", "30"], "cohesion nan is not allowed"),
    (["--material", "mohr-coulomb"], "cohesion 0 is not allowed with friction angle 0"),
    (["--material", "elastic", "--cohesion", "5"], "cohesion 5 is for --material mohr-coulomb or drucker-prager"),
    (["--material", "mohr-coulomb", "--cohesion", "5", "--yield-stress", "10"],
     "yield-stress 10 is for --material von-mises"),
    (["--material", "mohr-coulomb", "--friction-angle", "30", "--problem", "footing"],
     "cohesion 0 is not allowed for problem 'footing'"),
    (["--material", "mohr-coulomb", "--cohesion", "5", "--problem", "ample-collapse"],
     "material, cohesion cannot be set"),
    (["--material", "mohr-coulomb", "--cohesion", "-5", "--friction-angle", "30", "--problem", "hill-cylinder"],
     "cohesion -5"),
])
def test_bad_soil_is_one_line(arguments, words):
    if "--problem" not in arguments:
        arguments = arguments + ["--problem", "confined-block", "--load-type", "settlement", "--load", "5"]
    if {"footing", "hill-cylinder", "ample-collapse"} & set(arguments):
        arguments = arguments + ["--steps", "20", "--method", "penalty", "--ppc", "2"]
    done = subprocess.run([sys.executable, "-m", "studies.cli", "solve", *arguments, "--json"], capture_output=True,
                          text=True)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], done.stderr


def test_the_soil_is_in_the_record():
    record = json.loads(subprocess.run(
        [sys.executable, "-m", "studies.cli", "solve", "--problem", "passive-wall", "--material", "drucker-prager",
         "--cohesion", "20", "--friction-angle", "25", "--steps", "2", "--method", "nitsche", "--json"],
        capture_output=True, text=True, check=True).stdout)
    assert (record["material"], record["cohesion"], record["friction_angle"], record["dilation_angle"]) == \
        ("drucker-prager", 20.0, 25.0, 25.0)


def test_surcharge_adds_n_q_times_itself():
    """A surcharge q0 on the free top beside the footing (put on over the first quarter of the steps): on von
    Mises soil (N_q = 1) it lifts the collapse by q0 itself, measured 0.510 c for q0 = 0.520 c at B/h = 8; on
    phi = 20 soil the exact q / c is N_c + (q0 / c) N_q = 14.83 + 6.40 (N_q = 6.40)."""
    common = dict(B_over_h=8, width_over_B=3, depth_over_B=2, steps=20)
    bare = run_footing("penalty", 90.0, (0.0, 0.0), **common)
    loaded = run_footing("penalty", 90.0, (0.0, 0.0), surcharge=30.0, **common)
    c = 100 / np.sqrt(3)
    assert loaded["q_over_c_exact"] == pytest.approx(2 + np.pi + 30 / c, rel=1e-14)
    assert (loaded["q_over_c"] - bare["q_over_c"]) / (30 / c) == pytest.approx(1.0, abs=0.03)
    soil = run_footing("penalty", 90.0, (0.0, 0.0), material="mohr-coulomb", cohesion=20.0, friction_angle=20.0,
                       surcharge=20.0, settlement_over_B=0.05, **common)
    assert soil["q_over_c_exact"] == pytest.approx(14.835 + 6.399, abs=2e-3)
    assert 1.0 < soil["q_over_c"] / soil["q_over_c_exact"] < 1.16


@pytest.mark.parametrize("arguments, words", [
    (["--problem", "footing", "--footing", "rigid", "--method", "penalty"], "surcharge 5 is for the grid methods'"),
    (["--problem", "footing", "--method", "fem", "--locking", "none"], "not the smooth footing with 'fem' at small kinematics"),
    (["--problem", "passive-wall", "--method", "nitsche", "--material", "von-mises", "--yield-stress", "100"],
     "surcharge 5 is for a problem with a surcharge on the soil's free top (footing), not 'passive-wall'"),
])
def test_bad_surcharge_is_one_line(arguments, words):
    done = subprocess.run([sys.executable, "-m", "studies.cli", "solve", *arguments, "--surcharge", "5",
                           "--steps", "20", "--ppc", "2", "--json"], capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], done.stderr


def test_associated_flow_is_one_case_whether_given_or_not():
    """psi = phi given is the unset dilation angle (associated flow): the same case id, so a study runs it once;
    any other psi is another case."""
    from studies.run.identity import case_id
    soil = CaseSpec(problem="footing", material="mohr-coulomb", cohesion=57.735, friction_angle=20.0)
    assert case_id(soil.with_(dilation_angle=20.0)) == case_id(soil) == case_id(soil.with_(dilation_angle=20))
    assert case_id(soil.with_(dilation_angle=0.0)) != case_id(soil)
    assert case_id(soil.with_(friction_angle=30.0, dilation_angle=20.0)) != case_id(soil.with_(friction_angle=30.0))


def test_cylinder_limit_in_frictional_soil_solves_equilibrium_on_the_yield_surface():
    """sigma_r(r) = c cot phi ((b / r)^A - 1), A = 2 sin phi / (1 + sin phi), is zero at b, in equilibrium
    (d sigma_r / dr + (sigma_r - sigma_theta) / r = 0, compression positive) with sigma_theta on Mohr-Coulomb's
    plane; its value at a is frictional_limit, Tresca's 2 c ln(b / a) as phi -> 0."""
    from studies.problems.collapse import A as INNER, B as OUTER, frictional_limit
    c, phi = 138.564, np.radians(30.0)
    N, power = (1 + np.sin(phi)) / (1 - np.sin(phi)), 2 * np.sin(phi) / (1 + np.sin(phi))
    r = np.linspace(INNER, OUTER, 2001)
    radial = c / np.tan(phi) * ((OUTER / r) ** power - 1)
    hoop = (radial - 2 * c * np.sqrt(N)) / N
    assert radial[-1] == pytest.approx(0, abs=1e-12) and radial[0] == pytest.approx(frictional_limit(c, 30.0))
    residual = np.gradient(radial, r) + (radial - hoop) / r
    assert np.abs(residual[1:-1]).max() < 1e-5 * c / INNER
    assert frictional_limit(c, 1e-7) == pytest.approx(frictional_limit(c, 0.0), rel=1e-6)
    assert frictional_limit(c, 0.0) == pytest.approx(2 * c * np.log(2), rel=1e-15)
    assert frictional_limit(c, 30.0) == pytest.approx(140.976, rel=1e-5)


@pytest.mark.parametrize("method, locking", [("lagrange", "fbar"), ("fem", "none")])
def test_cylinder_in_frictional_soil_collapses_at_its_limit(method, locking):
    """Associated Mohr-Coulomb (phi = 30, c = sigma_y / sqrt 3 of the von Mises ring): the pressure ramped to
    1.05 p_lim in 20 steps converges at 0.9975 p_lim and not at 1.05 (measured with 100 steps: lagrange to
    1.008, fem 0.9975); without dilation the ring carries less."""
    case = CaseSpec(problem="hill-cylinder", method=method, angle=90.0, cell=10.0, ppc=2, steps=20, basis="mpm",
                    locking=locking, material="mohr-coulomb", cohesion=138.564, friction_angle=30.0)
    record = run_case(case)
    assert record["p_lim"] == pytest.approx(140.976, rel=1e-5) and record["hill_p"] == []
    assert record["p_over_p_lim"] == pytest.approx(0.9975, rel=1e-12) and isinstance(record["stopped"], str)
    assert record["friction_angle"] == 30.0 and record["cohesion"] == 138.564 and record["step_cuts"] == 0
    if method == "lagrange":
        assert run_case(case.with_(dilation_angle=0.0))["p_over_p_lim"] == pytest.approx(0.945, rel=1e-12)
