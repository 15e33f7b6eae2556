"""The contact laws' penalty return map: Signorini, Coulomb and Tresca bounds, and a tangent that
matches central finite differences away from the kinks."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ibm.contact.laws import OPEN, SLIP, STICK, ContactLaw, penalty_response
from ibm.exceptions import InputError

BETA_N, BETA_T = 1e3, 4e2


def _normals(angles):
    return np.stack([np.cos(angles), np.sin(angles)], axis=1)


def _finite_difference(law, r, slip, n, step=1e-7):
    m, d = r.shape
    columns = []
    for j in range(d):
        e = np.zeros(d)
        e[j] = step
        plus = penalty_response(law, r + e, slip, n, BETA_N, BETA_T).traction
        minus = penalty_response(law, r - e, slip, n, BETA_N, BETA_T).traction
        columns.append((plus - minus) / (2 * step))
    return np.stack(columns, axis=2)           # (m, d, d)


@pytest.mark.parametrize("law", [ContactLaw(), ContactLaw("coulomb", 0.4), ContactLaw("tresca", 0.3)])
def test_tangent_matches_finite_differences(law):
    rng = np.random.default_rng(3)
    m = 400
    n = _normals(rng.uniform(0, 2 * np.pi, m))
    r = rng.normal(scale=1e-2, size=(m, 2))
    slip = rng.normal(scale=1e-2, size=(m, 2))
    slip -= np.einsum("qi,qi->q", slip, n)[:, None] * n        # slips are tangential
    response = penalty_response(law, r, slip, n, BETA_N, BETA_T)
    numeric = _finite_difference(law, r, slip, n)
    # away from the kinks (gap = 0, |trial| = bound) the map is smooth
    gap = np.einsum("qi,qi->q", r, n)
    r_t = r - gap[:, None] * n
    trial = np.linalg.norm(BETA_T * (r_t - slip), axis=1)
    bound = law.bound(BETA_N * np.maximum(-gap, 0))
    smooth = (np.abs(gap) > 1e-5) & (np.abs(trial - bound) > 1e-2)
    assert smooth.sum() > 300
    scale = BETA_N
    assert np.abs(response.tangent[smooth] - numeric[smooth]).max() < 1e-6 * scale
    assert {OPEN, STICK if law.friction != "frictionless" else SLIP} <= set(response.status.tolist())


@settings(max_examples=200, deadline=None)
@given(gap=st.floats(-1e-2, 1e-2), tangential=st.floats(-1e-2, 1e-2), angle=st.floats(0, 6.283),
       mu=st.floats(0, 2))
def test_coulomb_bound_and_signorini(gap, tangential, angle, mu):
    n = _normals(np.array([angle]))
    tangent = np.array([[-n[0, 1], n[0, 0]]])
    r = gap * n + tangential * tangent
    response = penalty_response(ContactLaw("coulomb", mu), r, np.zeros((1, 2)), n, BETA_N, BETA_T)
    t = response.traction[0]
    pressure = t @ n[0]
    shear = t @ tangent[0]
    floor = 1e-12 * BETA_N * 1e-2          # r is built with round-off: the law sees it
    assert pressure >= 0                                                   # never pulls
    assert pressure == pytest.approx(BETA_N * max(-gap, 0.0), rel=1e-12, abs=floor)
    assert abs(shear) <= mu * pressure * (1 + 1e-12) + floor               # inside the Coulomb cone
    if abs(shear) > floor:
        assert np.sign(shear) == -np.sign(tangential)                      # resists the relative motion
    if response.status[0] == SLIP:
        # the returned traction is the trial from the new slip
        s = response.slip[0]
        assert np.allclose(-BETA_T * (tangential * tangent[0] - s), shear * tangent[0], rtol=1e-10, atol=1e-12)


def test_tresca_sticks_below_its_bound_and_slips_at_it():
    n = np.array([[0.0, 1.0]])
    law = ContactLaw("tresca", 2.0)
    below = penalty_response(law, np.array([[2.0 / BETA_T * 0.5, -1e-3]]), np.zeros((1, 2)), n, BETA_N, BETA_T)
    assert below.status[0] == STICK and below.traction[0, 0] == pytest.approx(-1.0)
    above = penalty_response(law, np.array([[0.1, -1e-3]]), np.zeros((1, 2)), n, BETA_N, BETA_T)
    assert above.status[0] == SLIP and above.traction[0, 0] == pytest.approx(-2.0)
    assert above.slip[0, 0] == pytest.approx(0.1 - 2.0 / BETA_T)
    opened = penalty_response(law, np.array([[0.1, 1e-3]]), np.zeros((1, 2)), n, BETA_N, BETA_T)
    assert opened.status[0] == OPEN and not np.any(opened.traction)


@pytest.mark.parametrize("friction, coefficient, words", [
    ("coulomb", -0.1, "friction -0.1"), ("tresca", float("nan"), "adhesion nan"),
    ("sticky", 0.0, "friction law 'sticky'"), ("frictionless", 0.2, "takes no coefficient")])
def test_bad_laws_are_one_line(friction, coefficient, words):
    with pytest.raises(InputError, match=words):
        ContactLaw(friction, coefficient)


@settings(max_examples=300, deadline=None)
@given(p=st.floats(0, 1e3), g=st.floats(0, 1e-2), gamma=st.floats(1e-3, 1e9))
def test_signorini_is_one_projection(p, g, gamma):
    """p = <p - gamma g>_+ holds for complementary pairs (g >= 0, p >= 0, p g = 0) and fails otherwise."""
    for pressure, gap in ((p, 0.0), (0.0, g)):
        assert pressure == max(0.0, pressure - gamma * gap)
    if p > 0 and g > 0 and gamma * g > 1e-12 * p:         # both positive: not complementary
        assert p != max(0.0, p - gamma * g)


def test_the_driver_refuses_contact_it_cannot_impose():
    """One line each: a method without contact, contact at large kinematics, a contact edge that is neither a
    wall nor a free edge with an obstacle, a wall moving along itself for a method that cannot move it so."""
    from baselines.registry import METHODS
    from ibm.geometry.outline import rectangle
    from ibm.large.load_paths import LoadPath
    from ibm.large.loadsteps import Loading, Setup, run
    from ibm.models.constitutive import Hencky
    from ibm.models.small_strain import LinearElastic

    body = rectangle(10.0, 10.0, ("roller", "traction", "fixed", "traction"), 30.0, np.array([0.3, 0.2]))
    small, law = LinearElastic(1e4, 0.3), {0: ContactLaw("coulomb", 0.3)}
    cases = [(Setup(body, small, Loading(), 2.5, contact=law), "ibm", "does not impose contact"),
             (Setup(body, Hencky(1e4, 0.3), Loading(), 2.5, contact=law), "penalty", "small kinematics only"),
             (Setup(body, small, Loading(), 2.5, contact={1: ContactLaw()}), "penalty", "contact edge 1 must be"),
             (Setup(body, small, Loading(wall_path=LoadPath([0, 1], np.array([np.zeros((2, 2)), [[0, 0], [1.0, 0]]]))),
                    2.5), "ibm", "move only along their normals")]
    for setup, method, words in cases:
        with pytest.raises(InputError, match=words):
            run(setup, METHODS[method].treatment())
