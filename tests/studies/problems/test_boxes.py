"""3D box problems (studies/problems/boxes.py), 3D sympy fields (studies/problems/manufactured.py) and frame_3d."""
import numpy as np
import pytest
import sympy as sp

from ibm.geometry.frames import frame_3d, frame_of_angle
from ibm.models.elastic import Elastic
from studies.problems.box_fields import BOXES
from studies.problems.manufactured import FACES, OUTWARD_3D, Field
from studies.problems.library import Parameters

MATERIAL = Elastic(1e4, 0.3)
PARAMETERS = Parameters(MATERIAL, 10.0, 100.0, 80.0, depth=60.0)     # L, H, W all different
SIZE = np.array([100.0, 80.0, 60.0])


def _on(s, face):
    return {"base": {s["eta"]: 0}, "right": {s["xi"]: s["L"]}, "top": {s["eta"]: s["H"]},
            "left": {s["xi"]: 0}, "front": {s["zeta"]: 0}, "back": {s["zeta"]: s["W"]}}[face]


def test_frame_3d():
    assert np.array_equal(frame_3d(90, 0), np.eye(3))
    for theta in (0, 30, 90, 137.5, -60):
        planar = frame_3d(theta, 0)
        assert np.array_equal(planar[:2, :2], frame_of_angle(theta)) and np.array_equal(planar[2], [0, 0, 1])
    t, s = np.deg2rad(30), np.deg2rad(20)
    R = frame_3d(30, 20)
    expected = np.array([[np.sin(t), -np.cos(t), 0],                                # e_xi: untouched by the tilt
                         [np.cos(s) * np.cos(t), np.cos(s) * np.sin(t), np.sin(s)],  # e_eta tilted towards z
                         [-np.sin(s) * np.cos(t), -np.sin(s) * np.sin(t), np.cos(s)]]).T
    assert np.abs(R - expected).max() < 1e-15
    assert np.abs(R.T @ R - np.eye(3)).max() < 1e-15 and np.isclose(np.linalg.det(R), 1.0)
    assert np.array_equal(frame_3d(90, 90), [[1, 0, 0], [0, 0, -1], [0, 1, 0]])   # snapped like frame_of_angle


def test_depth_defaults_and_2d_fields_unchanged():
    assert Parameters(MATERIAL, 1.0).depth == 100.0
    assert Field("0", "eta") == Field("0", "eta", None) and Field("0", "eta").dimension == 2
    u, grad = Field("xi * eta", "L + H")(np.array([1.0, 2.0]), np.array([3.0, 4.0]), PARAMETERS)
    assert u.shape == (2, 2) and grad.shape == (2, 2, 2)
    assert np.array_equal(u, [[3.0, 180.0], [8.0, 180.0]])
    with pytest.raises(TypeError, match="a 2D field takes"):
        Field("0", "eta")(np.zeros(2), np.zeros(2), np.zeros(2), PARAMETERS)


def test_3d_field_names_and_shapes():
    """xi, eta, zeta, L, H, W (= depth), p, lam, mu, M all reach the numpy functions."""
    field = Field("xi * eta * zeta / (L * H * W)", "W + p", "M - lam - 2 * mu + zeta")
    x = np.array([[10.0, 20.0, 30.0], [50.0, 40.0, 6.0]])
    u, grad = field(*x.T, PARAMETERS)
    assert u.shape == (2, 3) and grad.shape == (2, 3, 3)
    assert np.allclose(u, [[6000 / 480000, 70, 30], [12000 / 480000, 70, 6]], rtol=1e-14, atol=1e-12)
    assert np.allclose(grad[0], [[20 * 30 / 480000, 10 * 30 / 480000, 10 * 20 / 480000], [0, 0, 0], [0, 0, 1]])
    assert field.body_force(*x.T, PARAMETERS).shape == (2, 3)
    for face in FACES:
        assert field.traction(face, *x.T, PARAMETERS).shape == (2, 3)
    with pytest.raises(TypeError, match="a 3D field takes"):
        field(x[:, 0], x[:, 1], PARAMETERS)


@pytest.mark.parametrize("name", list(BOXES))
def test_boundary_conditions_hold_exactly(name):
    """Roller: u.n = 0 and both tangential shears of sigma n vanish; free: sigma n = 0;
    the derived tractions are sigma n on their faces."""
    field, kinds, _ = BOXES[name]
    assert len(kinds) == 6 and kinds.count("roller") == 5
    d = field.derivation()
    s = d.symbols
    for face, kind in zip(FACES, kinds):
        n = sp.Matrix(OUTWARD_3D[face])
        on = _on(s, face)
        traction = (d.sigma * n).subs(on)
        assert sp.simplify(traction - d.traction[face]) == sp.zeros(3, 1), face
        if kind == "roller":
            assert sp.simplify(n.dot(d.u.subs(on))) == 0, face
            tangents = [sp.Matrix(e) for e in np.eye(3, dtype=int).tolist() if sp.Matrix(e).dot(n) == 0]
            assert len(tangents) == 2
            for t in tangents:
                assert sp.simplify(t.dot(traction)) == 0, face
        elif kind == "free":
            assert sp.simplify(traction) == sp.zeros(3, 1), face


@pytest.mark.parametrize("name", list(BOXES))
def test_symbolic_equilibrium(name):
    d = BOXES[name][0].derivation()
    x = [d.symbols[c] for c in ("xi", "eta", "zeta")]
    divergence = sp.Matrix([sum(sp.diff(d.sigma[i, j], x[j]) for j in range(3)) for i in range(3)])
    assert sp.simplify(divergence + d.body_force) == sp.zeros(3, 1)


def test_known_loads():
    """Confined block: (0, -p, 0) on top; column: b = (0, -p / H, 0), the top free."""
    p, H = sp.Symbol("p", real=True), sp.Symbol("H", real=True)
    assert BOXES["confined-block"][0].derivation().traction["top"] == sp.Matrix([0, -p, 0])
    assert BOXES["confined-block"][0].derivation().body_force == sp.zeros(3, 1)
    assert BOXES["column"][0].derivation().body_force == sp.Matrix([0, -p / H, 0])


def _stress(grad):
    eps = 0.5 * (grad + np.swapaxes(grad, 1, 2))
    return 2 * MATERIAL.mu * eps + MATERIAL.lam * np.einsum("pii->p", eps)[:, None, None] * np.eye(3)


@pytest.mark.parametrize("name", list(BOXES))
def test_body_force_is_minus_div_sigma_numerically(name):
    """Central differences of the lambdified stress at random points: b = -div sigma to 1e-6."""
    field = BOXES[name][0]
    x = np.random.default_rng(3).random((50, 3)) * SIZE
    step = 1e-4 * SIZE
    divergence = np.zeros((len(x), 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = step[j]
        plus, minus = (_stress(field(*(x + sign * e).T, PARAMETERS)[1]) for sign in (1, -1))
        divergence += (plus[:, :, j] - minus[:, :, j]) / (2 * step[j])
    b = field.body_force(*x.T, PARAMETERS)
    scale = max(np.abs(b).max(), PARAMETERS.load / PARAMETERS.height)
    assert np.abs(b + divergence).max() <= 1e-6 * scale


def test_manufactured_field_is_smooth_not_polynomial_and_of_order_p():
    field, kinds, _ = BOXES["manufactured"]
    assert kinds == ("roller", "roller", "traction", "roller", "roller", "roller")
    d = field.derivation()
    coordinates = [d.symbols[c] for c in ("xi", "eta", "zeta")]
    assert not any(component.is_polynomial(*coordinates) for component in d.u)
    x = np.random.default_rng(4).random((2000, 3)) * SIZE
    sigma = _stress(field(*x.T, PARAMETERS)[1])
    assert 0.3 < np.abs(sigma).max() / PARAMETERS.load < 5          # 3.4 here (pi H / L and friends)
    # the numeric top traction is sigma n there, and it is nonzero (the top carries the field)
    top = x.copy()
    top[:, 1] = SIZE[1]
    t = field.traction("top", *top.T, PARAMETERS)
    assert np.abs(t - _stress(field(*top.T, PARAMETERS)[1])[:, :, 1]).max() < 1e-12 * PARAMETERS.load
    assert np.abs(t).max() > 0.1 * PARAMETERS.load
