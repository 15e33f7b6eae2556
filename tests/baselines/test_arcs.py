"""Weak baselines on essential arcs: per-point normals, arc pieces, rates on lame-dirichlet, the
limit form's curvature terms, and the refusals of the methods that cannot hold an arc."""
import numpy as np
import pytest
from skfem.assembly.form.form import FormExtraParams
from skfem.element import DiscreteField

from baselines import limit
from baselines.boundary import essential_edge_points
from baselines.registry import METHODS
from ibm import dirichlet
from ibm.geometry.arcs import Arc
from ibm.geometry.outline import Body
from ibm.exceptions import InputError
from ibm.models.elastic import Elastic
from ibm.small.model import Loads, build_model
from studies.run.case import CaseSpec, instance_of
from studies.run.convergence import converge

A, B = 50.0, 100.0
MATERIAL = Elastic(1e4, 0.3)


def lame_dirichlet(cell: float):
    spec = CaseSpec(problem="lame-dirichlet", angle=30.0, cell=cell, load_type="settlement")
    instance = instance_of(spec)
    return instance, build_model(instance.body, instance.parameters.material, instance.loads, cell, spec.ppc)


def test_edge_points_carry_radial_normals_on_arcs_and_pieces_in_one_cell():
    instance, model = lame_dirichlet(5.0)
    body = instance.body
    for edge in essential_edge_points(model):
        x, cells, piece = edge.points.x, edge.points.cells, edge.piece
        assert edge.normal.shape == (len(x), 2)
        assert np.abs(np.linalg.norm(edge.normal, axis=1) - 1).max() < 1e-15
        arc = body.arcs[edge.edge]
        if arc is None:
            assert np.array_equal(edge.normal, np.broadcast_to(-body.normals[edge.edge], x.shape))
            assert np.array_equal(piece, np.arange(len(x)) // 4)
        else:
            radial = (x - arc.center) / np.linalg.norm(x - arc.center, axis=1)[:, None]
            assert np.abs(edge.normal - (-radial if arc.clockwise else radial)).max() < 1e-15
        # a piece is the edge's part inside one cell: one cell per piece, a new cell at each new piece
        first = np.flatnonzero(np.diff(piece)) + 1
        assert np.all(np.diff(piece) >= 0) and np.all(cells[first] != cells[first - 1])
        assert all(len(np.unique(cells[piece == p])) == 1 for p in range(piece.max() + 1))


# (method, parameters, delta law): penalty and ibm-limit at their documented laws (studies.run.convergence);
# at their stiff defaults they lock on the arcs and inclined rollers (L2 rates 1.38 and 1.75 here)
CONVERGING = [("penalty", {"beta0": 1e3}, None), ("nitsche", {}, None), ("lagrange", {}, None),
              ("ibm-limit", {}, "0.01*h")]


@pytest.mark.parametrize("method,parameters,law", CONVERGING)
def test_weak_methods_converge_on_essential_arcs(method, parameters, law):
    """h = 10, 5, 2.5 at 30 degrees, ppc 1. Measured fits (L2, energy): penalty 2.15, 1.04; nitsche
    2.15, 1.04; lagrange 2.06, 1.04; ibm-limit 2.04, 1.03. Gates: 1.9 and 0.95."""
    result = converge(CaseSpec(problem="lame-dirichlet", method=method, angle=30.0, load_type="settlement",
                               method_parameters=parameters), 3, law, coarse=10.0)
    assert result["rates"]["err_l2"] >= 1.9
    assert result["rates"]["err_energy"] >= 0.95
    assert result["levels"][-1]["err_l2"] < 1e-3


def _quadratic(c: np.ndarray, x: np.ndarray):
    """Field (n, 2) and gradient (n, 2, 2) of u_i = c_ik m_k(x / 100), m = 1, x, y, x^2, xy, y^2."""
    X, Y = x[:, 0] / 100, x[:, 1] / 100
    one, zero = np.ones_like(X), np.zeros_like(X)
    m = np.stack([one, X, Y, X * X, X * Y, Y * Y], 1)
    dm = np.stack([np.stack([zero, one, zero, 2 * X, Y, zero], 1),
                   np.stack([zero, zero, one, zero, X, 2 * Y], 1)], 2) / 100         # (n, 6, 2)
    return m @ c.T, np.einsum("ik,nkj->nij", c, dm)


def _energy(G1: np.ndarray, G2: np.ndarray) -> np.ndarray:
    e1, e2 = (G1 + G1.transpose(0, 2, 1)) / 2, (G2 + G2.transpose(0, 2, 1)) / 2
    lam, mu = MATERIAL.lam, MATERIAL.mu
    return 2 * mu * np.einsum("nij,nij->n", e1, e2) + lam * np.trace(e1, axis1=1, axis2=2) * np.trace(e2, axis1=1, axis2=2)


def _skfem(u: np.ndarray, G: np.ndarray) -> DiscreteField:
    return DiscreteField(u.T[:, :, None], np.moveaxis(G, 0, 2)[:, :, :, None])


def band_minus_limit(piece: int, kind: str, delta: float) -> float:
    """(band energy - limit form) / |int T| for smooth quadratic u, v and one essential arc (the other
    pieces free, so the band is the annular sector beside the arc), in polar Gauss quadrature."""
    kinds = ["free"] * 4
    kinds[piece] = kind
    body = Body(np.array([[A, 0], [B, 0], [0, B], [0, A]]), tuple(kinds),
                arcs=(None, Arc(np.zeros(2)), None, Arc(np.zeros(2), clockwise=True)))
    R = B if piece == 1 else A
    lo = R - delta if piece == 1 else R
    cu, cv = np.random.default_rng(0).normal(size=(2, 2, 6))
    gr, wr = np.polynomial.legendre.leggauss(20)
    gt, wt = np.polynomial.legendre.leggauss(60)
    rho, theta = lo + delta * (gr + 1) / 2, np.pi / 4 * (gt + 1)
    weight = (np.outer(wr * delta / 2, wt * np.pi / 4) * rho[:, None]).ravel()
    x = (rho[:, None, None] * np.stack([np.cos(theta), np.sin(theta)], 1)[None]).reshape(-1, 2)
    D, dD = dirichlet.matrix(body, x, delta)

    def gradients(c):   # grad(D u) and grad u
        u, G = _quadratic(c, x)
        return np.einsum("piaj,pa->pij", dD, u) + np.einsum("pia,paj->pij", D, G), G

    (Gu, G0u), (Gv, G0v) = gradients(cu), gradients(cv)
    band = np.sum(weight * (_energy(Gu, Gv) - _energy(G0u, G0v)))
    xs = R * np.stack([np.cos(theta), np.sin(theta)], 1)
    n = body.outward(piece, xs).T[:, :, None]
    w = FormExtraParams({"n": DiscreteField(n), "t": DiscreteField(np.stack([-n[1], n[0]]))})
    u, v = _skfem(*_quadratic(cu, xs)), _skfem(*_quadratic(cv, xs))
    lam, mu, ds = MATERIAL.lam, MATERIAL.mu, wt * np.pi / 4 * R

    def line(form, a, b):
        return np.sum(ds * np.asarray(form.form(a, b, w))[:, 0])

    T = limit.consistency_term(kind, lam, mu)
    limit_value = (4 / (3 * delta) * line(limit.penalty_density(kind, lam, mu), u, v) - line(T, u, v) - line(T, v, u)
                   + limit.curvature(body, piece) * line(limit.curvature_term(kind, lam, mu), u, v))
    return (band - limit_value) / abs(line(T, u, v))


@pytest.mark.parametrize("piece", [1, 3], ids=["convex", "hole"])
@pytest.mark.parametrize("kind", ["roller", "fixed"])
def test_limit_form_is_the_limit_of_the_band_energy_on_an_arc(piece, kind):
    """O(delta) apart (~1e-3 of int T at delta = 0.1 for R = 50, 100); without the curvature terms the
    gap stays O(1) (0.15 - 3 of int T). (Below delta ~ 1e-3 phi = R - rho loses digits to rounding.)"""
    gaps = [band_minus_limit(piece, kind, delta) for delta in (1.0, 0.1, 0.01)]
    assert abs(gaps[1]) < 5e-3 and abs(gaps[2]) < 5e-4
    assert 9 < abs(gaps[0] / gaps[1]) < 11 and 9 < abs(gaps[1] / gaps[2]) < 11


@pytest.mark.parametrize("method", ["nodal", "lagrange-nodal"])
def test_methods_that_cannot_hold_an_arc_refuse_it_in_one_line(method):
    _, model = lame_dirichlet(10.0)
    with pytest.raises(InputError, match=r"piece 1 is an essential \(fixed\) arc") as error:
        METHODS[method](model)
    assert "\n" not in str(error.value)


def test_limit_stiffness_is_the_limit_of_the_band_stiffness_on_lame_dirichlet():
    """As tests/baselines/test_baselines.py on straight edges, now with both arcs essential and four corners
    (an arc's normal at each): ||K_band - K_limit|| / ||K|| = 6.4e-3, 6.5e-4, 6.5e-5 at delta = 0.1,
    0.01, 0.001 (without the curvature terms it stays at 4e-3)."""
    instance, _ = lame_dirichlet(10.0)
    body = instance.body
    from tests.baselines.test_baselines import band_to_limit_gaps
    deltas, gaps = band_to_limit_gaps(build_model(body, instance.parameters.material, Loads(), 10.0, 1))
    assert gaps[-1] < 1e-4 and abs(np.polyfit(np.log(deltas), np.log(gaps), 1)[0] - 1) <= 0.1
