"""One 3D case: a box problem (studies.problems.box_fields) placed at (theta, tilt), solved by a grid method
or the body-fitted hexahedral reference, with the errors every method reports.

    ibm-study solve --dim 3 --problem confined-block --method ibm --angle 30 --tilt 20 --json

Methods in 3D: those whose declaration supports "3d" (baselines.registry.in_3d), each solving the
placed model as in 2D; a body-fitted method (fem) meshes the box itself (baselines.fem.hexahedra, Hex1).
The others refuse in one line with their reason. Errors: at the material
points (err_u, err_sigma of sigma_eta_eta, err_sigma_fro, *_max) and by quadrature over the
body (err_l2, err_energy), the same definitions as in 2D (ibm.norms).
"""
from __future__ import annotations

from pathlib import Path
from time import perf_counter

import numpy as np

from baselines.fem.hexahedra import solve_box
from baselines.registry import METHODS, check_band, in_3d, in_load_steps, require, treatment
from ibm.exceptions import InputError
from ibm.geometry.frames import frame_3d
from ibm.geometry.polyhedron import box
from ibm.large.loadsteps import Setup, run
from ibm.models.constitutive import Hencky
from ibm.models.elastic import Elastic
from ibm.norms import norm_errors, point_errors, pointwise_relative
from ibm.small.model import build_model
from ibm.solvers import backends as solvers
from studies.problems.box_fields import BOXES, FINITE_STRAIN, place_box
from studies.problems.library import Parameters
from studies.problems.manufactured import FACES
from studies.run.large import errors, penetration, placed_exact, summary


def solve_box_case(problem: str, method: str, angle: float, tilt: float, offset, cell: float, ppc: int = 1,
                   E: float = 1e4, nu: float = 0.3, load: float = 10.0, size=(100.0, 100.0, 100.0),
                   vtk: str | None = None, solver: str = "auto", keep_fields: bool = False,
                   **method_parameters) -> dict:
    """Solve one 3D case; a dict of its settings, sizes, errors and times (JSON-ready). With `vtk`
    (a folder), the points, grid and body are written there too (write_vtk); record["vtk"] lists the files.
    With keep_fields, record["fields"] holds the per-point arrays (point_fields; not JSON-able).
    method_parameters: the method's declared parameters (None: the default)."""
    start = perf_counter()
    if problem not in BOXES:
        raise InputError(f"problem {problem!r} is not allowed in 3D; allowed: {', '.join(BOXES)}")
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; allowed in 3D: {', '.join(in_3d())}")
    require(method, "3d")
    METHODS[method].check(method_parameters)
    offset = tuple(float(v) for v in offset)
    if len(offset) != 3:
        raise InputError(f"--offset takes three numbers in 3D (ox oy oz); got {len(offset)}")
    parameters = Parameters(Elastic(E, nu), load, width=size[0], height=size[1], depth=size[2])
    placed = place_box(problem, parameters, angle, tilt, offset, cell)

    model = build_model(placed.body, parameters.material, placed.loads, cell, ppc)
    with solvers.choice(solver):
        evaluate, info, delta, u_h, sigma_h = _solve(model, placed, METHODS[method], cell, method_parameters)
    u, sigma, zz = placed.exact(model.points.x)
    errors = point_errors(model.points.volume, u_h, u, sigma_h, sigma, sigma_h[:, 2, 2], zz, placed.direction)
    errors.update(norm_errors(placed.body, model.grid, parameters.material, evaluate, placed.exact, delta=delta))
    files, fields = {}, None
    if vtk is not None or keep_fields:
        fields = point_fields(model, placed, u_h, sigma_h)
    if vtk is not None:
        stem = f"{problem}_{method}_angle{angle:g}_tilt{tilt:g}_h{cell:g}"
        files = {"vtk": [str(p) for p in write_vtk(vtk, stem, model.grid, fields)]}
    return {"problem": problem, "method": method, "dim": 3, "angle": angle, "tilt": tilt, "cell": cell, "ppc": ppc,
            "offset": list(offset), "ndof": int(info["ndof"]), "n_points": len(model.points),
            "n_band_points": int(info.get("n_band_points", 0)), **({"delta": delta} if delta else {}),
            "solver": info.get("solver", "direct (scikit-fem)" if METHODS[method].supports.body_fitted else solver),
            **({"amg_iterations": info["amg_iterations"]} if "amg_iterations" in info else {}),
            **({"time_solve": info["time_solve"]} if "time_solve" in info else {}),
            **errors, "time_s": perf_counter() - start, **files, **({"fields": fields} if keep_fields else {})}


def _solve(model, placed, method, cell, parameters):
    """evaluate, info, delta (None without bands), u and sigma at the points of one method's solution."""
    if method.supports.body_fitted:
        evaluate, info = _fem(placed, cell)
        return (evaluate, info, None, *evaluate(model.points.x, model.points.cells)[:2])
    solution = method(model, **parameters)
    return solution.evaluate, solution.info, solution.info.get("delta"), solution.u, solution.sigma


def _fem(placed, cell: float):
    """The hexahedral reference as an evaluator (x, cells) -> (u, sigma, sigma_zz), and its info."""
    field, kinds = placed.field, placed.body.kinds
    prm = placed.parameters

    def traction(k, xl):
        return field.traction(FACES[k], xl[:, 0], xl[:, 1], xl[:, 2], prm)

    def body_force(xl):
        return field.body_force(xl[:, 0], xl[:, 1], xl[:, 2], prm)

    size = (prm.width, prm.height, prm.depth)
    solution = solve_box(size, placed.frame, placed.corner, kinds, prm.material, cell,
                         body_force=body_force, traction=traction)

    def evaluate(x, cells=None, region=None):     # body-fitted: no bands, the region is not needed
        u, sigma = solution.evaluate(x)
        return u, sigma, sigma[:, 2, 2]

    return evaluate, {"ndof": solution.ndof}


def run_box_large(problem: str, method: str, angle: float, tilt: float, offset, cell: float, ppc: int = 2,
                  steps: int = 10, E: float = 1e4, nu: float = 0.0, load: float = 40000.0,
                  size=(10.0, 50.0, 10.0), solver: str = "auto", band: str = "auto", basis: str = "gimp",
                  locking: str = "none", checkpoint: str | Path | None = None, **method_parameters) -> dict:
    """One 3D large-deformation case: the load-step driver (ibm.large.loadsteps) on the box placed at
    (theta, tilt), Hencky elasticity, the point basis `basis` (mpm or gimp), `locking` none or fbar
    (F-bar, with mpm); its errors against the exact finite-strain solution (studies.problems.finite_strain)
    as in 2D (studies.run.large.errors), per step and at the end. checkpoint: a file every converged
    step is saved to; a run that finds it resumes from it, to the same record (time_s aside).

    The boxes with an exact finite-strain solution: studies.problems.box_fields.FINITE_STRAIN."""
    start = perf_counter()
    if problem not in FINITE_STRAIN:
        raise InputError(f"problem {problem!r} has no exact finite-strain solution in 3D; allowed: "
                         f"{', '.join(FINITE_STRAIN)}")
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; allowed for large kinematics in 3D: "
                         f"{', '.join(in_load_steps(3))}")
    require(method, "load-steps-3d")
    if not load > 0:
        raise InputError(f"load {load} is not allowed for large kinematics; it must be > 0 (compressive)")
    offset = np.asarray(offset, float)
    if offset.shape != (3,):
        raise InputError(f"--offset takes three numbers in 3D (ox oy oz); got {offset.size}")
    material = Hencky(E, nu)
    R, corner = frame_3d(angle, tilt), offset * cell
    body = box(size, BOXES[problem][1], R, corner)
    loading, exact = FINITE_STRAIN[problem](size, load, R)
    setup = Setup(body, material, loading, cell, ppc, basis, steps, locking=locking)
    given = {k: v for k, v in method_parameters.items() if k in METHODS[method].names}
    used = METHODS[method].used(given, load_steps=True)
    check_band(band, method, True)
    if METHODS[method].supports.band_kinematics:
        given["band"], used["band"] = band, band

    def after_step(p):
        now = placed_exact(exact(material, p.t), p.X, corner, R)
        return {**errors(now, p.X, p.x, p.sigma, p.V0, R), "penetration": penetration(p.lines, p.x)}

    with solvers.choice(solver):
        progress = run(setup, treatment(method, {k: v for k, v in given.items() if k in used}, dim=3),
                       after_step=after_step, checkpoint=checkpoint)
    return {"problem": problem, "method": method, "dim": 3, "kinematics": "large", "basis": basis, "locking": locking,
            "angle": angle, "tilt": tilt, "cell": cell, "ppc": ppc, "steps": steps, "offset": offset.tolist(), "E": E,
            "nu": nu, "load": load, "size": list(size), **used, **summary(progress, corner, R),
            "time_s": perf_counter() - start}


def point_fields(model, placed, u_h: np.ndarray, sigma_h: np.ndarray) -> dict[str, np.ndarray]:
    """The per-point arrays of a 3D case and its faces:
        x (n, 3), volume (n,), u_h, u (n, 3), sigma_h, sigma (n, 3, 3),
        err_u, err_sigma (n,)     |u_h - u| / max|u| and |s_h - s| / max|s| of the loaded-direction stress
        faces (k, 4, 3), kinds (k,)   the box's faces (corners in order) and their boundary kinds
        grid_h, grid_lower (3,), grid_shape (3,)   the covering grid (ibm.discretise.grid.Grid)"""
    x = model.points.x
    u, sigma, _ = placed.exact(x)
    err_u, err_sigma = pointwise_relative(u_h, u, sigma_h, sigma, placed.direction)
    return {"x": x, "volume": model.points.volume, "u_h": u_h, "u": u, "sigma_h": sigma_h, "sigma": sigma,
            "err_u": err_u, "err_sigma": err_sigma, "faces": np.stack(placed.body.faces),
            "kinds": np.array(placed.body.kinds), "grid_h": np.array(model.grid.h),
            "grid_lower": np.array(model.grid.lower), "grid_shape": np.array(model.grid.shape)}


def write_vtk(folder, stem: str, grid, fields: dict) -> list:
    """ParaView files of a 3D case (meshio, VTU) from its point_fields: STEM_points.vtu (vertex cells
    at the material points: displacement, its exact value and error, stress (3 x 3), its exact value,
    volume, err_u and err_sigma per point as in the error maps), STEM_grid.vtu (the covering grid's
    hexahedra, VTK's node order is ibm.discretise.grid's) and STEM_body.vtu (the faces, their kind as cell data)."""
    import meshio

    from studies.report.vtk import EDGE_KIND_CODES

    folder = Path(folder)      # the caller checked it can be written (studies.run.store.output_folder)
    folder.mkdir(parents=True, exist_ok=True)
    x, u_h, u = fields["x"], fields["u_h"], fields["u"]
    data = {"displacement": u_h, "displacement_exact": u, "displacement_error": u_h - u,
            "stress": fields["sigma_h"].reshape(-1, 9), "stress_exact": fields["sigma"].reshape(-1, 9),
            "volume": fields["volume"], "err_u": fields["err_u"], "err_sigma": fields["err_sigma"]}
    faces = fields["faces"]
    paths = [folder / f"{stem}_{part}.vtu" for part in ("points", "grid", "body")]
    meshio.Mesh(x, [("vertex", np.arange(len(x))[:, None])], point_data=data).write(paths[0])
    meshio.Mesh(grid.nodes(), [("hexahedron", grid.cell_nodes(np.arange(grid.n_cells)))]).write(paths[1])
    corners = faces.reshape(-1, 3)
    meshio.Mesh(corners, [("quad", np.arange(len(corners)).reshape(len(faces), 4))],
                cell_data={"face_kind": [np.array([EDGE_KIND_CODES[str(k)] for k in fields["kinds"]])]}).write(paths[2])
    return paths
