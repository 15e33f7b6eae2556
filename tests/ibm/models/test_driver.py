"""The mixed driver: a strain increment with one normal stress prescribed, vectorised over points."""
import numpy as np
import pytest

from ibm.exceptions import InputError
from ibm.models.driver import mixed_increment
from ibm.models.plasticity import HenckyJ2
from ibm.models.small_strain import LinearElastic, VonMises


def test_elastic_uniaxial_stress_in_plane_strain():
    """sigma_yy = 0 with eps_zz = 0: sigma_xx = E / (1 - nu^2) eps_xx, eps_yy = -nu / (1 - nu) eps_xx."""
    E, nu, strain = 1e4, 0.3, -1e-3
    material = LinearElastic(E, nu)
    increment = np.zeros((2, 3, 3))
    increment[:, 0, 0] = strain
    response = mixed_increment(material, material.initial(2), increment, 1, np.array([0.0, -3.0]))
    assert response.sigma[0, 0, 0] == pytest.approx(E / (1 - nu ** 2) * strain, rel=1e-11)
    assert response.state.F[0, 1, 1] - 1 == pytest.approx(-nu / (1 - nu) * strain, rel=1e-11)
    # round-off of dF = I + grad u: 1e-16 in a strain is 1e-12 in a stress at E = 1e4
    assert response.sigma[:, 1, 1] == pytest.approx([0.0, -3.0], abs=1e-11)


def test_von_mises_reaches_the_plane_strain_limit():
    """Pushed on at sigma_yy = target, sigma_xx - sigma_yy -> -2 sigma_y / sqrt(3) and sigma_zz -> the in-plane mean."""
    material = VonMises(1e4, 0.3, yield_stress=100.0)
    target = np.array([0.0, -40.0])
    state = material.initial(2)
    for _ in range(40):
        increment = np.zeros((2, 3, 3))
        increment[:, 0, 0] = -0.2 / 40
        response = mixed_increment(material, state, increment, 1, target)
        state = response.state
    sigma = response.sigma
    assert sigma[:, 1, 1] == pytest.approx(target, abs=1e-10)
    assert sigma[:, 0, 0] - sigma[:, 1, 1] == pytest.approx(-2 * 100 / np.sqrt(3), rel=1e-9)
    assert sigma[:, 2, 2] == pytest.approx((sigma[:, 0, 0] + sigma[:, 1, 1]) / 2, rel=1e-7)


def test_refusals():
    material = LinearElastic(1e4, 0.3)
    with pytest.raises(InputError, match="component 2 is not allowed"):
        mixed_increment(material, material.initial(1), np.zeros((1, 3, 3)), 2, np.zeros(1))
    with pytest.raises(InputError, match="small-strain models; got HenckyJ2"):
        finite = HenckyJ2(1e4, 0.3, yield_stress=100.0)
        mixed_increment(finite, finite.initial(1), np.zeros((1, 3, 3)), 1, np.zeros(1))
