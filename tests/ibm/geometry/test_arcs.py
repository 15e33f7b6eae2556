"""Curved pieces: arcs in outlines, exact volumes, converged quadrature, the Lame and Kirsch problems."""
import numpy as np
import pytest
import sympy as sp

from ibm.quadrature.bands import band_quadrature, edge_quadrature
from ibm.norms import body_quadrature
from ibm.geometry.arcs import Arc
from ibm.geometry.frames import frame_of_angle
from ibm.geometry.outline import Body
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid
from ibm.discretise.points import material_points

A, B = 50.0, 100.0


def annulus(angle: float = 30.0, offset=(3.7, 2.9), kinds=("roller", "free", "roller", "traction")) -> Body:
    """The quarter ring A <= r <= B about `offset`, turned by angle - 90 degrees."""
    R = frame_of_angle(angle)
    c = np.asarray(offset, float)
    v = c + np.array([[A, 0], [B, 0], [0, B], [0, A]]) @ R.T
    return Body(v, kinds, frame=R, arcs=(None, Arc(c), None, Arc(c, clockwise=True)))


def sector_integral(a: int, b: int, angle: float, centre, r0=A, r1=B, t0=0.0, t1=np.pi / 2) -> float:
    """int x^a y^b over the annular sector r0 <= r <= r1, t0 <= t <= t1 (local), placed like annulus()."""
    r, t = sp.symbols("r t", positive=True)
    R = frame_of_angle(angle)
    xy = sp.Matrix(R.tolist()) * sp.Matrix([r * sp.cos(t), r * sp.sin(t)]) + sp.Matrix(list(centre))
    integrand = (xy[0] ** a * xy[1] ** b * r).expand()
    return float(sp.integrate(sp.integrate(integrand, (r, r0, r1)), (t, t0, t1)))


@pytest.mark.parametrize("angle,offset", [(90.0, (0.0, 0.0)), (30.0, (3.7, 2.9)), (61.7, (8.3, 4.1))])
def test_arcs_give_exact_areas_and_material_point_volumes(angle, offset):
    body = annulus(angle, offset)
    exact = np.pi * (B * B - A * A) / 4
    assert body.area == pytest.approx(exact, rel=1e-14)
    for h, ppc in ((10.0, 1), (7.0, 2), (3.0, 3)):
        points = material_points(body, Grid.covering(body, h), ppc)
        assert points.volume.sum() == pytest.approx(exact, rel=1e-13)
        # first moments too: each domain's centroid is exact (chord polygon and circular segments)
        moment = (points.volume[:, None] * points.x).sum(axis=0)
        assert moment == pytest.approx([sector_integral(1, 0, angle, offset), sector_integral(0, 1, angle, offset)],
                                       rel=1e-12)


@pytest.mark.parametrize("angle,offset", [(30.0, (3.7, 2.9)), (61.7, (8.3, 4.1))])
def test_body_quadrature_over_a_curved_body_matches_closed_forms(angle, offset):
    body = annulus(angle, offset)
    qp = body_quadrature(body, Grid.covering(body, 7.0), order=4)
    for a, b in ((0, 0), (2, 0), (1, 2), (3, 3)):
        exact = sector_integral(a, b, angle, offset)
        assert np.sum(qp.weight * qp.x[:, 0] ** a * qp.x[:, 1] ** b) == pytest.approx(exact, rel=1e-12)


def test_curved_band_quadrature_converges_to_round_off_and_matches_a_closed_form():
    """Straight roller bands crossing both arcs: chord polygon (exact) plus circular segments (Gauss in
    the angle); against sympy's integral over the band {0 <= y' < delta} of the ring, and by refinement."""
    import ibm.quadrature.bands as bands
    delta = 2.5
    body = annulus(90.0, (0.0, 0.0), kinds=("roller", "free", "free", "traction"))   # one roller: y = 0
    grid = Grid.covering(body, 7.0)
    y, x = sp.symbols("y x", real=True)
    for k in (0, 2):
        # the roller band's region {0 <= y < delta, A^2 <= x^2 + y^2 <= B^2, x >= 0}
        inner = sp.integrate(y ** k * (sp.sqrt(B ** 2 - y ** 2) - sp.sqrt(A ** 2 - y ** 2)), (y, 0, delta))
        qp = band_quadrature(body, grid, delta)
        assert np.sum(qp.weight * qp.x[:, 1] ** k) == pytest.approx(float(inner), rel=1e-12)
    values = []
    for order in (4, 6, 10, 14):
        bands.ARC_ORDER, saved = order, bands.ARC_ORDER         # the band quadrature's points per sub-arc
        try:
            qp = band_quadrature(body, grid, delta)
        finally:
            bands.ARC_ORDER = saved
        values.append(np.sum(qp.weight * np.cos(qp.x[:, 0] / 7.0) * qp.x[:, 1] ** 2))
    changes = np.abs(np.diff(values)) / abs(values[-1])
    assert changes[-1] < 1e-13 and changes[0] > changes[-1]      # converged, by refinement


def test_traction_quadrature_on_an_arc_is_exact_for_its_length_and_moments():
    body = annulus(30.0)
    grid = Grid.covering(body, 7.0)
    for k, radius in ((1, B), (3, A)):
        qp = edge_quadrature(body, grid, k, None)
        assert qp.weight.sum() == pytest.approx(np.pi / 2 * radius, rel=1e-14)
        d = (qp.x - body.arcs[k].center) @ body.frame                      # the local frame
        assert np.sum(qp.weight * d[:, 0] ** 2) == pytest.approx(np.pi / 4 * radius ** 3, rel=1e-13)
        assert set(qp.cells) <= set(grid.locate(qp.x))


@pytest.mark.parametrize("arc,message", [
    (Arc(np.array([0.0, 1.0])), "piece 1: the arc's center (0, 1) is not equidistant from its ends"),
    (Arc(np.array([50.0, 10.0]), clockwise=True), "turns through 202.62 degrees about its center; at most 180"),
])
def test_bad_arcs_are_named_in_one_line(arc, message):
    v = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    arcs = (None, arc, None, None) if "equidistant" in message else (arc, None, None, None)
    with pytest.raises(InputError) as error:
        Body(v, ("free",) * 4, arcs=arcs)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_essential_arcs_off_right_angles_are_refused():
    """A circular segment: its fixed arc meets the chord at 53.13 degrees (tests/ibm/quadrature/test_curved_bands.py
    has the arcs that meet their neighbours at right angles)."""
    body = Body(np.array([[40.0, 30.0], [-40.0, 30.0], [0.0, 30.0]]), ("fixed", "traction", "traction"),
                arcs=(Arc(np.zeros(2)), None, None))
    with pytest.raises(InputError, match=r"piece 0: an essential \(fixed\) arc must meet its neighbours at right "
                                         r"angles \(interior angle 90 degrees\); at \(40, 30\) the interior angle "
                                         r"is 53.1301 degrees"):
        body.walls


LAME_PLACEMENTS = {"default": (30.0, (0.37, 0.29)), "random": (17.3, (0.61, 0.13))}


@pytest.mark.parametrize("placement", LAME_PLACEMENTS)
@pytest.mark.parametrize("problem,cell,levels", [("lame", 10.0, 4), ("kirsch", 1.25, 3)])
@pytest.mark.parametrize("method,law", [("lagrange", None), ("nitsche", None), ("ibm", "0.001*h^2")])
def test_curved_problems_converge_at_the_optimal_rates(problem, cell, levels, method, law, placement):
    """Kirsch from h = a/16 (a = 20, the hole): coarser grids do not resolve its stress concentration
    (from h = a/2 the fits are 1.65 - 1.85, the level rates rising to 1.95)."""
    from studies.run.case import CaseSpec
    from studies.run.convergence import converge
    angle, offset = LAME_PLACEMENTS[placement]
    result = converge(CaseSpec(problem=problem, method=method, angle=angle, offset=offset, ppc=2), levels, law,
                      coarse=cell)
    assert result["rates"]["err_l2"] >= 1.9
    assert result["rates"]["err_energy"] >= 0.95


@pytest.mark.parametrize("placement", LAME_PLACEMENTS)
@pytest.mark.parametrize("problem,cell", [("lame", 10.0), ("kirsch", 5.0)])
def test_body_fitted_fem_on_curved_problems_converges_at_its_own_rates(problem, cell, placement):
    """Isoparametric P2 on gmsh's curved mesh: L2 rate 3, energy 2 (the gates: >= 1.9, >= 0.95)."""
    from studies.run.case import CaseSpec
    from studies.run.convergence import converge
    angle, offset = LAME_PLACEMENTS[placement]
    result = converge(CaseSpec(problem=problem, method="fem", angle=angle, offset=offset, ppc=2), 3, None, coarse=cell)
    assert result["rates"]["err_l2"] >= 2.7
    assert result["rates"]["err_energy"] >= 1.7


def test_new_problems_give_the_same_table_whatever_the_number_of_workers(tmp_path):
    from tests.studies.run.test_runner import same_table_with_one_and_two_workers
    one = same_table_with_one_and_two_workers(
        '[[sweep]]\nname = "geometry"\nproblems = ["l-shape", "lame", "kirsch"]\n'
        'methods = ["ibm", "penalty", "nitsche", "lagrange", "fem"]\nangle = [90, 30]\ncell = 10\nppc = 2\n', tmp_path)
    assert len(one) == 30 and (one["status"] == "ok").all()


@pytest.mark.parametrize("problem", ["l-shape", "lame"])
@pytest.mark.parametrize("method,law,parameters", [("ibm-limit", "0.01*h", ()), ("penalty", None, (("beta0", 1e3),))])
def test_limit_and_penalty_keep_their_documented_laws_on_the_new_problems(problem, method, law, parameters):
    """The laws of studies.run.convergence (ibm-limit: delta = 0.01 h; penalty: beta0 = 1e3) at 30 degrees."""
    from studies.run.case import CaseSpec
    from studies.run.convergence import converge
    result = converge(CaseSpec(problem=problem, method=method, angle=30.0, ppc=2,
                               method_parameters=dict(parameters)), 4, law)
    assert result["rates"]["err_l2"] >= 1.9
    assert result["rates"]["err_energy"] >= 0.95
