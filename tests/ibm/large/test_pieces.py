"""Pieces of the large-deformation loop: the reduced tangent's pattern, merged slivers, the
outline's motion, Newton's rounding floor and halving, a point leaving the grid."""
import numpy as np
import pytest
import scipy.sparse as sp
import shapely

from baselines.registry import treatment
from ibm.exceptions import GridExit, SolveError
from ibm.models.constitutive import Hencky
from ibm.large.equilibrium import Blocks, PointSet, ReducedPattern, evaluate, triplets, unique_inverse
from ibm.geometry.outline import rectangle
from ibm.discretise.grid import Grid
from ibm.large.loadsteps import Loading, Setup, run
from ibm.discretise.points import material_points, merge_slivers

KINDS = ("roller", "roller", "free", "roller")


def test_reduced_pattern_assembles_the_reduced_tangent_exactly():
    rng = np.random.default_rng(7)
    n_dofs, n_points, m = 40, 30, 8
    dofs = np.stack([rng.choice(n_dofs, m, replace=False) for _ in range(n_points)])
    G = rng.standard_normal((n_points, 4, m)) * 1e-2
    model = Hencky(1e4, 0.3)
    points = PointSet(dofs, G, rng.uniform(0.5, 1.0, n_points), model.initial(n_points))
    active = np.sort(rng.choice(n_dofs, 32, replace=False))
    # an extension-like T: identity on most active DOFs, a few rows tying to two others, one fixed row
    T = sp.lil_matrix((len(active), 28))
    for i in range(28):
        T[i, i] = 1.0
    T[28, [0, 3]] = [0.25, 0.75]
    T[29, [5, 6]] = [0.5, 0.5]
    T[30, 10] = -1.5
    T = sp.csr_matrix(T)
    result = evaluate(model, [points], rng.standard_normal(n_dofs) * 1e-3)
    K = result.tangent(n_dofs)
    expected = (T.T @ K[active][:, active] @ T).toarray()
    pattern = ReducedPattern.of([points], active, n_dofs, T)
    assert np.abs(pattern.matrix(result.values).toarray() - expected).max() <= 1e-13 * np.abs(expected).max()
    rows, columns = triplets([points])
    assert len(rows) == n_points * m * m and np.array_equal(rows[:m], np.repeat(dofs[0, 0], m))


def test_absolute_is_the_sum_of_the_points_absolute_blocks():
    """Evaluation.absolute (the rounding floor's |K|) assembles to sum_p |K_p| for a plain set (one
    triplet block per point) and for a set whose points share DOF rows (row blocks: |.| before the sum)."""
    rng = np.random.default_rng(5)
    n_dofs, n_points, m = 30, 24, 8
    model = Hencky(1e4, 0.3)
    rows = np.stack([rng.choice(n_dofs, m, replace=False) for _ in range(6)])
    shared = rows[rng.integers(0, 6, n_points)]                         # four points a row on average
    plain = np.stack([rng.choice(n_dofs, m, replace=False) for _ in range(n_points)])
    G = rng.standard_normal((2, n_points, 4, m)) * 1e-2
    sets = [PointSet(plain, G[0], rng.uniform(0.5, 1.0, n_points), model.initial(n_points)),
            PointSet(shared, G[1], rng.uniform(0.5, 1.0, n_points), model.initial(n_points), sign=-1.0,
                     blocks=Blocks.of(shared))]
    dU = rng.standard_normal(n_dofs) * 1e-3
    result = evaluate(model, sets, dU)
    r, c = triplets(result.sets)
    assembled = sp.csr_matrix((result.absolute, (r, c)), shape=(n_dofs, n_dofs)).toarray()
    expected = np.zeros((n_dofs, n_dofs))
    for points in sets:
        for p in range(len(points)):
            one = PointSet(points.dofs[p:p + 1], points.G[p:p + 1], points.volume[p:p + 1],
                           points.state.take(np.array([p])), sign=points.sign)
            expected += np.abs(evaluate(model, [one], dU).tangent(n_dofs).toarray())
    assert np.abs(assembled - expected).max() <= 1e-13 * expected.max()
    assert np.abs(result.absolute).sum() > np.abs(result.values).sum()     # the shared rows' blocks partly cancel


def test_unique_inverse_is_numpys_unique():
    """The pattern's unique keys and slots are np.unique's, for runs of repeated and sorted keys and for
    keys in no order (the stable sort only changes the cost, not the result)."""
    rng = np.random.default_rng(3)
    runs = np.concatenate([np.arange(s, s + 9) for s in rng.integers(0, 10**9, 300)])
    for key in (runs, rng.integers(0, 50, 2000), rng.integers(0, 2**40, 500), np.array([7]), rng.integers(0, 9, 40).astype(np.int32), np.zeros(0, np.int64)):
        unique, slot = unique_inverse(key)
        expected, inverse = np.unique(key, return_inverse=True)
        assert np.array_equal(unique, expected) and np.array_equal(slot, inverse.ravel())
        assert np.array_equal(unique[slot], key)


def test_reduced_pattern_by_products_where_the_extension_ties_to_many_nodes():
    """Rows of T with many entries (a body one or two cells across) take the product mode: the
    same matrix, and a pattern that stays when entries cancel (PARDISO reuses its analysis)."""
    rng = np.random.default_rng(11)
    n_dofs, n_points, m = 40, 30, 8
    dofs = np.stack([rng.choice(n_dofs, m, replace=False) for _ in range(n_points)])
    model = Hencky(1e4, 0.3)
    points = PointSet(dofs, rng.standard_normal((n_points, 4, m)) * 1e-2, rng.uniform(0.5, 1.0, n_points),
                      model.initial(n_points))
    active = np.arange(n_dofs)
    T = sp.csr_matrix(rng.uniform(0.0, 1.0, (n_dofs, 12)) * (rng.uniform(size=(n_dofs, 12)) < 0.6))
    pattern = ReducedPattern.of([points], active, n_dofs, T)
    assert pattern.slot is None                              # ~50 entries a triplet: products
    result = evaluate(model, [points], rng.standard_normal(n_dofs) * 1e-3)
    expected = (T.T @ result.tangent(n_dofs) @ T).toarray()
    A = pattern.matrix(result.values)
    assert np.abs(A.toarray() - expected).max() <= 1e-13 * np.abs(expected).max()
    zero = pattern.matrix(np.zeros_like(result.values))
    assert zero.nnz == A.nnz and np.array_equal(zero.indices, A.indices) and not zero.data.any()


def test_merged_slivers_tile_the_body_and_leave_no_small_point():
    body = rectangle(10.0, 50.0, KINDS, 30.0, np.array([0.94, 0.63]))
    grid = Grid.covering(body, 3.125, 1)
    points = material_points(body, grid, 2, domains=True)
    merged = merge_slivers(points, grid, 2, 0.25)
    full = (3.125 / 2) ** 2
    assert points.volume.min() < 0.05 * full                      # the inclined edges cut slivers
    assert len(merged) < len(points)
    assert merged.volume.min() >= 0.25 * full
    assert abs(merged.volume.sum() - body.area) <= 1e-10 * body.area
    union = shapely.union_all(merged.domains)
    assert abs(union.area - body.area) <= 1e-9 * body.area and np.all(shapely.is_valid(merged.domains))
    assert np.allclose(merged.x, shapely.get_coordinates(shapely.centroid(merged.domains)))


def test_a_point_leaving_the_grid_stops_the_run_with_one_line():
    body = rectangle(10.0, 20.0, KINDS, 90.0, np.zeros(2))
    pulled_up = Setup(body, Hencky(1e4, 0.0), Loading(body_force=np.array([0.0, 2e4])), 5.0, 2, "gimp", 4)
    with pytest.raises(GridExit) as failure:
        run(pulled_up, treatment("nodal", {}))
    message = str(failure.value)
    assert isinstance(failure.value, SolveError) and "\n" not in message
    assert message.startswith("load step 1: a material point at") and "has left the grid" in message


def test_outline_stays_on_its_walls_and_follows_the_points():
    """Column at 30 degrees: the outline's wall vertices stay on the wall lines and every point
    stays inside the outline, at every step."""
    body = rectangle(10.0, 50.0, KINDS, 30.0, np.array([0.94, 0.63]))
    setup = Setup(body, Hencky(1e4, 0.0), Loading(body_force=-(40000 / 50) * body.frame[:, 1]), 50 / 16, 2, "gimp", 10)
    seen = []

    def check(progress):
        outline = shapely.Polygon(progress.outline.vertices)
        seen.append((float(np.min(shapely.distance(shapely.points(progress.x), outline.exterior)
                                   * np.where(shapely.contains_xy(outline, progress.x[:, 0], progress.x[:, 1]), 1, -1))),
                     max(abs(progress.lines.distance(w, progress.outline.vertices[progress.outline.wall == w])).max()
                         for w in range(3))))
        return {}

    run(setup, treatment("nitsche", {}), after_step=check)
    inside, on_walls = np.array(seen).T
    assert inside.min() > 0 and on_walls.max() <= 1e-9


def _column_arguments():
    return ["solve", "--problem", "column", "--kinematics", "large", "--steps", "3", "--nu", "0", "--load", "40000",
            "--width", "6.25", "--height", "50", "--cell", "6.25", "--ppc", "2", "--angle", "90", "--offset", "0", "0",
            "--method", "nodal"]


def test_load_steps_show_progress_only_when_asked(capsys):
    from studies.run.case import CaseSpec, run_case
    from studies.cli import main
    spec = CaseSpec(problem="column", method="nodal", angle=90, cell=6.25, ppc=2, offset=(0, 0), nu=0.0, load=40000,
                    width=6.25, height=50, kinematics="large", steps=3)
    run_case(spec, progress=True)
    shown = capsys.readouterr().err
    assert "nodal load steps" in shown and "3/3" in shown and "newton=" in shown
    assert main(_column_arguments() + ["--json"]) == 0
    assert "load steps" not in capsys.readouterr().err      # --json (and a non-terminal) stays silent


def test_polygons_inside_collections_are_integrated():
    """A clip that returns a polygon with a line beside it (a domain edge on a cell side) keeps the polygon."""
    from ibm.quadrature.rules import fan_quadrilaterals, quadrilateral_points
    domain = shapely.Polygon([(105, -5), (110, -5), (110, -4.9), (111.5, -10), (105, -10)])
    pieces = shapely.intersection(np.array([shapely.box(100, -10, 110, 0), shapely.box(110, -10, 120, 0)]), domain)
    assert shapely.get_type_id(pieces[0]) == 7                       # GEOMETRYCOLLECTION (polygon, line)
    quads, owner = fan_quadrilaterals(pieces)
    _, weight, quad = quadrilateral_points(quads, 2)
    assert np.allclose(np.bincount(owner[quad], weight, minlength=2), shapely.area(pieces), rtol=1e-14)


def test_dependent_constraints_are_dropped():
    from ibm.large.newton import independent_rows
    rows = np.array([[1.0, 0, 2, 0], [0, 1, 0, 0], [2, 1, 4, 0], [0, 0, 0, 3.0]])   # row 2 = 2 row 0 + row 1
    kept = independent_rows(sp.csr_matrix(rows))
    assert len(kept) == 3 and np.linalg.matrix_rank(rows[kept]) == 3 and 3 in kept


def test_lagrange_column_at_zero_degrees_survives_tied_wall_pieces():
    """At 0 degrees and h = 50/32 the extension ties two wall pieces' nodes together from step 5:
    one multiplier depends on the others and is dropped instead of the saddle system going singular."""
    from studies.run.case import CaseSpec, run_case
    spec = CaseSpec(problem="column", method="lagrange", angle=0, cell=50 / 32, ppc=2, offset=(0.3, 0.2), nu=0.0,
                    E=1e4, load=40000, width=10, height=50, kinematics="large", steps=40)
    record = run_case(spec)
    assert record["err_sigma_ample"] <= 1.5 * 1.048706e-3 and record["step_cuts"] == 0


def test_a_linearised_point_set_is_the_first_order_expansion_of_its_finite_twin():
    """The IBM's band in 3D (ImplicitBoundary band 'linearised'): at dU = 0 its force and tangent are
    the finite set's, and its force is affine in dU with that tangent (no fold barrier, no softening)."""
    from ibm.large.kinematics import planar
    rng = np.random.default_rng(3)
    n_dofs, n_points, m, d = 30, 12, 8, 2
    dofs = np.stack([rng.choice(n_dofs, m, replace=False) for _ in range(n_points)])
    G = rng.standard_normal((n_points, d * d, m)) * 1e-2
    model = Hencky(1e4, 0.3)
    dF = np.broadcast_to(np.eye(3), (n_points, 3, 3)).copy()
    dF[:, :d, :d] += rng.standard_normal((n_points, d, d)) * 0.2          # a deformed step start
    state = model.update(dF, model.initial(n_points)).state
    lift = rng.standard_normal((n_points, d, d)) * 1e-3
    start = model.update(np.broadcast_to(np.eye(3), (n_points, 3, 3)).copy(), state)
    volume = rng.uniform(0.5, 1.0, n_points)
    finite = PointSet(dofs, G, volume, state, lift, -1.0)
    linear = PointSet(dofs, G, volume, state, lift, -1.0, linear=(planar(start.sigma, d), planar(start.tangent, d)))
    lifted = np.zeros(n_dofs)   # the lift alone: compare at dU = 0 without it
    a = evaluate(model, [PointSet(dofs, G, volume, state, None, -1.0)], lifted)
    b = evaluate(model, [PointSet(dofs, G, volume, state, None, -1.0, linear=linear.linear)], lifted)
    assert np.abs(a.force - b.force).max() <= 1e-12 * np.abs(a.force).max()
    assert np.abs(a.values - b.values).max() <= 1e-12 * np.abs(a.values).max()
    dU = rng.standard_normal(n_dofs) * 1e-2
    at_zero, at_dU = evaluate(model, [linear], np.zeros(n_dofs)), evaluate(model, [linear], dU)
    K = at_zero.tangent(n_dofs)
    assert np.array_equal(at_zero.values, at_dU.values)
    assert np.abs(at_dU.force - at_zero.force - K @ dU).max() <= 1e-12 * np.abs(at_dU.force).max()
    assert not np.allclose(evaluate(model, [finite], dU).force, at_dU.force)   # the finite set is not affine


def test_the_ibm_band_is_finite_in_2d_and_linearised_on_request():
    """2D keeps the finite band ('auto' is the same run to the bit). The inclined column in standard
    MPM at h = 6.25 (1.6 cells across), base stress 4 E: with the finite band at delta = 1e-5 h
    the first step halves its updates to 2^-10 and is cut (corner band points crushed to a stretch of
    3e-5 beside others torn past e); linearised it converges in 3-5 iterations a step, no cut:
    measured err_sigma_ample 0.0381, height 23.30 (exact 24.06; penalty on this grid: 0.0374)."""
    from ibm.implicit_boundary import ImplicitBoundary
    from studies.problems.registry import problem_of
    from studies.run.case import CaseSpec

    def column(band, steps, basis):
        spec = CaseSpec(problem="column", method="ibm", kinematics="large", basis=basis, steps=steps, E=1e4, nu=0.0,
                        load=40000.0, width=10.0, height=50.0, cell=6.25, ppc=2, angle=30.0, offset=(0.3, 0.2))
        setup, corner, R = problem_of(spec).setup(spec)
        progress = run(setup, ImplicitBoundary(band=band) if band else ImplicitBoundary())
        return progress, float(np.max((progress.outline.vertices - corner) @ R[:, 1]))

    (auto, _), (finite, _) = column(None, 4, "gimp"), column("finite", 4, "gimp")
    assert np.array_equal(auto.x, finite.x) and np.array_equal(auto.sigma, finite.sigma)
    linearised, height = column("linearised", 20, "mpm")
    assert all(step["cuts"] == 0 and step["newton_iterations"] <= 6 for step in linearised.steps)
    assert abs(height - 23.303) < 0.01           # the exact 24.06 within 0.13 h, as penalty's 23.30
    with pytest.raises(ValueError, match="band 'exact' is not allowed"):
        column("exact", 1, "mpm")


def test_the_band_is_an_option_of_solve(capsys):
    """`--band linearised` reaches the run: the same column from the command line, recorded."""
    import json

    from studies.cli import main
    assert main(["solve", "--problem", "column", "--method", "ibm", "--kinematics", "large", "--steps", "20",
                 "--nu", "0", "--load", "40000", "--width", "10", "--height", "50", "--cell", "6.25", "--ppc", "2",
                 "--angle", "30", "--offset", "0.3", "0.2", "--basis", "mpm", "--band", "linearised", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["band"] == "linearised" and record["step_cuts"] == 0 and len(record["newton_iterations"]) == 20
    assert abs(record["height_final"] - 23.303) < 0.01 and abs(record["err_sigma_ample"] - 0.0381) < 5e-4


def test_material_points_split_by_the_nodes_they_use_give_the_same_forces_tangent_and_state():
    """A GIMP-like window of 16 nodes where most points use 4 (one wide domain widens it for all):
    split, the points carry 4, 6 or 16 nodes, and forces, tangent and the merged response equal the
    whole set's to round-off, with 7 times fewer triplets."""
    from ibm.models.constitutive import undeformed
    from ibm.large.equilibrium import merged, split_by_columns
    from ibm.large.kinematics import gradient_operator
    rng = np.random.default_rng(4)
    n, k = 200, 16
    nodes = rng.integers(0, 60, (n, 1)) + np.arange(k)[None, :]                    # (n, 16) distinct per point
    S, dS = rng.random((n, k)), 1e-2 * rng.standard_normal((n, k, 2))
    uses = np.full((n, k), False)
    uses[:, :4] = True                                                              # most points: 4 nodes
    uses[:40, 4:6] = True                                                           # some: 6
    uses[:3] = True                                                                 # three: all 16
    S, dS = np.where(uses, S, 0.0), np.where(uses[:, :, None], dS, 0.0)
    dofs = (2 * nodes[:, :, None] + np.arange(2)).reshape(n, -1)
    model = Hencky(1e4, 0.3)
    whole = PointSet(dofs, gradient_operator(S, dS), rng.random(n) + 0.5, undeformed(n), part=np.arange(n))
    parts = split_by_columns(whole)
    assert sorted(p.dofs.shape[1] for p in parts) == [8, 12, 32]
    dU = 1e-3 * rng.standard_normal(2 * (60 + k))
    a, b = evaluate(model, [whole], dU), evaluate(model, parts, dU)
    size = len(dU)
    assert np.abs(a.force - b.force).max() <= 1e-12 * np.abs(a.force).max()
    Ka, Kb = a.tangent(size), b.tangent(size)
    assert abs(Ka - Kb).max() <= 1e-12 * abs(Ka).max()
    assert len(triplets([whole])[0]) >= 7 * len(triplets(parts)[0])
    response = merged(parts, b.responses, n)
    assert np.abs(response.sigma - a.responses[0].sigma).max() <= 1e-12 * np.abs(a.responses[0].sigma).max()
    assert np.abs(response.state.F - a.responses[0].state.F).max() <= 1e-15
    with pytest.raises(ValueError, match="takes a plain point set"):
        split_by_columns(PointSet(dofs, whole.G, whole.volume, whole.state, np.zeros((n, 2, 2))))


def test_reduced_pattern_is_kept_while_the_points_keep_their_nodes():
    """`of(previous=...)` returns the last step's pattern when the DOF rows, active DOFs and T are the
    same; new weights of T rebuild it with the same sparsity; another DOF row is another structure."""
    rng = np.random.default_rng(2)
    n_dofs, n_points, m = 40, 30, 8
    dofs = np.stack([rng.choice(n_dofs, m, replace=False) for _ in range(n_points)])
    model = Hencky(1e4, 0.3)
    points = PointSet(dofs, rng.standard_normal((n_points, 4, m)) * 1e-2, np.ones(n_points), model.initial(n_points))
    active = np.arange(n_dofs)
    T = sp.eye(n_dofs, format="csr")[:, :36]
    first = ReducedPattern.of([points], active, n_dofs, T)
    assert ReducedPattern.of([points], active, n_dofs, T.copy(), previous=first) is first
    weighted = T.copy()
    weighted.data[:5] *= 0.5
    rebuilt = ReducedPattern.of([points], active, n_dofs, weighted, previous=first)
    assert rebuilt is not first and first.same_structure([points], active, weighted)
    assert np.array_equal(rebuilt.indptr, first.indptr) and np.array_equal(rebuilt.indices, first.indices)
    moved = dofs.copy()
    moved[0, 0] = next(k for k in range(n_dofs) if k not in dofs[0])
    other = PointSet(moved, points.G, points.volume, points.state)
    assert not first.same_structure([other], active, T)
    assert not first.same_structure([points], active[:-1], T[:-1])


@pytest.mark.parametrize("method", ["ibm", "lagrange"])
def test_pardiso_keeps_its_analysis_from_step_to_step_with_the_same_bits(method, monkeypatch):
    """The small-strain footing (its points never move). The IBM's Cholesky: every solve after the first
    refactors on the first's ordering and symbolic factors, over all 12 steps. Lagrange's saddle system
    (symmetric indefinite: PARDISO's analysis scales and matches on the values) is analysed afresh at
    each step. Either way the load curve has the same bits as a run that analyses each step afresh."""
    import ibm.large.loadsteps
    from ibm.solvers import backends as solvers
    from studies.problems.footing import run_footing

    def run(counts):
        newton = ibm.large.loadsteps.newton

        def counted(*args, **kwargs):
            solution = newton(*args, **kwargs)
            counts.append((solution.info["reused_analyses"], solution.iterations))
            return solution
        with monkeypatch.context() as patch, solvers.choice("pardiso"):
            patch.setattr(ibm.large.loadsteps, "newton", counted)
            return run_footing(method, offset=(0.0, 0.0), B_over_h=4, width_over_B=3.0, depth_over_B=2.0, steps=12)

    kept, fresh = [], []
    curve = run(kept)
    monkeypatch.setattr(ReducedPattern, "same_structure", lambda self, sets, active, T: False)
    again = run(fresh)
    within_steps = sum(i - 1 for _, i in kept)
    assert sum(r for r, _ in kept) == (sum(i for _, i in kept) - 1 if method == "ibm" else within_steps)
    assert sum(r for r, _ in fresh) == sum(i - 1 for _, i in fresh) and len(kept) == 12
    assert np.array_equal(curve["q"], again["q"]) and curve["q_over_c"] == again["q_over_c"]
