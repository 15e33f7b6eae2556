"""Problem library: exactness of every exact solution, the sympy derivation, the norms."""
import math

import numpy as np
import pytest
import sympy as sp

from ibm.norms import body_quadrature, norm_errors
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid
from ibm.models.elastic import Elastic
from ibm.small.model import Loads
from studies.run.case import CaseSpec, instance_of, run_case, validate
from studies.problems.manufactured import Field
from studies.problems.library import LOADINGS, Parameters, get_problem, place

MATERIAL = Elastic(1e4, 0.3)
PARAMETERS = Parameters(MATERIAL, 10.0, 100.0, 80.0)      # not square: L and H are not mixed up
LOCAL_NORMAL = {"base": (0, -1), "right": (1, 0), "top": (0, 1), "left": (-1, 0)}   # outward
SYMBOLIC = [key for key, problem in LOADINGS.items() if isinstance(problem.exact, Field)]


def test_library_holds_the_issue_problems():
    assert set(LOADINGS) >= {("confined-block", "pressure"), ("confined-block", "settlement"),
                             ("column", "pressure"), ("manufactured", "pressure"),
                             ("manufactured-fixed", "pressure")}
    assert get_problem("manufactured-fixed").kinds[0] == "fixed"
    assert get_problem("column").kinds == ("roller", "roller", "free", "roller")
    assert get_problem("confined-block", "settlement").kinds == ("roller",) * 4


@pytest.mark.parametrize("key", SYMBOLIC, ids=lambda key: ":".join(key))
def test_symbolic_boundary_conditions_hold_exactly(key):
    """Roller: n.(u - u^a) = 0 and zero shear traction; fixed: u = u^a; free: sigma n = 0."""
    problem = LOADINGS[key]
    d = problem.exact.derivation()
    s = d.symbols
    lift = problem.lift.derivation().u if problem.lift is not None else sp.zeros(2, 1)
    on = {"base": {s["eta"]: 0}, "right": {s["xi"]: s["L"]}, "top": {s["eta"]: s["H"]}, "left": {s["xi"]: 0}}
    sides = [(kind, sp.Matrix(LOCAL_NORMAL[side]), on[side], d.traction[side]) for side, kind in zip(on, problem.kinds)]
    if problem.outline is not None:   # pieces of an outline (L = H): x = a + lam (b - a), or on an arc
        sides = []
        vertices, kinds, *arcs = problem.outline(Parameters(Elastic(1.0, 0.3), 1.0, width=1.0, height=1.0))
        arcs = arcs[0] if arcs else (None,) * len(kinds)
        lam = sp.Symbol("lam_piece", real=True)
        sigma = d.sigma.subs(s["H"], s["L"])
        for k, kind in enumerate(kinds):
            a, b = (sp.Matrix([sp.nsimplify(c) for c in vertices[j % len(vertices)]]) * s["L"] for j in (k, k + 1))
            if arcs[k] is None:
                t = b - a
                outward = sp.Matrix([t[1], -t[0]]) / sp.sqrt(t.dot(t))
                where = {s["xi"]: a[0] + lam * t[0], s["eta"]: a[1] + lam * t[1]}
            else:                     # the angle lam about the centre; outward radial unless clockwise
                centre = sp.Matrix([sp.nsimplify(c) for c in arcs[k].center]) * s["L"]
                radius = sp.sqrt((a - centre).dot(a - centre))
                radial = sp.Matrix([sp.cos(lam), sp.sin(lam)])
                outward = -radial if arcs[k].clockwise else radial
                where = {s["xi"]: centre[0] + radius * sp.cos(lam), s["eta"]: centre[1] + radius * sp.sin(lam)}
            where[s["H"]] = s["L"]
            sides.append((kind, -outward, where, (sigma * outward).subs(where)))
    length = sp.Symbol("L_positive", positive=True)    # sqrt(L^2) = L on arcs (lame-dirichlet's lift has r)
    for side, (kind, n, where, traction) in enumerate(sides):
        gap = (d.u - lift).subs(where).subs(s["L"], length)
        n, traction = n.subs(s["L"], length), traction.subs(s["L"], length)
        if kind == "roller":
            assert sp.simplify(n.dot(gap)) == 0, side
            assert sp.simplify(traction.dot(sp.Matrix([-n[1], n[0]]))) == 0, side
        elif kind == "fixed":
            assert sp.simplify(gap) == sp.zeros(2, 1), side
        elif kind == "free":
            assert sp.simplify(traction) == sp.zeros(2, 1), side


@pytest.mark.parametrize("key", SYMBOLIC, ids=lambda key: ":".join(key))
def test_symbolic_equilibrium(key):
    """div sigma + b = 0 with the derived b, re-derived from the displacement text."""
    d = LOADINGS[key].exact.derivation()
    xi, eta = d.symbols["xi"], d.symbols["eta"]
    divergence = sp.Matrix([sp.diff(d.sigma[i, 0], xi) + sp.diff(d.sigma[i, 1], eta) for i in range(2)])
    assert sp.simplify(divergence + d.body_force) == sp.zeros(2, 1)


def test_manufactured_body_force_and_traction_match_a_hand_derivation():
    prm = PARAMETERS
    lam, mu, M = MATERIAL.lam, MATERIAL.mu, MATERIAL.M
    L, H, p = prm.width, prm.height, prm.load
    A, B, a, b = p * H / M, p * H / (2 * M), math.pi / L, math.pi / (2 * H)
    rng = np.random.default_rng(3)
    xi, eta = rng.random(20) * L, rng.random(20) * H
    field = get_problem("manufactured").exact
    expected = np.stack([((lam + 2 * mu) * A * a**2 + (lam + mu) * B * a * b + mu * A * b**2)
                         * np.sin(a * xi) * np.cos(b * eta),
                         ((lam + mu) * A * a * b + mu * B * a**2 + (lam + 2 * mu) * B * b**2)
                         * np.cos(a * xi) * np.sin(b * eta)], axis=1)
    assert np.abs(field.body_force(xi, eta, prm) - expected).max() < 1e-12 * np.abs(expected).max()
    top = field.traction("top", xi, np.full_like(xi, H), prm)
    assert np.abs(top[:, 0] + mu * (A * b + B * a) * np.sin(a * xi)).max() < 1e-12 * p
    assert np.abs(top[:, 1]).max() < 1e-12 * p
    u, grad = field(xi, eta, prm)
    assert np.allclose(u[:, 0], A * np.sin(a * xi) * np.cos(b * eta), rtol=0, atol=1e-15 * A)
    assert np.allclose(grad[:, 1, 0], -B * a * np.sin(a * xi) * np.sin(b * eta), rtol=0, atol=1e-15 * A)


def _divergence(instance, x, step):
    """Fourth-order central differences of the exact stress, (n, 2)."""
    div = np.zeros((len(x), 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = step
        sig = [instance.exact(x + k * e)[1][:, :, j] for k in (-2, -1, 1, 2)]
        div += (sig[0] - 8 * sig[1] + 8 * sig[2] - sig[3]) / (12 * step)
    return div


@pytest.mark.parametrize("key", list(LOADINGS), ids=lambda key: ":".join(key))
@pytest.mark.parametrize("angle", [90.0, 30.0])
def test_placed_exact_solution_is_in_equilibrium_and_meets_its_boundary_data(key, angle):
    """In the grid frame, at any angle: the global body force, lift and tractions fit the exact field."""
    instance = place(LOADINGS[key], PARAMETERS, angle, (0.37, 0.29), 10.0)
    body, loads = instance.body, instance.loads
    scale = PARAMETERS.load                                  # stresses are O(load) for every problem
    rng = np.random.default_rng(7)
    local = rng.random((400, 2)) * 0.8 + 0.1
    x = instance.corner + (local * [PARAMETERS.width, PARAMETERS.height]) @ instance.frame.T
    import shapely
    x = x[shapely.contains_xy(shapely.Polygon(body.ring()), *x.T)][:40]          # inside the body
    b = loads.body_force(x) if loads.body_force is not None else np.zeros_like(x)
    step = 0.05 if body.arcs else 0.5                        # 1/r fields: smaller steps for the same truncation
    assert np.abs(_divergence(instance, x, step) + b).max() < 1e-7 * scale / PARAMETERS.height

    t = np.linspace(0.0, 1.0, 11)
    u_scale = np.abs(instance.exact(x)[0]).max()
    for k, kind in enumerate(body.kinds):
        if body.arcs and body.arcs[k] is not None:           # points on the arc, its normal there
            radius, start, sweep = body.arc_angles(k)
            angle = start + t * sweep
            xe = body.arcs[k].center + radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        else:
            xe = body.starts[k] + t[:, None] * body.tangents[k]
        u, sigma, _ = instance.exact(xe)
        lift = loads.lift(xe)[0] if loads.lift is not None else np.zeros_like(xe)
        outward = body.outward(k, xe)
        traction = np.einsum("pij,pj->pi", sigma, outward)   # sigma n_out
        n = -outward                                         # inward, per point (it turns on an arc)
        tangent = np.stack([n[:, 1], -n[:, 0]], axis=1)
        if kind == "roller":
            assert np.abs(np.sum((u - lift) * n, axis=1)).max() < 1e-12 * u_scale, k
            assert np.abs(np.sum(traction * tangent, axis=1)).max() < 1e-12 * scale, k
        elif kind == "fixed":
            assert np.abs(u - lift).max() < 1e-12 * u_scale, k
        elif kind == "free":
            assert np.abs(traction).max() < 1e-12 * scale, k
        else:
            assert np.abs(loads.tractions[k](xe) - traction).max() < 1e-12 * scale, k


def test_settlement_lift_is_not_the_exact_field_and_carries_the_settlement():
    instance = place(get_problem("confined-block", "settlement"), PARAMETERS, 30.0, (0.37, 0.29), 10.0)
    x = instance.corner + np.array([[50.0, 40.0]]) @ instance.frame.T       # mid-height
    u = instance.exact(x)[0]
    lift = instance.loads.lift(x)[0]
    assert np.abs(u - 2 * lift).max() < 1e-12 * PARAMETERS.load          # -D eta/H vs -D (eta/H)^2 at H/2
    top = instance.body.starts[2] + 0.3 * instance.body.tangents[2]
    assert instance.loads.lift(top[None])[0] @ instance.body.normals[2] == pytest.approx(PARAMETERS.load)


def test_settlement_block_equals_the_pressure_block_with_p_equal_M_delta_over_L():
    delta = 0.05
    settled = instance_of(CaseSpec(load_type="settlement", load=delta, angle=45.0))
    pressed = instance_of(CaseSpec(load=MATERIAL.M * delta / 100.0, angle=45.0))
    x = settled.corner + np.array([[10.0, 20.0], [70.0, 90.0]]) @ settled.frame.T
    for a, b in zip(settled.exact(x), pressed.exact(x)):
        assert np.abs(a - b).max() < 1e-13 * max(np.abs(b).max(), 1e-300) + 1e-18


def test_ibm_with_the_exact_field_as_lift_is_exact():
    """With u^a = u the discrete part must vanish: the lift path is consistent (O(delta) only)."""
    spec = CaseSpec(load_type="settlement", angle=30.0)
    instance = instance_of(spec)
    exact = place(get_problem("confined-block", "settlement"), instance.parameters, 30.0, spec.offset, spec.cell)
    loads = Loads(lift=lambda x: (exact.exact(x)[0], exact.exact_gradient(x)))
    from baselines.registry import METHODS
    from ibm.small.model import build_model
    model = build_model(instance.body, MATERIAL, loads, spec.cell, spec.ppc)
    solution = METHODS["ibm"](model)
    errors = norm_errors(model.body, model.grid, MATERIAL, solution.evaluate, instance.exact,
                         delta=solution.info.get("delta"))
    assert errors["err_l2"] < 1e-9
    assert errors["err_energy"] < 1e-9


@pytest.mark.parametrize("problem,load_type", [("column", "pressure"), ("confined-block", "settlement"),
                                               ("manufactured-fixed", "pressure")])
def test_new_problems_solve_with_small_errors(problem, load_type):
    record = run_case(CaseSpec(problem=problem, load_type=load_type, angle=30.0, cell=5.0, ppc=2))
    assert record["load_type"] == load_type
    assert record["err_l2"] < 0.07 and record["err_energy"] < 0.2
    assert record["err_u"] < 0.07


# --- norms --------------------------------------------------------------------------

@pytest.mark.parametrize("delta", [None, 1e-4, 2.0])
def test_body_quadrature_integrates_polynomials_over_the_rotated_body(delta):
    instance = place(get_problem("manufactured-fixed"), PARAMETERS, 30.0, (0.37, 0.29), 7.0)
    body = instance.body
    grid = Grid.covering(body, 7.0)
    qp = body_quadrature(body, grid, 4, delta)
    L, H = PARAMETERS.width, PARAMETERS.height
    centre = instance.corner + instance.frame @ np.array([L / 2, H / 2])
    r2 = np.sum((qp.x - centre) ** 2, axis=1)
    assert qp.weight.sum() == pytest.approx(L * H, rel=1e-13)
    assert np.abs(qp.weight @ (qp.x - centre)).max() < 1e-10 * L * H * L
    assert qp.weight @ r2 == pytest.approx(L * H * (L**2 + H**2) / 12, rel=1e-12)
    xl = (qp.x - instance.corner) @ instance.frame                         # local (xi, eta)
    assert qp.weight @ (xl[:, 0] ** 3 * xl[:, 1] ** 2) == pytest.approx(L**4 / 4 * H**3 / 3, rel=1e-12)
    assert np.all(grid.locate(qp.x) == qp.cells)
    assert np.all(body.signed_distance(qp.x) >= -1e-9)


def test_norm_errors_are_exact_for_known_perturbations():
    instance = place(get_problem("manufactured"), PARAMETERS, 30.0, (0.37, 0.29), 10.0)
    grid = Grid.covering(instance.body, 10.0)

    def scaled(x, cells):
        u, sigma, zz = instance.exact(x)
        return 1.01 * u, 1.01 * sigma, 1.01 * zz

    errors = norm_errors(instance.body, grid, MATERIAL, scaled, instance.exact)
    assert errors["err_l2"] == pytest.approx(0.01, rel=1e-12)
    assert errors["err_energy"] == pytest.approx(0.01, rel=1e-12)

    shift = np.array([3e-3, -1e-3])

    def shifted(x, cells):                                   # a rigid translation: no energy
        u, sigma, zz = instance.exact(x)
        return u + shift, sigma, zz

    errors = norm_errors(instance.body, grid, MATERIAL, shifted, instance.exact)
    assert errors["err_energy"] == 0.0
    qp = body_quadrature(instance.body, grid, 6)
    norm_u = math.sqrt(qp.weight @ np.sum(instance.exact(qp.x)[0] ** 2, axis=1))
    assert errors["err_l2"] == pytest.approx(np.linalg.norm(shift) * 100.0 * math.sqrt(0.8) / norm_u, rel=1e-6)


# --- bad input ----------------------------------------------------------------------

def test_bad_load_types_are_named():
    with pytest.raises(InputError, match=r"load type 'settlement' is not allowed for problem 'column'; allowed: pressure"):
        get_problem("column", "settlement")
    with pytest.raises(InputError, match=r"load type 'weight' is not allowed; allowed: pressure, settlement"):
        validate(CaseSpec(load_type="weight"))
    with pytest.raises(InputError, match="unknown problem 'manufactured-fix'"):
        get_problem("manufactured-fix")
