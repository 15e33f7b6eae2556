"""Collapse at small strain: the mean dilatation (B-bar) and Hill's thick cylinder."""
import numpy as np
import pytest

from ibm.discretise.basis import point_basis
from ibm.discretise.grid import Grid
from ibm.large.kinematics import gradient_operator
from ibm.discretise.locking import cell_means, divergence, in_cell_order, mean_dilatation
from studies.problems.collapse import Hill, run_hill


def test_hill_solution_data():
    """de Souza Neto's data: p_lim = 2 k ln(b / a) = 192.09, first yield k (1 - a^2 / b^2); the curve
    starts elastic and ends at p_lim."""
    hill = Hill()
    assert hill.p_lim == pytest.approx(192.0906, abs=1e-4)
    assert hill.p_yield == pytest.approx(240 / np.sqrt(3) * 0.75, rel=1e-14)
    u, p = hill.curve()
    assert p[1] == pytest.approx(hill.p_yield) and p[-1] == pytest.approx(hill.p_lim) and np.all(np.diff(u) > 0)


def _cut_cell_points(seed=0):
    grid = Grid(h=10.0, lower=(0, 0), shape=(4, 4))
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.5, 39.5, (60, 2))
    volume = rng.uniform(1.0, 25.0, 60)          # cut cells: unequal volumes
    return grid, x, volume, point_basis("mpm", grid, x, None)


def test_mean_dilatation_keeps_linear_fields_and_the_patch_test():
    grid, x, volume, basis = _cut_cell_points()
    G = gradient_operator(basis.S, basis.dS)
    cells = grid.locate(x)
    cell_nodes = grid.cell_nodes(cells)
    rows = in_cell_order(divergence(G), basis.nodes, cell_nodes)
    means = cell_means(cells, volume, rows, cells, volume)
    mean = means["mean"][np.searchsorted(means["cells"], cells)]
    bar = mean_dilatation(G, basis.nodes, cell_nodes, mean)
    A = np.array([[0.3, -0.1], [0.2, 0.5]])
    U = (grid.nodes() @ A.T).ravel()
    assert np.abs(np.einsum("pij,pj->pi", bar - G, U[basis.dofs])).max() < 1e-15   # linear: unchanged
    # a uniform stress stays in equilibrium: sum_p V_p (Gbar - G)^T sigma = 0 node by node
    sigma = np.array([3.0, 1.0, 1.0, -2.0])                                        # (xx, xy, yx, yy)
    force = np.bincount(basis.dofs.ravel(), (np.einsum("pij,i->pj", bar - G, sigma) * volume[:, None]).ravel(),
                        minlength=2 * grid.n_nodes)
    assert np.abs(force).max() < 1e-12
    # and each point's dilatation is its cell's mean
    field = np.random.default_rng(1).normal(size=U.size)
    theta = np.einsum("pj,pj->p", divergence(bar), field[basis.dofs])
    for c in np.unique(cells):
        assert np.ptp(theta[cells == c]) < 1e-12


@pytest.mark.parametrize("method", ["lagrange", "nitsche", "penalty", "ibm"])
def test_hill_cylinder_collapses_at_the_limit_pressure_with_b_bar_and_locks_without(method):
    """Inclined (30 degrees), h = 10 (ten cells across the wall), 2 x 2 points, the pressure ramped to
    1.05 p_lim in 20 steps: with B-bar the last converged pressure is 0.9975 p_lim (every method, the
    IBM too; the next ones fail as the mechanism forms); without it every point's own volumetric
    constraint locks the ring and 1.05 p_lim is carried (measured for all four)."""
    remedied = run_hill(method, angle=30.0, cell=10.0, steps=20, basis="mpm", locking="fbar")
    assert abs(remedied["p_over_p_lim"] - 1) <= 0.01 and remedied["stopped"]
    locked = run_hill(method, angle=30.0, cell=10.0, steps=20, basis="mpm", locking="none")
    assert locked["p_over_p_lim"] >= 1.04 and locked["stopped"] is None


def test_b_bar_is_refused_where_it_does_not_apply():
    from ibm.exceptions import InputError
    with pytest.raises(InputError, match="locking 'fbar' needs basis 'mpm'"):
        run_hill("lagrange", steps=2, basis="gimp", locking="fbar")
    with pytest.raises(InputError, match="locking 'bar' is not allowed; allowed: none, fbar"):
        run_hill("lagrange", steps=2, basis="mpm", locking="bar")


def test_hill_cylinder_from_the_command_line(capsys):
    import json

    from studies.cli import main
    code = main(["solve", "--problem", "hill-cylinder", "--method", "penalty", "--angle", "30", "--steps", "20",
                 "--ppc", "2", "--basis", "mpm", "--locking", "fbar", "--json"])
    record = json.loads(capsys.readouterr().out)
    assert code == 0 and record["locking"] == "fbar" and record["p_lim"] == pytest.approx(192.0906, abs=1e-4)
    assert abs(record["p_final"] / record["p_lim"] - 1) <= 0.01
    assert len(record["curve_p"]) == len(record["curve_u"]) == len(record["newton_iterations"]) >= 15
    assert record["hill_p"][-1] == pytest.approx(record["p_lim"])


@pytest.mark.parametrize("arguments,message", [
    (["--E", "2e5"], "problem 'hill-cylinder' has its own material, geometry and load"),
    (["--steps", "3"], "steps 3 is not allowed for 'hill-cylinder'; it must be >= 5"),
    (["--steps", "20"], "ppc 1 is not allowed for 'hill-cylinder'; it must be >= 2"),
    (["--steps", "20", "--ppc", "2", "--method", "nodal"], "method 'nodal' refuses essential arcs"),
    (["--steps", "20", "--ppc", "2", "--locking", "fbar", "--method", "lagrange"], "locking 'fbar' needs --basis mpm"),
    (["--steps", "20", "--ppc", "2", "--locking", "full"], "locking 'full' is not allowed; allowed: none, fbar"),
    (["--steps", "20", "--method", "fem", "--locking", "fbar", "--basis", "mpm"],
     "locking is for the grid methods; fem's P2 triangles"),
    (["--kinematics", "large", "--steps", "20", "--method", "fem"],
     "kinematics 'large' is not available for 'hill-cylinder' with 'fem'; it is for the footing with the grid"),
])
def test_bad_collapse_options_are_one_line(arguments, message, capsys):
    from studies.cli import main
    assert main(["solve", "--problem", "hill-cylinder"] + arguments) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_locking_fbar_elsewhere_is_one_line(capsys):
    from studies.cli import main
    assert main(["solve", "--locking", "fbar", "--basis", "mpm"]) == 2
    assert "locking 'fbar' (B-bar at small strain, F-bar at large) is for yielding bodies" in capsys.readouterr().err
