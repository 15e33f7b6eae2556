"""Mohr-Coulomb and Drucker-Prager (ibm.models.mohr_coulomb, ibm.models.drucker_prager, ibm.models.isotropic):
every return region's stress on the yield surface, its consistent tangent against finite differences at
small and finite strain, the associated return as the closest point in the energy norm, the limits that
are other models (phi = 0) and the plane-strain match of the two surfaces."""
import numpy as np
import pytest
from scipy.optimize import minimize

from ibm.exceptions import InputError
from ibm.models.constitutive import Hencky, State
from ibm.models.driver import mixed_increment
from ibm.models.drucker_prager import DruckerPrager, HenckyDruckerPrager, drucker_prager_yield
from ibm.models.mohr_coulomb import HenckyMohrCoulomb, MohrCoulomb, mohr_coulomb_return, mohr_coulomb_yield
from ibm.models.small_strain import LinearElastic, VonMises
from tests.ibm.large.test_load_steps import tangent_error
from tests.ibm.models.test_small_strain import finite_difference_tangent

E, NU, C, PHI = 1e4, 0.3, 10.0, 30.0
SMALL = {"mohr-coulomb": (MohrCoulomb, mohr_coulomb_yield, (1, 2, 3, 4)),
         "drucker-prager": (DruckerPrager, drucker_prager_yield, (1, 2))}
FINITE = {"mohr-coulomb": HenckyMohrCoulomb, "drucker-prager": HenckyDruckerPrager}


def _increments(count: int, size: float, seed: int) -> np.ndarray:
    """dF = I + a random gradient with a random volume change: trials in every region."""
    rng = np.random.default_rng(seed)
    return (np.eye(3) + rng.normal(scale=size, size=(count, 3, 3))
            + np.eye(3) * rng.normal(scale=0.75 * size, size=(count, 1, 1)))


def _take(state: State, mine: np.ndarray) -> State:
    return state.take(np.flatnonzero(mine))


@pytest.mark.parametrize("dilation", [PHI, 10.0])
@pytest.mark.parametrize("name", list(SMALL))
def test_small_strain_return_lands_on_the_surface_with_its_tangent_in_every_region(name, dilation):
    cls, surface, regions = SMALL[name]
    model = cls(E, NU, cohesion=C, friction_angle=PHI, dilation_angle=dilation)
    dF = _increments(300, 4e-3, seed=1)
    response = model.update(dF, model.initial(300))
    region = response.state.internal["region"]
    assert set(np.unique(region)) == {0, *regions}                      # every region is tried
    principal = np.linalg.eigvalsh(response.sigma)
    f = surface(principal, C, PHI)
    assert np.abs(f[region > 0]).max() <= 1e-12 * np.abs(principal).max()
    assert f[region == 0].max() < 0
    fd = finite_difference_tangent(model, dF, model.initial(300), step=1e-9)
    for code in np.unique(region):
        mine = region == code
        assert np.abs(fd[mine] - response.tangent[mine]).max() <= 1e-5 * model.M, (name, code)


@pytest.mark.parametrize("dilation", [PHI, 10.0])
@pytest.mark.parametrize("name", list(FINITE))
def test_finite_strain_tangent_matches_finite_differences_in_every_region(name, dilation):
    model = FINITE[name](E, NU, cohesion=C, friction_angle=PHI, dilation_angle=dilation)
    dF = _increments(200, 4e-2, seed=2)
    state = model.initial(200)
    response = model.update(dF, state)
    region = response.state.internal["region"]
    tau = response.sigma * np.linalg.det(dF)[:, None, None]
    f = SMALL[name][1](np.linalg.eigvalsh(tau), C, PHI)
    assert np.abs(f[region > 0]).max() <= 1e-11 * np.abs(tau).max()
    for code in np.unique(region):
        mine = region == code
        assert tangent_error(model, dF[mine], _take(state, mine), eps=1e-7) <= 1e-6, (name, code)


def test_associated_mohr_coulomb_return_is_the_closest_point_in_the_energy_norm():
    """The return to a convex set with associated flow minimises (sigma - sigma_tr) D^-1 (sigma - sigma_tr)
    over the six planes of the prism (solved here by SLSQP, independent of the region logic)."""
    lam, mu = LinearElastic(E, NU).lam, LinearElastic(E, NU).mu
    D = lam * np.ones((3, 3)) + 2 * mu * np.eye(3)
    compliance = np.linalg.inv(D)
    strains = np.random.default_rng(3).normal(scale=3e-3, size=(40, 3))
    stress, _, region = mohr_coulomb_return(strains, lam, mu, C, PHI, PHI)
    assert set(np.unique(region)) >= {1, 2, 3, 4}
    s = np.sin(np.radians(PHI))
    pairs = [(i, j) for i in range(3) for j in range(3) if i != j]
    for trial, returned in zip(strains @ D, stress):
        constraints = [{"type": "ineq", "fun": lambda x, i=i, j=j: 2 * C * np.cos(np.radians(PHI))
                        - (x[i] - x[j] + (x[i] + x[j]) * s)} for i, j in pairs]
        best = minimize(lambda x: (x - trial) @ compliance @ (x - trial), trial, constraints=constraints,
                        method="SLSQP", options={"ftol": 1e-16, "maxiter": 500})
        assert np.abs(best.x - returned).max() <= 1e-6 * max(np.abs(trial).max(), 1.0)


def test_without_friction_drucker_prager_is_von_mises_and_mohr_coulomb_is_tresca():
    dF = _increments(100, 4e-3, seed=4)
    cone = DruckerPrager(E, NU, cohesion=C, friction_angle=0.0, dilation_angle=0.0)
    mises = VonMises(E, NU, yield_stress=np.sqrt(3) * C)
    a, b = cone.update(dF, cone.initial(100)), mises.update(dF, mises.initial(100))
    assert np.any(a.state.internal["region"] > 0)
    assert np.abs(a.sigma - b.sigma).max() <= 1e-12 * np.abs(b.sigma).max()
    assert np.abs(a.tangent - b.tangent).max() <= 1e-10 * np.abs(b.tangent).max()
    prism = MohrCoulomb(E, NU, cohesion=C, friction_angle=0.0, dilation_angle=0.0)
    r = prism.update(dF, prism.initial(100))
    principal = np.linalg.eigvalsh(r.sigma)
    plastic = r.state.internal["region"] > 0
    assert np.any(plastic) and not np.any(r.state.internal["region"] == 4)     # Tresca has no apex
    assert np.abs(principal[plastic, 2] - principal[plastic, 0] - 2 * C).max() <= 1e-12 * np.abs(principal).max()


@pytest.mark.parametrize("name", list(SMALL))
def test_below_yield_they_are_elastic(name):
    dF = _increments(20, 1e-5, seed=5)
    small = SMALL[name][0](E, NU, cohesion=1e3, friction_angle=PHI, dilation_angle=0.0)
    a, b = small.update(dF, small.initial(20)), LinearElastic(E, NU).update(dF, LinearElastic(E, NU).initial(20))
    assert np.all(a.state.internal["region"] == 0)
    assert np.abs(a.sigma - b.sigma).max() <= 1e-12 * np.abs(b.sigma).max()
    assert np.abs(a.tangent - b.tangent).max() <= 1e-9 * E
    large = FINITE[name](E, NU, cohesion=1e3, friction_angle=PHI, dilation_angle=0.0)
    a, b = large.update(dF, large.initial(20)), Hencky(E, NU).update(dF, Hencky(E, NU).initial(20))
    assert np.abs(a.sigma - b.sigma).max() <= 1e-12 * np.abs(b.sigma).max()
    assert np.abs(a.tangent - b.tangent).max() <= 1e-9 * E


def _biaxial_limit(model, confining: float, steps: int = 400, shortening: float = 0.1) -> float:
    """sigma_yy after shortening a plane-strain point under the lateral stress -confining (mixed driver)."""
    state = model.initial(1)
    increment = np.zeros((1, 3, 3))
    increment[0, 1, 1] = -shortening / steps
    for _ in range(steps):
        response = mixed_increment(model, state, increment, 0, np.array([-confining]), dim=2)
        state = response.state
    return float(response.sigma[0, 1, 1])


@pytest.mark.parametrize("phi", [20.0, 30.0, 40.0])
def test_plane_strain_drucker_prager_gives_the_mohr_coulomb_limit_with_associated_flow(phi):
    """Biaxial compression in plane strain: Mohr-Coulomb's limit sigma_yy = -p0 K_p - 2 c sqrt(K_p),
    K_p = (1 + sin phi) / (1 - sin phi); the matched cone reaches it once its out-of-plane flow stops."""
    p0 = 20.0
    K = (1 + np.sin(np.radians(phi))) / (1 - np.sin(np.radians(phi)))
    exact = -p0 * K - 2 * C * np.sqrt(K)
    prism = _biaxial_limit(MohrCoulomb(E, NU, cohesion=C, friction_angle=phi, dilation_angle=phi), p0)
    cone = _biaxial_limit(DruckerPrager(E, NU, cohesion=C, friction_angle=phi, dilation_angle=phi), p0)
    assert abs(prism - exact) <= 1e-10 * abs(exact)
    assert abs(cone - exact) <= 1e-6 * abs(exact)


@pytest.mark.parametrize("values, message", [
    ((C, 90.0, 0.0), "friction angle 90 is not allowed"),
    ((C, -1.0, 0.0), "friction angle -1"),
    ((C, float("nan"), 0.0), "friction angle nan"),
    ((C, 30.0, 35.0), "dilation angle 35 is not allowed; it must be in \\[0, friction angle 30\\]"),
    ((-1.0, 30.0, 0.0), "cohesion -1"),
    ((0.0, 0.0, 0.0), "cohesion 0 is not allowed with friction angle 0"),
])
@pytest.mark.parametrize("cls", [MohrCoulomb, HenckyMohrCoulomb, DruckerPrager, HenckyDruckerPrager])
def test_bad_parameters_are_one_line(cls, values, message):
    with pytest.raises(InputError, match=message):
        cls(E, NU, cohesion=values[0], friction_angle=values[1], dilation_angle=values[2])



@pytest.mark.parametrize("cls", [MohrCoulomb, HenckyMohrCoulomb, DruckerPrager, HenckyDruckerPrager])
def test_equivalent_plastic_strain_grows_only_where_the_soil_yields(cls):
    """alpha, the sum of sqrt(2/3) |d eps_p| (the plastic zones the report draws): zero on the elastic points,
    and at small strain, on a plastic one, sqrt(2/3) |eps_p| after one step from the undeformed state."""
    model = cls(E, NU, cohesion=C, friction_angle=PHI, dilation_angle=10.0)
    dF = _increments(100, 4e-3, seed=6)
    state = model.update(dF, model.initial(100)).state
    plastic = state.internal["region"] > 0
    assert np.all(state.internal["alpha"][~plastic] == 0) and np.all(state.internal["alpha"][plastic] > 0)
    if "plastic" in state.internal:
        size = np.sqrt(2 / 3 * np.sum(state.internal["plastic"] ** 2, axis=(1, 2)))
        assert np.abs(state.internal["alpha"] - size).max() <= 1e-15
