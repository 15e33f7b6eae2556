"""The body-fitted small-strain plasticity reference (baselines.fem.plastic) on Hill's thick cylinder."""
import numpy as np
import pytest

from baselines.fem.plastic import run_fem_plastic
from ibm.exceptions import InputError, StepFailure
from ibm.models.small_strain import VonMises
from studies.problems.collapse import B, E, NU, YIELD, Hill, hill_body, run_hill

OUTER, INNER = 1, 3          # the quarter ring's pieces: the outer arc r = b, the loaded inner arc r = a


def _radial(record, corner):
    """Radial and tangential displacement (m,) of the outer arc's nodes."""
    nodes = record["piece_nodes"][OUTER]
    x, u = record["nodes"][nodes] - corner, record["displacement"][nodes]
    r = np.linalg.norm(x, axis=1)
    return np.sum(u * x, axis=1) / r, (u[:, 1] * x[:, 0] - u[:, 0] * x[:, 1]) / r


@pytest.fixture(scope="module")
def ramp():
    """h = 10 at 30 degrees, the pressure ramped to 1.05 p_lim in 20 steps: the step records and the failure."""
    body, corner = hill_body(30.0, (0.37, 0.29), 10.0)
    records = []
    with pytest.raises(StepFailure) as failure:
        run_fem_plastic(body, VonMises(E, NU, yield_stress=YIELD), {INNER: 1.05 * Hill().p_lim}, 10.0, 20,
                        after_step=lambda record: records.append(record) or {})
    return records, failure.value


def test_elastic_range_matches_lame():
    """0.9 p_yield in one step (one Newton iteration): u_b of Lame in plane strain,
    u_b = (p a^2 / (b^2 - a^2)) (b / (2 mu)) (mu / (lam + mu) + 1). Measured at h = 10: mean -2.8e-6,
    worst node 9.5e-6 (h = 5: -1.2e-7, h = 20: -4.5e-5), tangential 1.0e-5 of u_b."""
    material = VonMises(E, NU, yield_stress=YIELD)
    lam, mu = material.lam, material.mu
    hill = Hill()
    p = 0.9 * hill.p_yield
    exact = p * hill.a ** 2 / (B ** 2 - hill.a ** 2) * B / (2 * mu) * (mu / (lam + mu) + 1)
    body, corner = hill_body(30.0, (0.37, 0.29), 10.0)
    progress = run_fem_plastic(body, material, {INNER: p}, 10.0, 1)
    record = progress.steps[-1]
    radial, tangential = _radial(record, corner)
    print(f"u_b {radial.mean():.10g} exact {exact:.10g} rel {radial.mean() / exact - 1:.3g}")
    assert record["newton_iterations"] == 1 and np.all(progress.state.internal["alpha"] == 0)
    assert abs(radial.mean() / exact - 1) < 1e-5
    assert np.abs(radial / exact - 1).max() < 3e-5 and np.abs(tangential).max() < 3e-5 * exact


def test_hill_cylinder_reaches_the_limit_pressure():
    """run_hill("fem"): the 20th step (to 1.05 p_lim) fails after its cuts, so p_final is the 19th step's
    0.9975 p_lim (as for the grid methods with B-bar); its cut substeps converge up to 0.99996 p_lim
    (the 3-point P2 triangle does not lock). Below Hill's end (c = b), p at equal u_b is within 0.15 %
    of Hill's (h = 10 and h = 5 alike: von Mises against Hill's Tresca-like plane-strain solution)."""
    record = run_hill("fem", angle=30.0, cell=10.0, steps=20)
    assert abs(record["p_over_p_lim"] - 1) <= 0.01 and record["stopped"]
    assert record["p_over_p_lim"] == pytest.approx(0.9975, abs=1e-12)
    assert abs(record["p_last_substep"] / record["p_lim"] - 1) < 1e-3
    assert len(record["curve_u"]) == len(record["curve_p"]) == len(record["newton_iterations"]) == 19
    u, p = np.array(record["curve_u"]), np.array(record["curve_p"])
    inside = u <= record["hill_u"][-1]
    hill_p = np.interp(u[inside], record["hill_u"], record["hill_p"])
    difference = np.abs(p[inside] / hill_p - 1)
    print("p / p_hill - 1 at equal u_b:", np.array2string(p[inside] / hill_p - 1, precision=2))
    assert difference[p[inside] < record["p_yield"]].max() < 1e-5     # elastic
    assert difference.max() < 2e-3
    assert u[-1] > record["hill_u"][-1]                               # the last step: the mechanism


def test_six_point_rule_reaches_the_limit_too():
    """The degree-4 rule (6 points per triangle) carries at most 0.03 % more (h = 10; measured 1.00017 p_lim
    converged, none at h = 5)."""
    body, _ = hill_body(30.0, (0.37, 0.29), 10.0)
    p_lim = Hill().p_lim
    with pytest.raises(StepFailure) as failure:
        run_fem_plastic(body, VonMises(E, NU, yield_stress=YIELD), {INNER: 1.05 * p_lim}, 10.0, 20, order=4)
    assert abs(failure.value.progress.t * 1.05 - 1) < 1e-3


def test_newton_converges_quadratically_in_plastic_steps(ramp):
    """Steps 11 to 18 (p_yield < p < 0.95 p_lim, the plastic zone spreading): the last iterate above the
    residual's floor (~1e-12) has r_{k+1} <= 10 r_k^2 (measured 0.1 to 5); the consistent tangent."""
    records, failure = ramp
    assert len(records) == 19 and "after 8 step cuts" in str(failure)
    assert all(r["newton_iterations"] == 1 for r in records[:10])     # elastic: one linear solve
    for record in records[10:18]:
        r = np.array(record["residuals"])
        print(f"step {record['step']}:", " ".join(f"{v:.1e}" for v in r), "  r_k+1 / r_k^2:",
              " ".join(f"{v:.2g}" for v in r[1:] / r[:-1] ** 2))
        k = np.flatnonzero(r[1:] > 1e-11)[-1]
        assert r[k] < 1e-2 and r[k + 1] <= 10 * r[k] ** 2 and r[-1] <= 1e-9
        assert record["newton_iterations"] <= 6 and record["cuts"] == 0


def test_a_pressure_on_an_essential_piece_is_refused():
    body, _ = hill_body(30.0, (0.37, 0.29), 10.0)
    with pytest.raises(InputError, match="piece 0 is roller; a pressure needs a natural"):
        run_fem_plastic(body, VonMises(E, NU, yield_stress=YIELD), {0: 1.0}, 20.0, 1)
