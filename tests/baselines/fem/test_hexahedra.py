"""Body-fitted hexahedral reference (baselines/fem/hexahedra.py) on the 3D boxes of studies/problems/boxes.py."""
import numpy as np
import pytest
from skfem import Basis, ElementHex1, ElementHex2, ElementVector, MeshHex, asm
from skfem.models.elasticity import linear_elasticity

from baselines.fem.hexahedra import FACES, OUTWARD, _stiffness, isotropic_stress, solve_box
from ibm.geometry.frames import frame_3d
from ibm.exceptions import InputError
from ibm.models.elastic import Elastic
from studies.problems.box_fields import BOXES
from studies.problems.manufactured import FACES as FIELD_FACES, OUTWARD_3D, Field
from studies.problems.library import Parameters

MATERIAL = Elastic(1e4, 0.3)
PARAMETERS = Parameters(MATERIAL, 10.0, 100.0, 80.0, depth=60.0)     # L, H, W all different
CUBE = Parameters(MATERIAL, 10.0, 100.0, 100.0, depth=100.0)
CORNER = np.array([3.0, -7.0, 11.0])


def _random_frame(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q * np.sign(np.linalg.det(q))                 # a right-handed orthonormal frame


def _size(prm: Parameters) -> np.ndarray:
    return np.array([prm.width, prm.height, prm.depth])


def _solve(name: str | None, R: np.ndarray, h: float, order: int = 1, prm: Parameters = PARAMETERS,
           kinds=None, lift: Field | None = None):
    """fem_hex on the box `name` with its body force and tractions (kinds: its own unless given), or,
    name None, on `kinds` loaded by the lift alone."""
    body_force = traction = None
    if name is not None:
        field, box_kinds, _ = BOXES[name]
        kinds = kinds or box_kinds

        def body_force(xl):
            return field.body_force(*xl.T, prm)

        def traction(k, xl):
            return field.traction(FACES[k], *xl.T, prm)
    return solve_box(_size(prm), R, CORNER, kinds, prm.material, h, body_force=body_force, traction=traction,
                     lift=None if lift is None else (lambda xl: lift(*xl.T, prm)), order=order)


def _exact_global(field: Field, xl: np.ndarray, R: np.ndarray, prm: Parameters = PARAMETERS):
    u, grad = field(*xl.T, prm)
    return u @ R.T, np.einsum("ai,pij,bj->pab", R, isotropic_stress(grad, prm.material), R)


def _max_relative_error(solution, field: Field, R: np.ndarray, prm: Parameters = PARAMETERS, n: int = 400):
    """max |u_h - u| / max |u| and the same for sigma at random interior points (global frame)."""
    xl = np.random.default_rng(7).random((n, 3)) * _size(prm)
    u, sigma = solution.evaluate(CORNER + xl @ R.T)
    u_exact, sigma_exact = _exact_global(field, xl, R, prm)
    return (np.abs(u - u_exact).max() / np.abs(u_exact).max(),
            np.abs(sigma - sigma_exact).max() / np.abs(sigma_exact).max())


def _gauss_box(size: np.ndarray, counts, g: int) -> tuple[np.ndarray, np.ndarray]:
    """Tensor Gauss rule, g points per direction in every element: local points (m, 3), weights (m,)."""
    x, w = np.polynomial.legendre.leggauss(g)
    axes, weights = [], []
    for side, n in zip(size, counts):
        h = side / n
        axes.append(((np.arange(n)[:, None] + (x + 1) / 2) * h).ravel())
        weights.append(np.tile(w * h / 2, n))
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return points, np.einsum("a,b,c->abc", *weights).ravel()


def _norm_errors(solution, field: Field, R: np.ndarray, prm: Parameters) -> tuple[float, float]:
    """Relative L2 error of u and energy-norm error, sqrt(int (sigma_h - sigma) : C^-1 (sigma_h - sigma)),
    by a tensor Gauss rule of order + 2 points per direction over the local box."""
    xl, weight = _gauss_box(_size(prm), solution.counts, solution.order + 2)
    u, sigma = solution.evaluate(CORNER + xl @ R.T)
    u, sigma = u @ R, np.einsum("ia,pij,jb->pab", R, sigma, R)             # back to the local frame
    u_exact, grad = field(*xl.T, prm)
    sigma_exact = isotropic_stress(grad, prm.material)
    lam, mu = prm.material.lam, prm.material.mu

    def compliance(s):                                                     # C^-1 s
        trace = np.einsum("pii->p", s)
        return (s - lam / (3 * lam + 2 * mu) * trace[:, None, None] * np.eye(3)) / (2 * mu)

    du, ds = u - u_exact, sigma - sigma_exact
    l2 = np.sqrt(weight @ np.sum(du ** 2, axis=1) / (weight @ np.sum(u_exact ** 2, axis=1)))
    energy = np.sqrt(weight @ np.einsum("pij,pij->p", ds, compliance(ds))
                     / (weight @ np.einsum("pij,pij->p", sigma_exact, compliance(sigma_exact))))
    return float(l2), float(energy)


def _rate(hs, errors) -> float:
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


def test_faces_are_the_fields_faces():
    assert FACES == FIELD_FACES and np.array_equal(OUTWARD, [OUTWARD_3D[face] for face in FACES])


@pytest.mark.parametrize("R", [frame_3d(90, 0), frame_3d(30, 20), _random_frame(5)],
                         ids=["90-0", "30-20", "random"])
def test_confined_block_is_exact(R):
    """Linear u: trilinear hexahedra reproduce it (h = 30 does not divide the sides: 4 x 3 x 2 elements)."""
    solution = _solve("confined-block", R, 30.0)
    assert solution.counts == (4, 3, 2)
    err_u, err_sigma = _max_relative_error(solution, BOXES["confined-block"][0], R)
    assert err_u < 1e-10 and err_sigma < 1e-10


def test_confined_block_dofs():
    """Rollers drop one component per face node: of the 5 x 4 x 3 nodes' u_xi the two xi faces' 2 x 12
    go, of u_eta the base's 15, of u_zeta the two zeta faces' 2 x 20: 180 - 24 - 15 - 40 = 101."""
    assert _solve("confined-block", frame_3d(90, 0), 30.0).ndof == 101


def test_column_order_2_is_exact_and_order_1_converges():
    R = frame_3d(30, 20)
    field = BOXES["column"][0]
    err_u, err_sigma = _max_relative_error(_solve("column", R, 30.0, order=2), field, R)
    assert err_u < 1e-10 and err_sigma < 1e-10
    # a fixed base holds the same field (u = 0 on eta = 0): the fixed path, exact too
    fixed = ("fixed",) + BOXES["column"][1][1:]
    err_u, err_sigma = _max_relative_error(_solve("column", R, 30.0, order=2, kinds=fixed), field, R)
    assert err_u < 1e-10 and err_sigma < 1e-10
    hs = [40.0, 20.0, 10.0]
    errors = np.array([_norm_errors(_solve("column", R, h), field, R, PARAMETERS) for h in hs])
    assert _rate(hs, errors[:, 0]) > 1.9 and _rate(hs, errors[:, 1]) > 0.95
    # the solution is 1D in eta and linear elements are nodally exact there
    solution = _solve("column", R, 20.0)
    u_exact, _ = _exact_global(field, (solution.nodes - CORNER) @ R, R)
    assert np.abs(solution.nodal - u_exact).max() < 1e-10 * np.abs(u_exact).max()


def test_lift_carries_the_settlement():
    """Rollers on all six faces, the top settled by Delta = p through the quadratic lift
    u^a_eta = -p (eta / H)^2 (not the exact field -p eta / H): u^h carries a quadratic, which
    Hex2 reproduces and Hex1 does not."""
    R = frame_3d(30, 20)
    exact, lift = Field("0", "-p * eta / H", "0"), Field("0", "-p * (eta / H)**2", "0")
    err_2 = _max_relative_error(_solve(None, R, 20.0, order=2, kinds=("roller",) * 6, lift=lift), exact, R)
    err_1 = _max_relative_error(_solve(None, R, 20.0, order=1, kinds=("roller",) * 6, lift=lift), exact, R)
    assert max(err_2) < 1e-10
    assert 1e-3 < err_1[0] < 0.05


def test_manufactured_rates_order_1():
    """Smooth field at (30, 20), L = H = W = 100, h = H/4, H/8, H/16."""
    R = frame_3d(30, 20)
    field = BOXES["manufactured"][0]
    hs = [25.0, 12.5, 6.25]
    errors = np.array([_norm_errors(_solve("manufactured", R, h, prm=CUBE), field, R, CUBE) for h in hs])
    assert _rate(hs, errors[:, 0]) > 1.9 and _rate(hs, errors[:, 1]) > 0.95
    assert errors[-1, 0] < 5e-3 and errors[-1, 1] < 0.05          # measured 3.82e-3 and 4.40e-2


def test_manufactured_rates_order_2():
    R = frame_3d(30, 20)
    field = BOXES["manufactured"][0]
    hs = [50.0, 25.0, 12.5]
    errors = np.array([_norm_errors(_solve("manufactured", R, h, order=2, prm=CUBE), field, R, CUBE) for h in hs])
    assert _rate(hs, errors[:, 0]) > 2.9 and _rate(hs, errors[:, 1]) > 1.9
    assert errors[-1, 0] < 6e-4 and errors[-1, 1] < 5e-3          # measured 4.99e-4 and 4.42e-3


@pytest.mark.parametrize("order", [1, 2])
def test_evaluation_equals_scikit_fem(order):
    """The lattice evaluation (tensor shape functions) equals scikit-fem's interpolation of the same
    DOF vector at its quadrature points, values and gradients."""
    R = _random_frame(2)
    solution = _solve("manufactured", R, 30.0, order=order)
    size = _size(PARAMETERS)
    mesh = MeshHex.init_tensor(*(np.linspace(0, s, n + 1) for s, n in zip(size, solution.counts)))
    basis = Basis(mesh, ElementVector(ElementHex1() if order == 1 else ElementHex2()), intorder=3)
    component = np.empty(basis.N, dtype=int)
    for c, dofs in enumerate(basis.split_indices()):
        component[dofs] = c
    at = np.rint(basis.doflocs.T * (order * np.array(solution.counts) / size)).astype(int)
    U = solution.values[at[:, 0], at[:, 1], at[:, 2], component]
    field = basis.interpolate(U)
    points = np.asarray(basis.global_coordinates()).reshape(3, -1).T
    u, grad = solution.local_fields(points)
    assert np.abs(u - np.asarray(field).reshape(3, -1).T).max() < 1e-12 * np.abs(u).max()
    assert np.abs(grad - np.moveaxis(np.asarray(field.grad).reshape(3, 3, -1), 2, 0)).max() < 1e-12 * np.abs(grad).max()


@pytest.mark.parametrize("element, n", [(ElementHex1(), 3), (ElementHex2(), 2)])
def test_uniform_stiffness_equals_scikit_fem_assembly(element, n):
    """One element's matrix scattered to all equals asm over every element (sides 100 x 80 x 60)."""
    mesh = MeshHex.init_tensor(np.linspace(0, 100, n + 1), np.linspace(0, 80, n + 2), np.linspace(0, 60, n))
    basis = Basis(mesh, ElementVector(element), intorder=5)
    K = _stiffness(basis, 5, MATERIAL.lam, MATERIAL.mu)
    K_skfem = asm(linear_elasticity(MATERIAL.lam, MATERIAL.mu), basis)
    assert abs(K - K_skfem).max() < 1e-13 * abs(K_skfem).max()


@pytest.mark.parametrize("change, message", [
    ({"size": (100.0, 0.0, 60.0)}, "box sides must be three positive numbers, got 100.0 x 0.0 x 60.0"),
    ({"size": (100.0, 80.0)}, "box sides must be three positive numbers, got 100.0 x 80.0"),
    ({"kinds": ("roller", "roller", "traction", "roller", "roller", "glued")},
     "face 5 (back): kind 'glued' is not one of roller, fixed, traction, free"),
    ({"kinds": ("roller",) * 4}, "a box has 6 faces (base, right, top, left, front, back) but 4 kinds were given"),
    ({"frame": np.diag([1.0, 1.0, 1.1])}, r"the frame is not orthonormal: max |R^T R - I| = 0.21"),
    ({"frame": np.eye(2)}, r"the frame must be a finite (3, 3) matrix, got shape (2, 2)"),
    ({"h": -1.0}, "cell size h=-1.0 is not allowed; it must be > 0"),
    ({"order": 3}, "order=3 is not allowed; it must be 1 (Hex1) or 2 (Hex2)"),
    ({"traction": None}, "face 2 (top) is of kind traction but no traction was given"),
])
def test_bad_input(change, message):
    arguments = dict(size=_size(PARAMETERS), frame=np.eye(3), corner=CORNER, kinds=BOXES["confined-block"][1],
                     material=MATERIAL, h=30.0, traction=lambda k, xl: np.zeros_like(xl), order=1)
    arguments.update(change)
    with pytest.raises(InputError) as raised:
        solve_box(**arguments)
    assert str(raised.value).startswith(message) and "\n" not in str(raised.value)
