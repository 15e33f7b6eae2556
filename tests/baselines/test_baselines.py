"""Baselines: scikit-fem bridge, patch tests, parameter rates, multiplier tractions, failures."""
from __future__ import annotations

import json

import numpy as np
import scipy.sparse as sp
import pytest
import scipy.sparse.linalg as spla

from baselines import boundary
from baselines.lagrange import solve_lagrange
from baselines.lagrange_nodal import solve_lagrange_nodal
from baselines.limit import limit_stiffness
from baselines.registry import METHODS
from ibm import dirichlet
from ibm.small import forms
from ibm.quadrature.bands import band_quadrature
from ibm.geometry.outline import rectangle
from ibm.models.elastic import Elastic
from ibm.small.model import Loads, build_model
from ibm.exceptions import SolveError
from studies.run.case import CaseSpec, instance_of, run_case
from studies.cli import main

MATERIAL = Elastic(1e4, 0.3)
BASELINES = ["ibm-limit", "penalty", "nitsche", "lagrange", "lagrange-nodal", "fem"]


def confined(angle: float, offset=(0.37, 0.29)):
    spec = CaseSpec(angle=angle, offset=offset)
    instance = instance_of(spec)
    return instance, build_model(instance.body, instance.parameters.material, instance.loads, spec.cell, spec.ppc)


def slope(x, y) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


# --- the scikit-fem bridge -------------------------------------------------------------------

def test_every_method_is_registered():
    assert set(BASELINES + ["ibm"]) <= set(METHODS)


def test_skfem_grid_numbering_matches_ibm_grid():
    _, model = confined(30.0)
    grid = model.grid
    space = boundary.grid_space(grid)
    cells = np.arange(grid.n_cells)
    full = boundary.point_basis(space.mesh, space.element, grid.cell_corners(cells) + 0.3 * grid.h, cells)
    assert np.array_equal(full.element_dofs.T, grid.cell_dofs(cells))
    rng = np.random.default_rng(1)
    x = model.points.x + rng.uniform(-1, 1, model.points.x.shape)
    cells = grid.locate(x)
    Nv, dofs = boundary.trace_operator(model, x, cells)
    N, dN = grid.shape_functions(x, cells)
    assert np.array_equal(dofs, grid.cell_dofs(cells))
    assert np.allclose(Nv[:, 0, 0::2], N, atol=1e-14) and np.allclose(Nv[:, 1, 1::2], N, atol=1e-14)
    assert np.all(Nv[:, 0, 1::2] == 0) and np.all(Nv[:, 1, 0::2] == 0)
    U = rng.normal(size=2 * grid.n_nodes)
    u, grad = boundary.values_at(boundary.point_basis(space.mesh, space.element, x, cells), U)
    ue = U[grid.cell_dofs(cells)]
    assert np.allclose(u, np.stack([np.sum(N * ue[:, 0::2], 1), np.sum(N * ue[:, 1::2], 1)], 1), atol=1e-13)
    assert np.allclose(grad[:, 0], np.einsum("pI,pIj->pj", ue[:, 0::2], dN), atol=1e-13)


def test_boundary_weights_integrate_edge_lengths():
    _, model = confined(30.0)
    for edge in boundary.essential_edge_points(model):
        basis = boundary.edge_basis(model, edge)
        assert np.isclose(basis.dx.sum(), model.body.lengths[edge.edge], rtol=1e-13)


# --- patch tests: consistent methods reproduce the linear solution ------------------------------

@pytest.mark.parametrize("method", ["nitsche", "lagrange", "fem"])
@pytest.mark.parametrize("angle", [30.0, 45.0])
def test_consistent_methods_pass_the_patch_test(method, angle):
    record = run_case(CaseSpec(method=method, angle=angle))
    assert record["err_u"] <= 1e-10 and record["err_sigma"] <= 1e-10
    if method == "lagrange":
        assert record["err_traction"] <= 1e-10 and record["n_multipliers"] > 0


def settlement_case(angle: float):
    """Non-homogeneous rollers: u = (a xi + c - w eta, b eta + d + w xi) in the local frame (no shear
    stress, so rollers hold), with a lift that differs from u by k eta e_eta (n.lift = n.u on rollers)."""
    a, b, c, d, w, k = 2e-4, -5e-4, 0.01, -0.02, 1e-4, 3e-4
    body = rectangle(100, 100, ("roller", "roller", "traction", "roller"), angle, np.array([3.7, 2.9]))
    R, origin = body.frame, body.vertices[0]
    G_loc = np.array([[a, -w], [w, b]])
    G = R @ G_loc @ R.T
    sigma = 2 * MATERIAL.mu * 0.5 * (G + G.T) + MATERIAL.lam * np.trace(G) * np.eye(2)

    def exact_u(x):
        xl = (x - origin) @ R
        return (xl @ G_loc.T + np.array([c, d])) @ R.T

    def lift(x):
        eta = (x - origin) @ R[:, 1]
        u = exact_u(x) + k * eta[:, None] * R[:, 1][None]
        return u, np.broadcast_to(G + k * np.outer(R[:, 1], R[:, 1]), (len(x), 2, 2))

    top = -body.normals[2]
    loads = Loads(tractions={2: lambda x: np.broadcast_to(sigma @ top, (len(x), 2))}, lift=lift)
    return build_model(body, MATERIAL, loads, 10.0, 1), exact_u, sigma


@pytest.mark.parametrize("method", ["nitsche", "lagrange", "fem", "ibm-limit", "penalty", "ibm"])
def test_non_homogeneous_roller_data_from_the_lift(method):
    model, exact_u, sigma = settlement_case(30.0)
    solution = METHODS[method](model)
    u = exact_u(model.points.x)
    err_u = np.linalg.norm(solution.u - u) / np.linalg.norm(u)
    err_s = np.abs(solution.sigma - sigma).max() / np.abs(sigma).max()
    tolerance = 1e-10 if method in ("nitsche", "lagrange", "fem") else 1e-5
    assert err_u <= tolerance and err_s <= tolerance


# --- rates in the method parameters ---------------------------------------------------------------

def test_penalty_error_falls_as_one_over_beta0():
    _, model = confined(30.0)
    instance, _ = confined(30.0)
    u = instance.exact(model.points.x)[0]
    betas = np.array([1e2, 1e3, 1e4, 1e5])
    errors = [np.linalg.norm(METHODS["penalty"](model, beta0=b).u - u) / np.linalg.norm(u) for b in betas]
    assert abs(slope(betas, errors) + 1) <= 0.15


@pytest.mark.parametrize("method", ["ibm", "ibm-limit"])
def test_ibm_errors_fall_linearly_in_delta(method):
    instance, model = confined(45.0)
    u = instance.exact(model.points.x)[0]
    deltas = np.array([1e-3, 1e-4, 1e-5, 1e-6])
    errors = [np.linalg.norm(METHODS[method](model, delta_rel=d).u - u) / np.linalg.norm(u) for d in deltas]
    assert abs(slope(deltas, errors) - 1) <= 0.15


def band_to_limit_gaps(model, deltas=np.array([1e-1, 1e-2, 1e-3])):
    """deltas and ||K_band(delta) - K_limit(delta)|| / ||K_points||: the band form against its limit form."""
    body, bulk = model.body, boundary.bulk_system(model)
    K0 = forms.stiffness(model, model.points.quadrature())
    gaps = []
    for delta in deltas:
        band = band_quadrature(body, model.grid, delta)
        K_band = K0 + forms.stiffness(model, band, lambda x: dirichlet.matrix(body, x, delta)) \
            - forms.stiffness(model, band)
        gaps.append(spla.norm(K_band - limit_stiffness(model, bulk, delta)) / spla.norm(K0))
    return deltas, np.array(gaps)


@pytest.mark.parametrize("kinds", [("roller", "roller", "traction", "roller"),
                                   ("fixed", "roller", "traction", "roller"),
                                   ("fixed", "fixed", "traction", "fixed")])
def test_limit_form_is_the_limit_of_the_band_stiffness(kinds):
    """||K_band(delta) - K_limit(delta)|| / ||K|| falls linearly: every O(1) term is in the limit form
    (the shorter form without the corner terms keeps an O(1) difference, ~1e-2 here)."""
    body = rectangle(100, 100, kinds, 30.0, np.array([3.7, 2.9]))
    deltas, gaps = band_to_limit_gaps(build_model(body, MATERIAL, Loads(), 10.0, 1))
    assert gaps[-1] < 1e-4 and abs(slope(deltas, gaps) - 1) <= 0.15


# --- multipliers ---------------------------------------------------------------------------------

@pytest.mark.parametrize("angle", [90.0, 45.0, 30.0])
def test_nodal_multipliers_oscillate_and_piecewise_constants_do_not(angle):
    instance, model = confined(angle)
    stable, naive = solve_lagrange(model), solve_lagrange_nodal(model)
    assert stable.info["traction_variation"] <= 1e-8
    assert naive.info["traction_variation"] >= 1.0          # O(1) jumps of the traction along an edge
    record = run_case(CaseSpec(method="lagrange-nodal", angle=angle))
    assert record["err_traction"] >= 1e-2 and record["err_u"] >= 1e-3


def test_nodes_sharing_one_lonely_point_are_tied_so_even_unaugmented_lagrange_is_exact():
    # at 45 degrees two corner nodes see only the one point of their cell: a zero-energy mode the
    # piecewise-constant multipliers cannot see (this system was singular, condition ~1e17)
    instance, model = confined(45.0)
    solution = solve_lagrange(model, augment=0.0)
    u = instance.exact(model.points.x)[0]
    assert solution.info["n_extended"] == 2 and solution.info["cond_est"] < 1e7
    assert np.abs(solution.u - u).max() < 1e-12 * np.abs(u).max()


# --- failures are reported, never printed as numbers -------------------------------------------------

def test_nitsche_with_too_small_gamma_is_refused():
    _, model = confined(30.0)
    with pytest.raises(SolveError, match=r"gamma=1\b"):
        METHODS["nitsche"](model, gamma=1.0)


def test_nitsche_definiteness_check_counts_negative_eigenvalues():
    """What a refused Nitsche matrix is told by (the solve's Cholesky refused it): SuperLU's
    symmetric pivots count the negative eigenvalues of a dense 40 x 40 matrix."""
    from baselines.nitsche import negative_pivots
    rng = np.random.default_rng(3)
    Q, _ = np.linalg.qr(rng.standard_normal((40, 40)))
    eigenvalues = np.linspace(1.0, 10.0, 40)
    assert negative_pivots(sp.csr_matrix(Q @ np.diag(eigenvalues) @ Q.T)) == 0
    eigenvalues[:3] *= -1
    assert negative_pivots(sp.csr_matrix(Q @ np.diag(eigenvalues) @ Q.T)) == 3


def test_nitsche_refusal_through_the_cli(capsys):
    assert main(["solve", "--method", "nitsche", "--gamma", "1", "--angle", "30"]) == 3
    assert "gamma=1" in capsys.readouterr().err


@pytest.mark.parametrize("method", BASELINES)
def test_cli_solves_with_every_method(method, capsys):
    assert main(["solve", "--method", method, "--angle", "45", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["method"] == method and record["cond_est"] > 1 and record["time_s"] > 0
    assert ("n_multipliers" in record) == method.startswith("lagrange")


def test_cli_rejects_a_parameter_the_method_does_not_take(capsys):
    assert main(["solve", "--method", "fem", "--gamma", "10"]) == 2
    assert "gamma" in capsys.readouterr().err


# --- placements within rounding of grid lines -------------------------------------------------------

@pytest.mark.parametrize("method", ["lagrange", "nitsche", "penalty", "ibm-limit", "fem"])
@pytest.mark.parametrize("angle,offset", [(5.960464477539063e-08, (0.0, 0.0)), (1e-7, (1e-6, 0.5))])
def test_edges_within_rounding_of_grid_lines(method, angle, offset):
    """Points a rounding error outside their cell once stalled scikit-fem's Newton inverse map,
    and an inward nudge of 1e-9 h once put edge points in the wrong cell."""
    record = run_case(CaseSpec(method=method, angle=angle, offset=offset))
    limit = 1e-10 if method in ("lagrange", "nitsche", "fem") else 3e-7
    assert record["err_u"] <= limit and record["err_sigma"] <= max(limit, 1e-6)


@pytest.mark.parametrize("poke", [3.2e-10, 1e-8, 1e-6])
def test_short_multiplier_pieces_are_merged(poke):
    """The base pokes poke*h past a grid line: its own multiplier piece would make the saddle
    system's condition grow as 1 / poke (6e13 at 3.2e-10, refused); merged, it stays ~1e5."""
    record = run_case(CaseSpec(method="lagrange", angle=0.0, offset=(0.0, poke)))
    assert record["cond_est"] < 1e7 and record["err_u"] < 1e-12 and record["err_traction"] < 1e-12
