"""Finite-strain exact solutions: Lambert-W column against a numerical integration, the
Hencky stress in uniaxial strain (sympy), the small-load limit, compression by a pressure."""
import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad
from scipy.optimize import brentq

from ibm.models.elastic import Elastic
from studies.problems.finite_strain import (ample_error, column, column_height, compression,
                                   compression_stretch_of_pressure, small_strain_column)

MATERIAL = Elastic(1e4, 0.3)
H = 50.0
WEIGHT = 800.0          # weight H / M = 2.97: stretch 0.33 at the base


def stretch_by_root(Y, H, weight, M):
    """s in (0, 1] with M ln(s) / s = -weight (H - Y), by bracketing."""
    pressure = weight * (H - Y)
    if pressure == 0:
        return 1.0
    return brentq(lambda s: M * np.log(s) / s + pressure, 1e-6, 1.0, xtol=1e-16, rtol=1e-15)


def test_column_matches_a_numerical_integration_of_dy_dY_equal_stretch():
    lam, M = MATERIAL.lam, MATERIAL.M
    Y = np.linspace(0.0, H, 11)[1:]                                    # (10,)
    exact = column(Y, H, WEIGHT, lam, M)
    stretch = np.array([stretch_by_root(y, H, WEIGHT, M) for y in Y])
    assert np.abs(exact.stretch / stretch - 1).max() < 1e-12
    u_eta = np.array([quad(lambda t: stretch_by_root(t, H, WEIGHT, M) - 1, 0.0, y,
                           epsabs=0.0, epsrel=1e-13, limit=200)[0] for y in Y])
    assert np.abs(exact.u_eta / u_eta - 1).max() < 1e-10
    assert abs(column_height(H, WEIGHT, M) / (H + u_eta[-1]) - 1) < 1e-10


def test_column_stress_is_the_hencky_stress_of_its_stretch_and_the_base_stays():
    lam, M = MATERIAL.lam, MATERIAL.M
    Y = np.linspace(0.0, H, 101)                                       # (101,)
    exact = column(Y, H, WEIGHT, lam, M)
    hencky = M * np.log(exact.stretch) / exact.stretch
    assert np.abs(hencky - exact.sigma_eta_eta).max() < 1e-12 * WEIGHT * H
    assert np.abs(exact.sigma_eta_eta + WEIGHT * (H - Y)).max() < 1e-12 * WEIGHT * H
    assert np.abs(exact.sigma_xi_xi - lam * np.log(exact.stretch) / exact.stretch).max() < 1e-12 * WEIGHT * H
    assert exact.u_eta[0] == 0.0
    assert exact.stretch[-1] == 1.0
    assert np.all(np.diff(exact.stretch) > 0)                          # least compressed at the top


def test_column_known_numbers():
    material = Elastic(1e4, 0.0)
    exact = column(np.array([0.0]), 50.0, 800.0, material.lam, material.M)
    assert abs(exact.stretch[0] - 0.30054) < 5e-6
    assert abs(column_height(50.0, 800.0, material.M) - 24.0596) < 5e-5


def test_hencky_cauchy_stress_in_uniaxial_strain():
    s = sp.Symbol("s", positive=True)
    lam, mu = sp.symbols("lam mu", positive=True)
    F = sp.diag(1, s, 1)                                               # (xi, eta, z)
    b = F * F.T
    assert b.is_diagonal()
    eps = sp.diag(*[sp.expand_log(sp.log(b[i, i]) / 2) for i in range(3)])
    tau = lam * eps.trace() * sp.eye(3) + 2 * mu * eps
    sigma = tau / F.det()
    M = lam + 2 * mu
    assert sp.simplify(sigma - sp.diag(lam, M, lam) * sp.log(s) / s) == sp.zeros(3, 3)
    state = compression(np.array([1.0]), 0.7, MATERIAL.lam, MATERIAL.M)
    values = {s: 0.7, lam: MATERIAL.lam, mu: MATERIAL.mu}
    for i, component in enumerate((state.sigma_xi_xi, state.sigma_eta_eta, state.sigma_zz)):
        assert component[0] == pytest.approx(float(sigma[i, i].subs(values)), rel=1e-14)


def test_small_weight_limit_is_the_small_strain_column_with_relative_difference_of_order_weight():
    lam, M = MATERIAL.lam, MATERIAL.M
    Y = np.linspace(0.0, H, 21)[1:]                                    # (20,)

    def relative_difference(weight):
        small = small_strain_column(Y, H, weight, M)
        return np.abs(column(Y, H, weight, lam, M).u_eta - small).max() / np.abs(small).max()

    weight = 1e-2 * M / H                                              # weight H / M = 0.01
    difference, halved = relative_difference(weight), relative_difference(weight / 2)
    assert difference < weight * H / M
    assert halved / difference == pytest.approx(0.5, rel=0.1)


def test_compression_stretch_of_pressure_solves_the_hencky_relation():
    M = MATERIAL.M
    pressure = np.logspace(-6, 1, 57) * M                              # (57,)
    s = compression_stretch_of_pressure(pressure, M)
    assert np.all((s > 0) & (s < 1))
    residual = M * np.log(s) / s + pressure
    # s near 1 is stored to within eps, so M eps bounds the residual at small pressure
    assert np.all(np.abs(residual) < 1e-12 * pressure + 4 * M * np.finfo(float).eps)
    state = compression(np.linspace(0, H, 5), s[-1], MATERIAL.lam, M)
    assert state.sigma_eta_eta == pytest.approx(-pressure[-1], rel=1e-12)
    assert state.u_eta[-1] == pytest.approx((s[-1] - 1) * H, rel=1e-15)
    assert np.all(state.u_xi == 0)


def test_ample_error_is_volume_weighted_and_normalised_by_weight_H():
    exact = np.array([-2.0, -1.0, 0.0])
    computed = np.array([-2.5, -1.0, 0.5])
    V0 = np.array([1.0, 2.0, 4.0])
    assert ample_error(computed, exact, V0, 4.0, 0.5) == pytest.approx((0.5 + 2.0) / (4.0 * 0.5 * 7.0), rel=1e-15)
    assert ample_error(exact, exact, V0, 4.0, 0.5) == 0.0
