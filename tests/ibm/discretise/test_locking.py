"""F-bar at large strain (ibm.discretise.locking, ibm.large.equilibrium.evaluate).

The tangent. Per point the internal force is f = V J Gc^T sigma(dF_bar), with dF_bar = alpha dF
in the plane, alpha = (J_c / J)^(1/d), J_c = sum_q V_q J_q / sum_q V_q over the cell. Write it
as V (J / J_c) tau_bar : Gc (tau_bar = J_c sigma the Kirchhoff stress of dF_bar) and vary the
nodal values, l = delta dF dF^-1 = Gc delta u:
    delta(J / J_c) = (J / J_c) (tr l - tr l_c),   tr l_c = sum_q V_q J_q tr l_q / sum_q V_q J_q,
    delta dF_bar dF_bar^-1 = l + (tr l_c - tr l) I / d = l_bar,
    delta (Gc^T) at fixed stress gives -Gc^T (tau l^T) as without F-bar,
and the model's spatial tangent a satisfies J_c a : l_bar = delta tau_bar - tau_bar l_bar^T. The
geometric terms leave Gc^T tau_bar (l_bar - l)^T = Gc^T tau_bar (tr l_c - tr l) / d; summed,
    delta f = V J Gc^T [a : l + ((a : I - (d - 1) sigma) / d) (tr l_c - tr l)],
the form in ibm.discretise.locking (de Souza Neto et al.'s q = a : I / 3 - 2 sigma / 3 in 3D; in plane strain,
with the in-plane dF scaled, (a : I - sigma) / 2). Earlier the code had (a : I - sigma) / d, right
in 2D only: the 3D finite differences below caught it (0.4 % off with Hencky).
"""
import numpy as np
import pytest

from ibm.discretise.basis import mpm_basis
from ibm.large.equilibrium import PointSet, evaluate
from ibm.discretise.grid import Grid
from ibm.large.kinematics import gradient_operator
from ibm.discretise.locking import CellGroups
from ibm.models.plasticity import HenckyJ2


def _set(model, state, with_fbar=True, dim=2):
    """Three cells of a 3 x 1 (x 1) grid, 2^d points each (the standard basis: a point's nodes are its cell's)."""
    grid = Grid(1.0, (0,) * dim, (3,) + (1,) * (dim - 1))
    offsets = 0.25 + 0.5 * grid.local_nodes
    x = np.concatenate([offsets + np.eye(dim)[0] * c for c in range(3)])
    basis = mpm_basis(grid, x)
    cells = grid.locate(x)
    groups = CellGroups(cells, basis.nodes, grid.cell_nodes(cells)) if with_fbar else None
    G = gradient_operator(basis.S, basis.dS)
    volume = np.full(len(x), 0.5 ** dim) * (1 + 0.1 * np.arange(len(x)) / len(x))
    return PointSet(basis.dofs, G, volume, state, fbar=groups), dim * grid.n_nodes


@pytest.mark.parametrize("hardening, dim", [(0.0, 2), (400.0, 2), (400.0, 3)])
def test_fbar_tangent_matches_finite_differences_in_plastic_states(hardening, dim):
    rng = np.random.default_rng(3)
    model = HenckyJ2(1e4, 0.3, yield_stress=20.0, hardening=hardening)
    n_points = 3 * 2 ** dim
    points, n = _set(model, model.initial(n_points), dim=dim)
    dU = 0.02 * rng.standard_normal(n)
    start = evaluate(model, [points], dU)
    # a plastic state at the step start, then a plastic trial from it
    points, _ = _set(model, start.responses[0].state, dim=dim)
    dU = 0.01 * rng.standard_normal(n)
    result = evaluate(model, [points], dU)
    assert np.all(result.responses[0].state.internal["alpha"] > points.state.internal["alpha"])
    K = result.tangent(n).toarray()
    eps, worst = 1e-7, 0.0
    for j in range(n):
        e = np.zeros(n)
        e[j] = eps
        column = (evaluate(model, [points], dU + e).force - evaluate(model, [points], dU - e).force) / (2 * eps)
        worst = max(worst, np.abs(column - K[:, j]).max())
    assert worst <= 1e-6 * np.abs(K).max()
    assert np.abs(K - K.T).max() > 1e-3 * np.abs(K).max()        # the F-bar tangent is not symmetric
    J = np.linalg.det(result.responses[0].state.F)               # each cell's points share its mean J
    assert max(np.ptp(J[c * 2 ** dim:(c + 1) * 2 ** dim]) for c in range(3)) <= 1e-12 < np.ptp(J)


def test_fbar_changes_nothing_for_a_uniform_jacobian_and_gives_each_cell_its_mean():
    rng = np.random.default_rng(5)
    model = HenckyJ2(1e4, 0.3, yield_stress=20.0)
    points, n = _set(model, model.initial(12))
    plain, _ = _set(model, model.initial(12), with_fbar=False)
    # a homogeneous increment (a linear nodal field, past yield): every point has the same J
    gradient = np.array([[-0.05, 0.02], [0.01, 0.03]])
    U = (Grid(1.0, (0, 0), (3, 1)).nodes() @ gradient.T).ravel()
    a, b = evaluate(model, [points], U), evaluate(model, [plain], U)
    assert np.all(b.responses[0].state.internal["alpha"] > 0)
    assert np.abs(a.force - b.force).max() <= 1e-12 * np.abs(b.force).max()
    # a random one: the stressed deformation of each cell's points has their mean Jacobian
    result = evaluate(model, [points], 0.02 * rng.standard_normal(n))
    J = np.linalg.det(result.responses[0].state.F[:, :2, :2])
    for cell in range(3):
        assert np.ptp(J[4 * cell:4 * cell + 4]) <= 1e-12 and np.ptp(J) > 1e-3


def _order(residuals) -> float:
    """The observed order of the last three Newton residuals above round-off."""
    r = [x for x in residuals if x > 1e-12][-3:]
    return np.log(r[2] / r[1]) / np.log(r[1] / r[0])


@pytest.mark.parametrize("kinematics", ["small", "large"])
def test_newton_converges_quadratically_in_plastic_steps_with_the_mean_dilatation(kinematics):
    """The footing settled past collapse (B/h = 8, lagrange, 10 steps): the last Newton residuals
    above round-off fall at a median order of 2.1 with B-bar (small strain) and 2.4 with F-bar's
    unsymmetric tangent (large); the step where the mechanism forms, the active set still
    changing, at 1.24. With q's sign flipped the F-bar orders are 0.6-0.9."""
    from baselines.registry import treatment
    from ibm.large.loadsteps import Loading, Setup, run
    from ibm.models.small_strain import VonMises
    from studies.problems.footing import edge_corner, footing_body
    h, B, H = 1 / 8, 1.0, 2.0
    body, _ = footing_body(3.0, H, B, 90.0, edge_corner(90.0, (0.0, 0.0), h, B, H))
    motion = np.zeros(len(body.essential_edges))
    motion[body.essential_edges.index(3)] = 0.02
    model = (VonMises if kinematics == "small" else HenckyJ2)(1e5, 0.3, yield_stress=100.0)
    progress = run(Setup(body, model, Loading(wall_motion=motion), h, 2, "mpm", 10, locking="fbar"),
                   treatment("lagrange", {}))
    assert np.all(progress.state.internal["alpha"].max() > 0)
    orders = [_order(step["residuals"]) for step in progress.steps[2:] if len(step["residuals"]) >= 4]
    assert len(orders) == 8 and np.median(orders) >= 1.8 and sum(o >= 1.7 for o in orders) >= 6, orders
