"""Small-strain models: linear elasticity and von Mises radial return (ibm.models.small_strain)."""
import numpy as np
import pytest

from ibm.exceptions import InputError
from ibm.models.small_strain import LinearElastic, VonMises, strain

E, NU, YIELD = 2.1e5, 0.3, 240.0


def plane_strain_increments(count, size, seed=0):
    """dF = I + grad du with grad du random in-plane (3 x 3, zz row and column zero)."""
    grad = np.zeros((count, 3, 3))
    grad[:, :2, :2] = np.random.default_rng(seed).normal(scale=size, size=(count, 2, 2))
    return np.eye(3) + grad


def finite_difference_tangent(model, dF, state, step=1e-9):
    n = len(dF)
    fd = np.zeros((n, 3, 3, 3, 3))
    for k in range(3):
        for l in range(3):
            e = np.zeros((3, 3))
            e[k, l] = step
            plus = model.update(dF + e, state).sigma
            minus = model.update(dF - e, state).sigma
            fd[:, :, :, k, l] = (plus - minus) / (2 * step)
    return fd


@pytest.mark.parametrize("hardening", [0.0, 1e4])
def test_von_mises_tangent_matches_finite_differences_in_plastic_states(hardening):
    model = VonMises(E, NU, yield_stress=YIELD, hardening=hardening)
    state = model.initial(50)
    # a first plastic step, then a second from its converged state
    first = model.update(plane_strain_increments(50, 4e-3, seed=1), state)
    dF = plane_strain_increments(50, 2e-3, seed=2)
    response = model.update(dF, first.state)
    assert np.mean(response.state.internal["alpha"] > first.state.internal["alpha"]) > 0.5   # mostly plastic
    fd = finite_difference_tangent(model, dF, first.state)
    assert np.abs(fd - response.tangent).max() <= 1e-6 * np.abs(response.tangent).max()


@pytest.mark.parametrize("hardening", [0.0, 1e4])
def test_radial_return_ends_on_the_yield_surface_and_unloads_elastically(hardening):
    model = VonMises(E, NU, yield_stress=YIELD, hardening=hardening)
    loaded = model.update(plane_strain_increments(200, 5e-3, seed=3), model.initial(200))
    alpha = loaded.state.internal["alpha"]
    s = loaded.sigma - np.trace(loaded.sigma, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    q = np.sqrt(1.5 * np.sum(s * s, axis=(1, 2)))                       # von Mises stress
    plastic = alpha > 0
    assert plastic.mean() > 0.9
    assert np.abs(q[plastic] - (YIELD + hardening * alpha[plastic])).max() <= 1e-10 * YIELD
    # plastic flow is isochoric and deviatoric
    assert np.abs(np.trace(loaded.state.internal["plastic"], axis1=1, axis2=2)).max() < 1e-17
    # unloading by a small reverse increment is exactly elastic: stress change C : d eps
    back = np.eye(3) - 1e-5 * (plane_strain_increments(200, 1.0, seed=3) - np.eye(3))
    unloaded = model.update(back, loaded.state)
    elastic = LinearElastic(E, NU)
    expected = loaded.sigma + elastic.update(back, elastic.initial(200)).sigma
    assert np.abs(unloaded.sigma - expected).max() <= 1e-12 * YIELD
    assert np.array_equal(unloaded.state.internal["alpha"], alpha)


def test_below_yield_von_mises_is_linear_elastic():
    dF = plane_strain_increments(20, 1e-5, seed=4)
    plastic, elastic = VonMises(E, NU, yield_stress=YIELD), LinearElastic(E, NU)
    a, b = plastic.update(dF, plastic.initial(20)), elastic.update(dF, elastic.initial(20))
    assert np.allclose(a.sigma, b.sigma, rtol=0, atol=1e-12 * YIELD)
    assert np.allclose(a.tangent, b.tangent, rtol=1e-14, atol=0)
    assert np.array_equal(strain(a.state.F), strain(dF))


def test_uniaxial_plane_strain_hardening_curve():
    """Pure shear eps_xy = g: tau = mu * 2 g elastically, then sigma_y / sqrt(3) + hardening along
    the equivalent plastic strain; the closed form is tau = (sqrt(3) k + H alpha) / sqrt(3), alpha =
    2 (g - g_y) / sqrt(3) (1 + H / (3 mu))^-1."""
    H = 2e4
    model = VonMises(E, NU, yield_stress=YIELD, hardening=H)
    mu = model.mu
    state, taus = model.initial(1), []
    shears = np.linspace(0, 8e-3, 81)
    for dg in np.diff(shears):
        dF = np.eye(3)[None].copy()
        dF[0, 0, 1] = dF[0, 1, 0] = dg
        response = model.update(dF, state)
        state = response.state
        taus.append(response.sigma[0, 0, 1])
    g = shears[1:]
    g_yield = YIELD / np.sqrt(3) / (2 * mu)
    alpha = np.where(g > g_yield, 2 * (g - g_yield) / np.sqrt(3) / (1 + H / (3 * mu)), 0.0)
    exact = np.where(g > g_yield, (YIELD + H * alpha) / np.sqrt(3), 2 * mu * g)
    assert np.abs(np.array(taus) - exact).max() <= 1e-9 * YIELD


@pytest.mark.parametrize("yield_stress,hardening,message", [
    (0.0, 0.0, "yield stress 0.0 is not allowed; it must be > 0"),
    (240.0, -1.0, "hardening modulus -1.0 is not allowed; it must be >= 0")])
def test_von_mises_refuses_bad_parameters(yield_stress, hardening, message):
    with pytest.raises(InputError, match=message):
        VonMises(E, NU, yield_stress=yield_stress, hardening=hardening)
