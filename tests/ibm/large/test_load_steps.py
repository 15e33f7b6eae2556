"""Large-deformation core: tangent, finite-strain patch test, Newton's rate, agreement with AMPLE-m."""
import numpy as np
import pytest

from ibm.models.constitutive import Hencky, undeformed
from studies.run.case import CaseSpec, run_case

# AMPLE-m (Octave 7.3, commit 4cbd757) on its column setup: err_sigma at 16, 32, 64 cells
AMPLE = {16: 3.658906e-3, 32: 1.048706e-3, 64: 4.357237e-4}


def _first_piola(model, dF, state):
    r = model.update(dF, state)
    return np.linalg.det(dF)[:, None, None] * r.sigma @ np.linalg.inv(dF).transpose(0, 2, 1)


def tangent_error(model, dF, state, eps: float = 1e-6) -> float:
    """max |d P / d dF by central differences - the model's spatial tangent pulled back to d P / d dF|,
    relative to the largest entry (P the first Piola stress of the step)."""
    r = model.update(dF, state)
    inverse = np.linalg.inv(dF)
    analytic = np.linalg.det(dF)[:, None, None, None, None] * np.einsum("nmj,nijkl,nol->nimko", inverse, r.tangent,
                                                                          inverse)
    numeric = np.zeros_like(analytic)
    for k in range(3):
        for o in range(3):
            d = np.zeros((3, 3))
            d[k, o] = eps
            numeric[:, :, :, k, o] = (_first_piola(model, dF + d, state) - _first_piola(model, dF - d, state)) / (2 * eps)
    return float(np.abs(numeric - analytic).max() / np.abs(analytic).max())


@pytest.mark.parametrize("prestrain", [0.0, 0.2])
def test_hencky_tangent_matches_finite_differences(prestrain):
    rng = np.random.default_rng(3)
    model = Hencky(1e4, 0.3)
    Fn = np.eye(3) + prestrain * rng.standard_normal((4, 3, 3))
    state = model.update(Fn, undeformed(4)).state if prestrain else undeformed(4)
    dF = np.eye(3) + 0.1 * rng.standard_normal((4, 3, 3)) if prestrain else np.broadcast_to(np.eye(3), (4, 3, 3)).copy()
    assert tangent_error(model, dF, state) <= 1e-7


@pytest.mark.parametrize("plane", [True, False])
def test_every_model_gives_the_in_plane_tangent_it_is_asked_for(plane):
    """update(..., dim=2) is the first two axes of the full tangent (what the 2D equilibrium uses), for
    every constitutive model, in plane strain and for a general 3D increment, from a prestrained and
    (J2, von Mises) yielding state; the full tangent is checked against finite differences above."""
    from ibm.models.plasticity import HenckyJ2
    from ibm.models.small_strain import LinearElastic, VonMises
    rng = np.random.default_rng(11)
    n = 50
    models = [Hencky(1e4, 0.3), HenckyJ2(1e4, 0.3, yield_stress=20.0, hardening=100.0),
              LinearElastic(1e4, 0.3), VonMises(1e4, 0.3, yield_stress=20.0, hardening=100.0)]
    for model in models:
        prestrain, increment = np.eye(3) + 0.05 * rng.standard_normal((2, n, 3, 3))
        if plane:
            prestrain[:, 2, :2] = prestrain[:, :2, 2] = increment[:, 2, :2] = increment[:, :2, 2] = 0
            prestrain[:, 2, 2] = increment[:, 2, 2] = 1
        state = model.update(prestrain, model.initial(n)).state
        full, planar = model.update(increment, state), model.update(increment, state, dim=2)
        assert planar.tangent.shape == (n, 2, 2, 2, 2)
        scale = np.abs(full.tangent).max()
        assert np.abs(planar.tangent - full.tangent[:, :2, :2, :2, :2]).max() <= 1e-13 * scale, type(model).__name__
        assert np.array_equal(planar.sigma, full.sigma)
    assert np.all(state.internal["alpha"] > 0)             # the last model (von Mises) has yielded


def test_plane_strain_principal_values_in_closed_form_agree_with_lapack():
    """ibm.models.constitutive.principal's closed form for plane-strain b_e (its 2 x 2 block's Mohr circle):
    b_e rebuilt from its eigenpairs to round-off, orthonormal vectors, LAPACK's eigenvalues, also at
    equal eigenvalues, a diagonal block and b_11 < b_22; a 3D b_e goes to LAPACK."""
    from ibm.models.constitutive import principal
    rng = np.random.default_rng(8)
    F = np.eye(3) + 0.3 * rng.standard_normal((200, 3, 3))
    F[:, 2, :2] = F[:, :2, 2] = 0
    F[:, 2, 2] = 1 + 0.1 * rng.standard_normal(200)
    F[0, :2, :2] = 1.3 * np.eye(2)                       # equal in-plane eigenvalues
    F[1, :2, :2] = np.diag([1.2, 0.8])                   # diagonal, b_11 > b_22
    F[2, :2, :2] = np.diag([0.8, 1.2])                   # diagonal, b_11 < b_22
    be = F @ F.transpose(0, 2, 1)
    values, vectors = principal(be)
    rebuilt = np.matmul(vectors * values[:, None, :], vectors.transpose(0, 2, 1))
    scale = np.abs(be).max()
    assert np.abs(rebuilt - be).max() <= 1e-15 * scale              # 1.3e-16 (LAPACK's own: 2.6e-16)
    assert np.abs(vectors.transpose(0, 2, 1) @ vectors - np.eye(3)).max() <= 1e-15
    assert np.abs(np.sort(values, axis=1) - np.linalg.eigvalsh(be)).max() <= 1e-15 * scale
    general = be.copy()
    general[:, 0, 2] = general[:, 2, 0] = 0.01
    values, vectors = principal(general)
    assert np.abs(np.matmul(vectors * values[:, None, :], vectors.transpose(0, 2, 1)) - general).max() <= 1e-14


def _block(method, angle, offset=(0.37, 0.29), **changes):
    settings = dict(problem="confined-block", load_type="settlement", load=40.0, method=method, angle=angle,
                    offset=offset, cell=10.0, ppc=2, kinematics="large", steps=10)
    spec = CaseSpec(**{**settings, **changes})
    return run_case(spec)


@pytest.mark.parametrize("angle,offset", [(90, (0.37, 0.29)), (45, (0.1, 0.7)), (30, (0.37, 0.29))])
@pytest.mark.parametrize("method", ["lagrange", "nitsche", "fem"])
def test_finite_strain_patch_test_consistent_methods(method, angle, offset):
    """Settled by 40% in 10 steps with GIMP: consistent methods reproduce the homogeneous field."""
    r = _block(method, angle, offset)
    worst = max(max(h["err_u"], h["err_sigma"]) for h in r["history"])
    assert worst <= 1e-9, worst


_RANDOM = np.random.default_rng(12)
PLACEMENTS = [(round(float(a), 3), tuple(np.round(o, 3))) for a, o in
              zip(_RANDOM.uniform(0, 90, 3), _RANDOM.uniform(0, 1, (3, 2)))]


@pytest.mark.parametrize("angle,offset", PLACEMENTS)
@pytest.mark.parametrize("method", ["lagrange", "nitsche"])
def test_finite_strain_patch_test_at_random_placements(method, angle, offset):
    r = _block(method, angle, offset)
    assert max(max(h["err_u"], h["err_sigma"]) for h in r["history"]) <= 1e-9
    assert r["max_penetration"] == 0.0


def test_standard_mpm_patch_error_recorded_beside_gimp():
    """Standard MPM's cell-crossing error on the same patch test: recorded (it is O(1)), not small."""
    mpm, gimp = _block("nitsche", 30, basis="mpm"), _block("nitsche", 30)
    assert mpm["err_sigma"] > 1e-2 > 1e-9 > gimp["err_sigma"]


def test_finite_strain_patch_test_nodal_on_grid_lines():
    r = _block("nodal", 90, (0.0, 0.0), cell=4.0, width=40.0)     # the top wall on a grid line at every step
    assert max(max(h["err_u"], h["err_sigma"]) for h in r["history"]) <= 1e-9


@pytest.mark.parametrize("angle", [90, 30])
def test_finite_strain_patch_test_ibm_and_penalty_at_their_level(angle):
    ibm, penalty = _block("ibm", angle), _block("penalty", angle)
    # O(delta): delta/h = 1e-5 gives ~1e-7 in u, ~1e-6 in sigma; O(1/beta0): beta0 = 1e6
    assert 1e-10 < ibm["err_u"] < 1e-6 and ibm["err_sigma"] < 1e-5
    assert 1e-9 < penalty["err_u"] < 2e-6 and penalty["err_sigma"] < 1e-5
    ten = _block("ibm", angle, method_parameters={"delta_rel": 1e-4})
    assert 5 < ten["err_u"] / ibm["err_u"] < 20          # the error is linear in delta


def _column(cells, method="nodal", basis="gimp"):
    h = 50 / cells
    spec = CaseSpec(problem="column", method=method, kinematics="large", basis=basis, steps=40, E=1e4, nu=0.0,
                    load=40000.0, width=h, height=50.0, cell=h, ppc=2, angle=90.0, offset=(0.0, 0.0))
    return run_case(spec)


@pytest.mark.parametrize("cells", sorted(AMPLE))
def test_nodal_gimp_column_agrees_with_ample(cells):
    r = _column(cells)
    assert abs(r["err_sigma_ample"] / AMPLE[cells] - 1) <= 0.03
    assert abs(r["err_sigma_ample"] / AMPLE[cells] - 1) <= 1e-5     # measured: the same to 7 digits


def test_standard_mpm_column_stalls_like_ample():
    r = _column(16, basis="mpm")
    assert abs(r["err_sigma_ample"] / 8.669649e-2 - 1) <= 1e-5


@pytest.mark.parametrize("method", ["nodal", "ibm"])
def test_newton_converges_quadratically_on_the_column(method):
    r = _column(16, method)
    for step in r["history"]:
        res = step["residuals"]
        assert res[-1] <= 1e-9
        # from the second iteration on, log r_(k+1) / log r_k >= 1.8 while above round-off
        rates = [np.log(b) / np.log(a) for a, b in zip(res[1:], res[2:]) if b > 1e-13 and a < 1e-1]
        assert all(rate >= 1.8 for rate in rates), (step["step"], res)


@pytest.mark.parametrize("changes,message", [
    ({"kinematics": "big"}, "kinematics 'big' is not allowed"),
    ({"steps": 0, "kinematics": "large"}, "steps 0 is not allowed"),
    ({"steps": 5}, "steps 5 is not allowed with small kinematics"),
    ({"basis": "bspline"}, "basis 'bspline' is not allowed"),
    ({"width": -1.0}, "body width -1.0 is not allowed"),
    ({"kinematics": "large", "method": "ibm-limit"}, "refuses large kinematics"),
    ({"kinematics": "large", "method": "lagrange-nodal"}, "refuses large kinematics"),
    ({"kinematics": "large", "problem": "manufactured"}, "no exact finite-strain solution"),
    ({"kinematics": "large", "method": "nodal", "angle": 30.0}, "needs every essential edge on a grid line"),
])
def test_bad_large_deformation_input_is_one_clear_line(changes, message):
    from ibm.exceptions import InputError
    with pytest.raises(InputError, match=message):
        run_case(CaseSpec(**{"problem": "column", **changes}))
