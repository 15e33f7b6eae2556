"""Essential (roller and fixed) arcs: Dirichlet functions with a turning normal, curved bands."""
import numpy as np
import pytest

from ibm import dirichlet
from ibm.geometry.arcs import Arc
from ibm.geometry.outline import Body

A, B = 50.0, 100.0


def quarter_ring(base="roller", outer="fixed", left="roller", inner="roller") -> Body:
    vertices = np.array([[A, 0], [B, 0], [0, B], [0, A]], float)
    return Body(vertices, (base, outer, left, inner),
                arcs=(None, Arc(np.zeros(2)), None, Arc(np.zeros(2), clockwise=True)))


def ring_points(delta, count=200, seed=0):
    rng = np.random.default_rng(seed)
    theta = rng.uniform(0, np.pi / 2, count)
    r = np.concatenate([rng.uniform(A, A + 1.2 * delta, count // 2), rng.uniform(B - 1.2 * delta, B, count // 2)])
    return np.stack([r * np.cos(theta), r * np.sin(theta)], 1), theta


@pytest.mark.parametrize("outer, inner", [("fixed", "roller"), ("roller", "fixed"), ("roller", "roller")])
def test_arc_dirichlet_gradient_matches_finite_differences(outer, inner):
    body, delta = quarter_ring(outer=outer, inner=inner), 8.0
    x, _ = ring_points(delta)
    _, grad = dirichlet.matrix(body, x, delta)
    e = 1e-6
    fd = np.stack([(dirichlet.matrix(body, x + e * np.eye(2)[j], delta)[0]
                    - dirichlet.matrix(body, x - e * np.eye(2)[j], delta)[0]) / (2 * e) for j in range(2)], -1)
    assert np.abs(fd - grad).max() < 1e-7 * np.abs(grad).max()


@pytest.mark.parametrize("outer, inner", [("fixed", "roller"), ("roller", "fixed"), ("roller", "roller")])
def test_arc_dirichlet_functions_vanish_where_they_must(outer, inner):
    """n^T D = 0 on roller arcs (n = e_r there), D = 0 on fixed arcs, e_y^T D = 0 on the base roller
    and e_x^T D = 0 on the left one, also inside the arcs' bands (the arc factor leads the product)."""
    body, delta = quarter_ring(outer=outer, inner=inner), 8.0
    theta = np.linspace(0, np.pi / 2, 41)
    for radius, kind in ((A, inner), (B, outer)):
        x = radius * np.stack([np.cos(theta), np.sin(theta)], 1)
        D, _ = dirichlet.matrix(body, x, delta)
        value = np.einsum("pi,pia->pa", x / radius, D) if kind == "roller" else D
        assert np.abs(value).max() < 1e-14
    line = np.linspace(A, B, 51)
    D, _ = dirichlet.matrix(body, np.stack([line, 0 * line], 1), delta)
    assert np.abs(D[:, 1, :]).max() == 0.0
    D, _ = dirichlet.matrix(body, np.stack([0 * line, line], 1), delta)
    assert np.abs(D[:, 0, :]).max() < 1e-15


# --- curved bands: exact areas, closed forms, refinement -----------------------------------------

PLACEMENTS = [(90.0, (0.0, 0.0)), (30.0, (3.7, 2.9)), (17.3, (6.1, 1.3))]


def placed_ring(angle, offset, kinds=("roller", "fixed", "roller", "roller")) -> Body:
    from ibm.geometry.frames import frame_of_angle
    R = frame_of_angle(angle)
    c = np.asarray(offset, float)
    v = c + np.array([[A, 0], [B, 0], [0, B], [0, A]]) @ R.T
    return Body(v, kinds, frame=R, arcs=(None, Arc(c), None, Arc(c, clockwise=True)))


def in_band(x, wall, delta):
    from ibm.quadrature.curved_bands import band_radii
    low, high = band_radii(wall, delta)
    r = np.linalg.norm(x - wall.center, axis=1)
    return (r > low - 1e-12 * high) & (r < high + 1e-12 * high)


@pytest.mark.parametrize("angle,offset", PLACEMENTS)
@pytest.mark.parametrize("h,delta", [(10.0, 3.0), (10.0, 1e-4), (2.5, 0.75)])
def test_curved_band_and_body_quadrature_match_closed_forms(angle, offset, h, delta):
    """Against sympy's integrals of x^a y^b over each arc's annular band and over the body: 1e-12, or for
    thin bands the rounding of the band's edge positions (eps R) relative to its width delta."""
    from ibm.quadrature.bands import band_quadrature
    from ibm.norms import body_quadrature
    from ibm.discretise.grid import Grid
    from tests.ibm.geometry.test_arcs import sector_integral
    body = placed_ring(angle, offset)
    grid = Grid.covering(body, h)
    band = band_quadrature(body, grid, delta)
    for wall, (r0, r1) in zip(body.walls[:2], ((B - delta, B), (A, A + delta))):
        mine = in_band(band.x, wall, delta)
        for a, b in ((0, 0), (1, 0), (2, 1)):
            exact = sector_integral(a, b, angle, offset, r0, r1)
            value = np.sum(band.weight[mine] * band.x[mine, 0] ** a * band.x[mine, 1] ** b)
            assert value == pytest.approx(exact, rel=1e-12 + 4e-16 * B / delta)
    qp = body_quadrature(body, grid, 4, delta)
    for a, b in ((0, 0), (1, 2)):
        assert np.sum(qp.weight * qp.x[:, 0] ** a * qp.x[:, 1] ** b) == pytest.approx(
            sector_integral(a, b, angle, offset), rel=1e-12)


def test_curved_band_correction_is_converged_to_round_off():
    """The band correction of the IBM stiffness with 8 polar Gauss points per direction against 14."""
    import ibm.quadrature.curved_bands as curved
    from ibm import dirichlet
    from ibm.small import forms
    from ibm.quadrature.bands import band_quadrature
    from ibm.discretise.grid import Grid
    from ibm.models.elastic import Elastic
    from ibm.small.model import Loads, Model
    from ibm.discretise.points import material_points
    body, h, delta = placed_ring(30.0, (3.7, 2.9)), 10.0, 3.0
    grid = Grid.covering(body, h)
    model = Model(body, Elastic(1e4, 0.3), Loads(), grid, material_points(body, grid, 1))

    def correction(order):
        curved.ORDER = order
        try:
            band = band_quadrature(body, grid, delta)
            return (forms.stiffness(model, band, lambda x: dirichlet.matrix(body, x, delta))
                    - forms.stiffness(model, band)).toarray()
        finally:
            curved.ORDER = 8
    coarse, fine = correction(8), correction(14)
    assert np.abs(coarse - fine).max() <= 1e-12 * np.abs(fine).max()


# --- the problem with essential arcs ----------------------------------------------------------------

@pytest.mark.parametrize("angle,offset", [(30.0, (0.37, 0.29)), (17.3, (0.61, 0.13))])
def test_ibm_on_lame_dirichlet_converges_at_the_optimal_rates(angle, offset):
    """With its delta law (delta / h = 0.001 h^2): measured 1.96 and 0.975 at both placements."""
    from studies.run.case import CaseSpec
    from studies.run.convergence import converge
    result = converge(CaseSpec(problem="lame-dirichlet", load_type="settlement", method="ibm", angle=angle,
                               offset=offset, ppc=2), 4, "0.001*h^2", coarse=10.0)
    assert result["rates"]["err_l2"] >= 1.9
    assert result["rates"]["err_energy"] >= 0.95


def test_ibm_converges_on_a_half_disc_whose_traction_diameter_crosses_the_arc_band():
    """A fixed semicircle (its data from u = s (x - c), sigma = -p I) and a loaded diameter whose ends run
    through the arc's band (the traction quadrature splits at the band's circles): the lift
    s (x - c) (r / R)^2 leaves u^h a cubic to approximate. Measured err_u 6.6e-2, 1.6e-2, 3.1e-3."""
    from baselines.registry import METHODS
    from ibm.norms import point_errors
    from ibm.models.elastic import Elastic
    from ibm.small.model import Loads, build_model
    p, R, c = 10.0, 50.0, np.array([3.7, 2.9])
    along = np.array([np.cos(np.radians(20)), np.sin(np.radians(20))])
    body = Body(np.array([c - R * along, c, c + R * along]), ("traction", "traction", "fixed"),
                arcs=(None, None, Arc(c)))
    material = Elastic(1e4, 0.3)
    s = -p / (2 * (material.lam + material.mu))

    def lift(x):
        d = x - c
        q = np.sum(d * d, axis=1) / R ** 2
        return s * d * q[:, None], s * (q[:, None, None] * np.eye(2) + 2 * d[:, :, None] * d[:, None, :] / R ** 2)

    tractions = {k: (lambda n: lambda x: np.broadcast_to(-p * n, (len(x), 2)).copy())(-body.normals[k]) for k in (0, 1)}
    errors = []
    for h in (5.0, 2.5, 1.25):
        model = build_model(body, material, Loads(tractions=tractions, lift=lift), h, ppc=2)
        solution = METHODS["ibm"](model)
        x = model.points.x
        n = len(x)
        result = point_errors(model.points.volume, solution.u, s * (x - c), solution.sigma,
                              np.broadcast_to(-p * np.eye(2), (n, 2, 2)), solution.sigma_zz,
                              np.full(n, 2 * material.lam * s), np.array([0.0, 1.0]))
        errors.append(result["err_u"])
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] < 5e-3 and rates.min() >= 1.9
