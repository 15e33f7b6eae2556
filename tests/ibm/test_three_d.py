"""The 3D core: trilinear grid, structured CSR, Dirichlet products of planes, polyhedral band
and face quadrature, material points, and the seed's validation in 3D (confined block)."""

from functools import lru_cache
from itertools import combinations

import numpy as np
import pytest
import scipy.sparse as sp

from ibm import dirichlet
from ibm.quadrature import moment_fitting
from ibm.geometry import polytope
from ibm.discretise.assembly import GridMatrix, strain_matrix, voigt
from ibm.geometry.frames import frame_3d
from ibm.exceptions import InputError
from ibm.discretise.grid import Grid
from ibm.models.elastic import Elastic
from ibm.implicit_boundary import solve_ibm
from ibm.small.model import Loads, build_model
from ibm.geometry.polyhedron import FACES, band_quadrature, box, cell_rule, check_delta, face_quadrature, material_points
from ibm.solvers.rigid_modes import free_modes

H = 10.0
KINDS = ("roller", "roller", "traction", "roller", "roller", "roller")   # base, right, top, left, front, back
ORIENTATIONS = [(90.0, 0.0), (45.0, 0.0), (30.0, 20.0), (17.3, 41.9)]   # the last: a random one
OFFSET = np.array([0.37, 0.29, 0.11])


def block(theta=30.0, tilt=20.0, kinds=KINDS, h=H, side=100.0):
    return box((side, side, side), kinds, frame_3d(theta, tilt), OFFSET * h)


def test_trilinear_partition_of_unity_and_linear_reproduction():
    grid = Grid(2.5, (-3, 4, 1), (4, 3, 5))
    x = grid.origin + np.random.default_rng(0).random((400, 3)) * np.array(grid.shape) * grid.h
    cells = grid.locate(x)
    N, dN = grid.shape_functions(x, cells)
    nodes = grid.nodes()[grid.cell_nodes(cells)]                              # (n, 8, 3)
    assert np.abs(N.sum(axis=1) - 1).max() < 1e-14
    assert np.abs(dN.sum(axis=1)).max() < 1e-14
    assert np.abs(np.einsum("pi,pid->pd", N, nodes) - x).max() < 1e-12
    assert np.abs(np.einsum("pij,pik->pjk", dN, nodes) - np.eye(3)).max() < 1e-13
    # ids: first axis fastest, and cell coordinates invert cell ids
    assert np.array_equal(grid.cell_coordinates(cells), np.floor((x - grid.origin) / grid.h).astype(int))
    assert len(grid.nodes()) == grid.n_nodes == 5 * 4 * 6


def test_strain_operator_of_a_linear_field_is_its_strain():
    grid = Grid(1.0, (0, 0, 0), (2, 2, 2))
    G = np.random.default_rng(1).normal(size=(3, 3))
    x = np.random.default_rng(2).random((20, 3)) * 2
    cells = grid.locate(x)
    N, dN = grid.shape_functions(x, cells)
    U = (grid.nodes() @ G.T).ravel()                                         # u = G x at the nodes
    B = strain_matrix(N, dN)                                                 # (n, 6, 24)
    eps = np.einsum("prk,pk->pr", B, U[grid.cell_dofs(cells)])
    assert np.abs(eps - voigt(np.broadcast_to(G, (20, 3, 3)))).max() < 1e-12


def test_structured_csr_equals_coo_assembly_in_3d():
    grid = Grid(1.0, (0, 0, 0), (4, 3, 5))
    rng = np.random.default_rng(1)
    cells = rng.choice(grid.n_cells, 30, replace=False)
    cells = np.concatenate([cells, cells[:7]])                               # repeated cells sum
    blocks = rng.random((len(cells), 24, 24))
    dofs = grid.cell_dofs(cells)
    rows, columns = np.repeat(dofs, 24, axis=1).ravel(), np.tile(dofs, (1, 24)).ravel()
    A = sp.coo_matrix((blocks.ravel(), (rows, columns)), shape=(3 * grid.n_nodes,) * 2).tocsr()
    M = GridMatrix(grid, cells).add(cells, blocks).tocsr()
    assert abs(M - A).max() < 1e-13 and M.nnz == A.nnz and M.has_sorted_indices
    keep_rows, keep_columns = np.unique(dofs)[::2], np.unique(dofs)[1::3]
    part = GridMatrix(grid, cells).add(cells, blocks).tocsr(keep_rows, keep_columns)
    assert abs(part - A[keep_rows][:, keep_columns]).max() < 1e-13


@pytest.mark.parametrize("theta, tilt", ORIENTATIONS[2:])
def test_roller_products_hold_every_normal_on_its_face(theta, tilt):
    """n_k^T D = 0 on roller face k, also where other bands cross it; D = I beyond the bands;
    grad D by central differences."""
    body = block(theta, tilt, kinds=("fixed",) + KINDS[1:])
    delta = 2.0
    rng = np.random.default_rng(3)
    for k in range(6):
        if body.kinds[k] == "traction":
            continue
        face = body.faces[k]
        a, b = rng.random((2, 200, 1))
        # points on the face, crowded towards its edges and corners where two or three bands meet
        a, b = a ** 3, 1 - b ** 3
        x = face[0] + a * (face[1] - face[0]) + b * (face[3] - face[0])
        Dm, _ = dirichlet.matrix(body, x, delta)
        if body.kinds[k] == "fixed":
            assert np.abs(Dm).max() < 1e-12
        else:
            assert np.abs(np.einsum("i,pia->pa", body.normals[k], Dm)).max() < 1e-12
    centre = body.vertices.mean(axis=0)
    Dm, grad = dirichlet.matrix(body, centre[None] + rng.normal(size=(50, 3)), delta)
    assert np.array_equal(Dm, np.broadcast_to(np.eye(3), Dm.shape)) and not grad.any()
    inside = centre + (body.vertices[:8] - centre) * 0.99                      # near the corners: 3 bands
    _, grad = dirichlet.matrix(body, inside, delta)
    step = 1e-6
    for j in range(3):
        e = np.zeros(3)
        e[j] = step
        fd = (dirichlet.matrix(body, inside + e, delta)[0] - dirichlet.matrix(body, inside - e, delta)[0]) / (2 * step)
        assert np.abs(fd - grad[..., j]).max() < 1e-6 * np.abs(grad).max()


def test_material_points_tile_the_body_and_the_cell_rule_is_exact():
    body = block(30.0, 20.0)
    grid = Grid.covering(body, H)
    for ppc in (1, 2):
        points = material_points(body, grid, ppc)
        assert abs(points.volume.sum() - 1e6) < 1e-9 * 1e6
        # first moments: the centroids are exact for linear integrands
        centroid = (points.volume[:, None] * points.x).sum(axis=0) / points.volume.sum()
        assert np.abs(centroid - body.vertices.mean(axis=0)).max() < 1e-9 * 100
    rule = cell_rule(body, grid)
    # degree <= 2 per axis, 4 in all (as B^T C B), against the body's own tetrahedra

    def f(x):
        return x[:, 0] ** 2 * x[:, 1] ** 2 - 3 * x[:, 1] * x[:, 2] ** 2 * x[:, 0] + x[:, 2] ** 2 + 1.0

    lo, hi = body.bounds()
    x, w, _ = polytope.quadrature(*body.clip(*polytope.box_simplices(lo[None], hi[None])), 4)
    exact = np.sum(w * f(x))
    assert abs(np.sum(rule.weight * f(rule.x)) - exact) < 1e-11 * np.sum(w * np.abs(f(x)))


def test_moment_fitted_rules_are_exact_on_clipped_pieces():
    lo = np.random.default_rng(4).random((30, 3)) * 5
    vertices, owner = polytope.box_simplices(lo, lo + 1.0)
    normal = np.array([0.3, -0.5, 0.81])
    normal /= np.linalg.norm(normal)
    middle = (lo + 0.5) @ normal
    for low, high in ((middle[0] - 0.2, middle[0] + 1e-5), (middle[3] - 0.4, middle[3] + 0.3)):
        pieces = polytope.slab(vertices, owner, normal, low, high)
        chained = polytope.clip(*polytope.clip(vertices, owner, -normal, -low), normal, high)
        frame = np.vstack([normal, np.linalg.qr(np.column_stack([normal, np.eye(3)]))[0][:, 1:3].T])
        x, w, which, _, _ = moment_fitting.fitted(*pieces, frame, 8)

        def f(y):
            return y[:, 0] ** 4 * y[:, 1] ** 2 * y[:, 2] ** 2 - 3 * y[:, 1] ** 5 + y[:, 2]

        reference = []
        for v, o in (pieces, chained):
            xq, wq, oq = polytope.quadrature(v, o, 8)
            reference.append(np.bincount(oq, wq * f(xq), minlength=30))
        fitted = np.bincount(which, w * f(x), minlength=30)
        scale = np.abs(reference[1]).max()
        assert np.abs(reference[0] - reference[1]).max() < 1e-9 * scale    # one slab cut = two plane cuts
        assert np.abs(fitted - reference[1]).max() < 1e-9 * scale


OPPOSITE = {0: 2, 2: 0, 1: 3, 3: 1, 4: 5, 5: 4}          # a box's faces (FACES order) and the ones facing them


def test_band_regions_integrate_polynomials_of_their_degree_exactly():
    """Every band region R_S of the 3D block (slabs, the edges where two bands meet, the corners of
    three) integrates a monomial of its rule's degree 4 |S| + 4 in the faces' distances exactly:
    s_a^4 s_b^2 s_c^2, s_a^5 s_b^4 s_c^3, s_a^6 s_b^5 s_c^5 over [0, delta]^|S| times the free axes'
    spans (delta from an essential face's end, 0 from a free one), summed over the cells' pieces at
    (30, 20), where the grid cuts every region. Measured 1.7e-13 at worst."""
    h, delta, side = 20.0, 3.0, 100.0
    body = block(30.0, 20.0, h=h)
    band = band_quadrature(body, Grid.covering(body, h), delta)
    walls = [wall.pieces[0] for wall in body.walls]
    s = body.signed_distance(band.x)                                          # (n, 6)
    exponents = {1: (4, 2, 2), 2: (5, 4, 3), 3: (6, 5, 5)}
    checked = 0
    for size in (1, 2, 3):
        for S in combinations(range(len(walls)), size):
            faces = [walls[w] for w in S]
            if any(OPPOSITE[f] in faces for f in faces):
                continue                                                      # opposite bands never meet here
            axes = faces + [f for f in (0, 1, 4) if f not in faces and OPPOSITE[f] not in faces]
            exact = 1.0
            for k, (f, e) in enumerate(zip(axes, exponents[size])):
                low = 0.0 if k < size else (delta if f in walls else 0.0)
                high = delta if k < size else side - (delta if OPPOSITE[f] in walls else 0.0)
                exact *= (high ** (e + 1) - low ** (e + 1)) / (e + 1)
            on = band.region == sum(1 << w for w in S)
            integrand = np.prod([s[on, f] ** e for f, e in zip(axes, exponents[size])], axis=0)
            assert abs(np.sum(band.weight[on] * integrand) / exact - 1) < 1e-11, faces
            checked += 1
    assert checked == 5 + 8 + 4                                                # slabs, edges, corners


def test_band_and_face_quadrature_measure_their_regions():
    body = block(30.0, 20.0)
    grid = Grid.covering(body, 2 * H)
    delta = 0.5
    band = band_quadrature(body, grid, delta)
    # five roller faces of 100 x 100, bands of width delta, overlapping along the 8 edges
    # between rollers (4 around the base's sides... counted exactly by inclusion-exclusion)
    edges, corners = 8, 4
    expected = 5 * 100 * 100 * delta - edges * 100 * delta ** 2 + corners * delta ** 3
    assert abs(band.weight.sum() - expected) < 1e-10 * expected
    top = face_quadrature(body, grid, FACES.index("top"), delta)
    assert abs(top.weight.sum() - 1e4) < 1e-9 * 1e4
    assert np.abs(body.signed_distance(top.x)[:, 2]).max() < 1e-9
    with pytest.raises(InputError, match="band width delta=60"):
        check_delta(body, 60.0)


def test_simplex_rules_integrate_the_bands_and_the_body_as_the_fitted_ones():
    """rule="simplex" (positive weights, points inside the pieces) against the fitted rules: the same
    band measure by inclusion-exclusion, and the same integral of a quartic over the body."""
    from ibm.geometry.polyhedron import body_quadrature
    body = block(30.0, 20.0)
    grid = Grid.covering(body, 2 * H)
    delta = 0.5
    band = band_quadrature(body, grid, delta, rule="simplex", degree=2)
    expected = 5 * 100 * 100 * delta - 8 * 100 * delta ** 2 + 4 * delta ** 3
    assert abs(band.weight.sum() - expected) < 1e-10 * expected and band.weight.min() > 0
    assert body.signed_distance(band.x).min() > -1e-9                       # inside the body

    def f(x):
        return (x[:, 0] - 20) ** 2 * (x[:, 1] + 5) * x[:, 2] + x[:, 1] ** 4
    fitted, simplex = (body_quadrature(body, grid, 4, delta, rule=rule) for rule in ("fitted", "simplex"))
    exact = np.sum(fitted.weight * f(fitted.x))
    assert abs(np.sum(simplex.weight * f(simplex.x)) - exact) < 1e-10 * abs(exact)
    assert simplex.weight.min() > 0 and len(simplex.weight) > len(fitted.weight)
    with pytest.raises(InputError, match="band rule 'gauss' is not allowed; allowed: 'fitted', 'simplex'"):
        band_quadrature(body, grid, delta, rule="gauss")
    with pytest.raises(InputError, match="body rule 'gauss' is not allowed; allowed: 'fitted', 'simplex'"):
        body_quadrature(body, grid, 4, delta, rule="gauss")


def test_free_rigid_motions_are_named_in_3d():
    body = block(30.0, 20.0, kinds=("roller",) + ("traction",) * 5)
    model = build_model(body, Elastic(1e4, 0.3), Loads(tractions={k: (lambda x: np.zeros_like(x)) for k in range(1, 6)}), H)
    from ibm.small import forms

    K = forms.stiffness(model, model.points.quadrature())
    dofs = np.flatnonzero(np.abs(K.diagonal()) > 0)
    assert len(free_modes(K[dofs][:, dofs], model.grid, dofs)) == 6             # nothing holds it yet


def confined_block(theta, tilt, p=10.0, material=Elastic(1e4, 0.3), frame=None, corner=None, delta_rel=1e-5):
    """(err_u, err_sigma) of the IBM on the seed's confined block placed at (theta, tilt) with its
    base corner at OFFSET h, or by `frame` (3, 3) and `corner` (3,) when given."""
    frame = frame_3d(theta, tilt) if frame is None else frame
    corner = OFFSET * H if corner is None else corner
    body = box((100.0, 100.0, 100.0), KINDS, frame, corner)
    outward_top = -body.normals[FACES.index("top")]
    loads = Loads(tractions={2: lambda x: np.broadcast_to(-p * outward_top, x.shape).copy()})
    model = build_model(body, material, loads, H, 1)
    solution = solve_ibm(model, delta_rel=delta_rel, estimate_condition=False)
    R = body.frame
    strain = -p / material.M
    local = (model.points.x - corner) @ R
    u = np.outer(strain * local[:, 1], R[:, 1])
    V = model.points.volume
    err_u = np.sqrt(np.sum(V * np.sum((solution.u - u) ** 2, axis=1)) / np.sum(V * np.sum(u ** 2, axis=1)))
    s = np.einsum("i,pij,j->p", R[:, 1], solution.sigma, R[:, 1])
    err_sigma = np.sqrt(np.sum(V * (s + p) ** 2) / np.sum(V * p ** 2))
    return err_u, err_sigma


@pytest.mark.slow
@pytest.mark.parametrize("theta, tilt", ORIENTATIONS)
def test_seed_table_in_3d(theta, tilt):
    """The seed's confined block as a 100^3 cube at h = 10, one point per cell, delta = 1e-5 h:
    at or below the paper's 2D errors at every orientation (90: 5.55e-5, 8.25e-6; 30: 3.14e-3,
    4.48e-3), and as small as the 2D code's (1.88e-7, 8.9e-7), whatever the tilt."""
    err_u, err_sigma = confined_block(theta, tilt)
    assert err_u < 6e-7 and err_sigma < 3e-6, (err_u, err_sigma)


TURN_Z = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])          # 90 degrees about z
TURN_X = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])          # 90 degrees about x
MIRROR = np.diag([-1.0, 1, 1])                                     # x -> -x


@lru_cache(maxsize=1)
def _unmapped_block_errors() -> np.ndarray:
    return np.array(confined_block(30.0, 20.0, delta_rel=1e-3))


@pytest.mark.slow
@pytest.mark.parametrize("symmetry", ["turn about z", "turn about x", "mirror"])
def test_ibm_errors_are_invariant_under_the_grids_symmetries_in_3d(symmetry):
    """The grid's nodes are h Z^3, mapped to themselves by quarter turns about the axes and by
    mirrors in the coordinate planes: the block at (30, 20) so mapped (its base corner too) has the
    same errors to the solve's rounding. A mirror reverses the box's handedness, so its image is
    the box whose local zeta runs the other way from the image of the far corner (front and back,
    both rollers, trade places). delta = 1e-3 h, so that the errors (1.9e-5, 9.4e-5) lie well above
    rounding and depend on the placement: measured 1.2e-9 and 5e-11 apart (relative) after a turn,
    4.9e-5 and 7.9e-4 apart after a shift by 0.013 h."""
    R, corner = frame_3d(30.0, 20.0), OFFSET * H
    if symmetry == "mirror":
        frame, corner_mapped = MIRROR @ R @ np.diag([1.0, 1, -1]), MIRROR @ (corner + R[:, 2] * 100.0)
    else:
        turn = TURN_Z if symmetry == "turn about z" else TURN_X
        frame, corner_mapped = turn @ R, turn @ corner
    reference = _unmapped_block_errors()
    mapped = np.array(confined_block(0, 0, frame=frame, corner=corner_mapped, delta_rel=1e-3))
    assert np.abs(mapped / reference - 1).max() < 1e-8, (mapped, reference)


def test_fem_hex_and_ibm_from_the_command_line(capsys):
    import json

    from studies.cli import main

    assert main(["solve", "--dim", "3", "--problem", "confined-block", "--method", "fem", "--angle", "30",
                 "--tilt", "20", "--cell", "20", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["dim"] == 3 and record["ndof"] == 468
    errors = np.array([record[k] for k in ("err_u", "err_sigma", "err_l2", "err_energy")])
    assert np.all(np.isfinite(errors)) and errors.max() < 1e-12


@pytest.mark.parametrize("argv, message", [
    (["--dim", "4"], "--dim 4 is not allowed; allowed: 2 or 3"),
    (["--tilt", "3"], "tilt 3 needs dim = 3"),
    (["--offset", "0.1", "0.2", "0.3"], "--offset takes two numbers in 2D"),
    (["--dim", "3", "--offset", "0.1", "0.2"], "--offset takes three numbers in 3D"),
    (["--dim", "3", "--method", "nodal"], "method 'nodal' needs every essential face on a grid plane; face 0 (normal"),
    (["--dim", "3", "--method", "ibn"], "unknown method 'ibn' (did you mean 'ibm'?); allowed with dim = 3: ibm, "
                                        "ibm-limit, penalty, nitsche, lagrange, nodal, fem"),
    (["--dim", "3", "--method", "lagrange-nodal"], "method 'lagrange-nodal' refuses 3D cases (dim = 3): its collocation "
                                                   "points are the grid-line crossings of straight edges"),
    (["--dim", "3", "--problem", "footing"], "problem 'footing' is not available with dim = 3; allowed:"),
    (["--dim", "3", "--kinematics", "large"], "problem 'confined-block' has no exact finite-strain solution in 3D "
                                              "(dim = 3): kinematics 'large' is not available for it; allowed: "
                                              "'small' ('large' for column)"),
])
def test_three_d_options_are_checked_in_one_line(argv, message, capsys):
    from studies.cli import main

    assert main(["solve", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_nodal_constraints_pass_the_3d_patch_test_on_grid_planes(capsys):
    """The confined block at (90, 0) with its faces on grid planes (offset 0): the nodes on each
    roller face keep their normal component, and the uniform state is exact (measured 1.7e-14)."""
    import json

    from studies.cli import main

    assert main(["solve", "--dim", "3", "--problem", "confined-block", "--method", "nodal", "--angle", "90",
                 "--offset", "0", "0", "0", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["ndof"] == 3388 and max(record["err_u"], record["err_sigma"], record["err_l2"]) < 1e-12


def test_three_d_vtk_files(tmp_path, capsys):
    import json

    import meshio

    from studies.cli import main

    assert main(["solve", "--dim", "3", "--method", "fem", "--cell", "25", "--angle", "30", "--tilt", "20",
                 "--vtk", str(tmp_path / "out"), "--json"]) == 0
    points, grid, body = (meshio.read(p) for p in json.loads(capsys.readouterr().out)["vtk"])
    assert points.point_data["displacement"].shape == (len(points.points), 3)
    assert np.abs(points.point_data["displacement_error"]).max() < 1e-12      # fem is exact here
    assert grid.cells[0].type == "hexahedron" and body.cells[0].data.shape == (6, 4)
    assert list(body.cell_data["face_kind"][0]) == [2, 2, 1, 2, 2, 2]


@pytest.mark.slow
def test_a_whole_cell_shift_changes_nothing_in_3d():
    """Grid symmetry: the body moved by whole cells along each axis gives the same solution (the
    errors are relative to the exact field, so they agree to the solve's rounding, ~1e-11 of it)."""
    from studies.run.solid import solve_box_case

    records = [solve_box_case("confined-block", "ibm", 30.0, 20.0, offset, 20.0)
               for offset in ((0.37, 0.29, 0.11), (2.37, -1.71, 3.11))]
    for key in ("err_u", "err_sigma", "err_l2", "err_energy"):
        assert abs(records[0][key] - records[1][key]) <= 1e-10, key
    assert records[0]["ndof"] == records[1]["ndof"]


@pytest.mark.slow
@pytest.mark.parametrize("method, theta, tilt, cell, gate", [
    *[(method, theta, tilt, H, 1e-10) for method in ("nitsche", "lagrange", "fem") for theta, tilt in ORIENTATIONS],
    ("penalty", 30.0, 20.0, 10.0, 3e-7),            # O(1 / beta0): 2.47e-7 at every orientation
    ("ibm-limit", 30.0, 20.0, 10.0, 1e-6),          # O(delta) like the band form: 5e-8 (u) to 3.8e-7 (energy)
])
def test_other_methods_on_the_seed_block_in_3d(method, theta, tilt, cell, gate):
    """The seed's table in 3D at h = 10, one point per cell, at every orientation: Nitsche and
    Lagrange multipliers pass the patch test (measured 1.7e-14 to 7.2e-13, and 3.6e-13 to 8.9e-13),
    the hexahedral reference is exact (1.2e-14); penalty is its O(1 / beta0) as in 2D."""
    from studies.run.solid import solve_box_case

    record = solve_box_case("confined-block", method, theta, tilt, (0.37, 0.29, 0.11), cell)
    errors = np.array([record[k] for k in ("err_u", "err_sigma", "err_l2", "err_energy")])
    assert np.all(np.isfinite(errors)) and errors.max() < gate, record


def band_to_limit_gaps_3d(kinds, ridges: bool = True, deltas=np.array([1e-1, 1e-2, 1e-3])):
    """||K_band(delta) - K_limit(delta)|| / ||K_points|| on a cube at (30, 20), h = 20 (delta relative to h)."""
    import scipy.sparse.linalg as spla

    from baselines import boundary, limit
    from ibm.small import forms

    body = box((100.0, 100.0, 100.0), kinds, frame_3d(30.0, 20.0), (3.7, 2.9, 1.3))
    model = build_model(body, Elastic(1e4, 0.3), Loads(), 20.0, 1)
    bulk, points = boundary.bulk_system(model), model.points.quadrature()
    K0 = forms.stiffness(model, points)
    gaps = []
    for delta in deltas * model.grid.h:
        band = band_quadrature(body, model.grid, delta)
        K_band = forms.corrected_stiffness(model, points, band,
                                           lambda x, region=None: dirichlet.matrix(body, x, delta, region=region))
        K_limit = limit.limit_stiffness(model, bulk, delta)
        if not ridges:
            K_limit = K_limit - limit.corner_terms(model)
        gaps.append(spla.norm(K_band - K_limit) / spla.norm(K0))
    return deltas, np.array(gaps)


@pytest.mark.slow
@pytest.mark.parametrize("kinds", [("roller", "roller", "traction", "roller", "roller", "roller"),
                                   ("fixed", "roller", "traction", "fixed", "roller", "fixed")])
def test_limit_form_is_the_limit_of_the_band_stiffness_in_3d(kinds):
    """Every O(1) term of the band form is in ibm-limit's face and ridge terms: the gap falls linearly
    in delta (measured slopes 0.998 and 0.999, gap 4.7e-4 and 6.2e-4 at delta = 1e-3 h)."""
    deltas, gaps = band_to_limit_gaps_3d(kinds)
    slope = np.polyfit(np.log(deltas), np.log(gaps), 1)[0]
    assert gaps[-1] < 1e-3 and abs(slope - 1) <= 0.05, (gaps, slope)


def test_the_ridge_terms_carry_an_order_one_part():
    """Without the line terms along ridges joining two essential faces the gap stays O(1) (4.6e-2)."""
    _, gaps = band_to_limit_gaps_3d(("roller", "roller", "traction", "roller", "roller", "roller"), ridges=False,
                                    deltas=np.array([1e-3]))
    assert gaps[0] > 1e-2, gaps
