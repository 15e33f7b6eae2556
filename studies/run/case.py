"""One case: spec -> problem -> model -> method -> errors vs exact, as one flat record.

The defaults of CaseSpec are the settings of the seed reproduction, kept here and only here:
- E = 1e4, nu = 0.3, p = 10: the paper gives none; relative errors of this linear
  problem do not depend on E or p, and nu = 0.3 is a typical soil/metal value.
- delta / h = 1e-5: the IBM's error is O(delta) (method notes section 2), so a thin band
  puts all six seed numbers well below the paper's while the (equilibrated) condition
  estimate stays near 1e8-1e9, far from round-off trouble.
- offset (0.37, 0.29): a generic placement, so no boundary lies on a grid line and no
  cut is symmetric; the README's offset sweep shows the numbers barely move with it.
- h = 10 and one point per 10-unit square: the paper's resolution.
- dim = 3 (studies.run.box_case): the box problems as cubes, offset (0.37, 0.29, 0.11) (the seed's and a
  third generic component) unless given.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from time import perf_counter

import numpy as np

from baselines.registry import METHODS, method_parameters
from ibm.discretise.basis import BASES
from ibm.norms import norm_errors, point_errors
from ibm.exceptions import InputError
from ibm.models.elastic import Elastic
from ibm.solvers import backends as solvers
from ibm.small.model import build_model
from studies.problems import ample_collapse, collapse
from studies.problems.library import LOAD_TYPES, Parameters, closest, get_problem, place, plastic
from studies.run.reactions import reaction_error, reaction_records

ANGLE_RANGE = (0.0, 360.0)
MAGNITUDE = 1e100          # the largest load and modulus (and the inverse of the smallest)
KINEMATICS = ("small", "large")
DIMS = (2, 3)
OFFSET_3D = (0.37, 0.29, 0.11)


@dataclass(frozen=True)
class CaseSpec:
    problem: str = "confined-block"
    method: str = "ibm"
    angle: float = 90.0
    cell: float = 10.0
    ppc: int = 1
    offset: tuple[float, float] = (0.37, 0.29)
    E: float = 1e4
    nu: float = 0.3
    load: float = 10.0
    width: float = 100.0
    height: float = 100.0
    load_type: str = "pressure"      # pressure: load is a stress; settlement: load is the top settlement
    kinematics: str = "small"        # small: one linear step (load steps with j2); large: updated Lagrangian, Hencky
    steps: int = 1                   # load steps (large kinematics)
    basis: str = "gimp"              # point basis of large kinematics: mpm or gimp
    band: str = "auto"               # the IBM's band in the load steps: auto, finite or linearised (ibm.large.treatment)
    material: str = "elastic"        # elastic (Hencky at large strain) or j2 (von Mises: radial return at small
                                     # kinematics, exponential map at large)
    yield_stress: float = 0.0        # J2 yield stress (material von-mises; 0 otherwise)
    hardening: float = 0.0           # J2 linear hardening modulus (material von-mises)
    problem_file: str = ""           # a user's problem (studies.problems.problem_file); replaces `problem`
    locking: str = "none"            # none, or fbar (the mean dilatation at small strain, ibm.discretise.locking)
    footing: str = "smooth"          # problem footing: smooth (a roller) or rough (fixed: the soil stuck to it)
    dim: int = 2                     # 2 (plane strain) or 3 (the box problems, studies.run.box_case)
    tilt: float = 0.0                # 3D: the tilt about the body's own xi axis after the angle about z
    solver: str = "auto"             # linear solver (ibm.solvers.backends); amg's results differ within its tolerance
    method_parameters: dict = field(default_factory=dict)   # e.g. {"delta_rel": 1e-5}

    def __post_init__(self):
        if self.dim == 3 and tuple(self.offset) == CaseSpec.offset:   # the 2D default means the 3D one
            object.__setattr__(self, "offset", OFFSET_3D)

    def with_(self, **changes) -> "CaseSpec":
        return replace(self, **changes)


def validate(spec: CaseSpec) -> None:
    """Raise InputError naming the first bad value and what is allowed."""
    if spec.load_type not in LOAD_TYPES:
        raise InputError(f"load type {spec.load_type!r} is not allowed; allowed: {', '.join(LOAD_TYPES)}")
    if isinstance(spec.dim, bool) or spec.dim not in DIMS:
        raise InputError(f"dim {spec.dim!r} is not allowed; allowed: {', '.join(map(str, DIMS))}")
    size = max(spec.width, spec.height)
    if spec.dim == 3:
        from studies.run import box_case
        box_case.validate(spec)
    elif spec.problem_file:
        from studies.problems.problem_file import load_problem_file
        user = load_problem_file(spec.problem_file)
        size = float(np.ptp(user.vertices, axis=0).max())
        if spec.kinematics != "small":
            raise InputError(f"kinematics {spec.kinematics!r} is not allowed with a problem file; problem files "
                             "are solved at small kinematics")
    elif spec.problem in collapse.PROBLEMS:
        collapse.validate(spec)
    elif spec.problem == ample_collapse.PROBLEM:
        ample_collapse.validate(spec)
    else:
        get_problem(spec.problem, spec.load_type)
    from studies.problems.footing import FOOTINGS
    if spec.footing not in FOOTINGS:
        raise InputError(f"footing {spec.footing!r} is not allowed; allowed: {', '.join(FOOTINGS)}")
    if spec.footing != CaseSpec.footing and spec.problem != "footing":
        raise InputError(f"footing {spec.footing!r} is for problem 'footing', not {spec.problem!r}")
    if spec.method not in METHODS:
        raise InputError(f"unknown method {spec.method!r}{closest(spec.method, METHODS)}; "
                         f"allowed: {', '.join(METHODS)}")
    check_angles(spec.angle, spec.tilt)
    if spec.tilt != 0 and spec.dim != 3:
        raise InputError(f"tilt {spec.tilt:g} needs dim = 3 (a 2D body has no tilt)")
    if spec.solver not in solvers.SOLVERS:
        raise InputError(f"solver {spec.solver!r} is not allowed; allowed: {', '.join(solvers.SOLVERS)}")
    if not (math.isfinite(spec.cell) and spec.cell > 0):
        raise InputError(f"cell size {spec.cell} is not allowed; it must be > 0")
    for name in ("width", "height"):
        value = getattr(spec, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise InputError(f"body {name} {value} is not allowed; it must be > 0")
    if size / spec.cell > 2000 or spec.cell > 10 * size:     # a coarser grid holds the body in one cell anyway
        raise InputError(f"cell size {spec.cell} is not allowed with a body of size {size:g}; it must be from "
                         f"size/2000 = {size / 2000:g} to 10 size = {10 * size:g}")
    if spec.kinematics not in KINEMATICS:
        raise InputError(f"kinematics {spec.kinematics!r} is not allowed; allowed: {', '.join(KINEMATICS)}")
    if isinstance(spec.steps, bool) or not isinstance(spec.steps, int) or not 1 <= spec.steps <= 10000:
        raise InputError(f"steps {spec.steps!r} is not allowed; it must be an integer from 1 to 10000")
    if spec.kinematics == "small" and spec.steps != 1 and not plastic(spec) \
            and spec.problem not in (*collapse.PROBLEMS, ample_collapse.PROBLEM):
        raise InputError(f"steps {spec.steps} is not allowed with small kinematics (one linear step); "
                         "use --kinematics large, or --material von-mises (load steps at small strain)")
    if spec.basis not in BASES:
        raise InputError(f"basis {spec.basis!r} is not allowed; allowed: {', '.join(BASES)}")
    _validate_band(spec)
    _validate_material(spec)
    from ibm.discretise.locking import LOCKING
    if spec.locking not in LOCKING:
        raise InputError(f"locking {spec.locking!r} is not allowed; allowed: {', '.join(LOCKING)}")
    if spec.locking == "fbar" and not (plastic(spec) or spec.problem in collapse.PROBLEMS):
        raise InputError("locking 'fbar' (B-bar at small strain, F-bar at large) is for yielding bodies (--material "
                         "von-mises, or a collapse problem)")
    if spec.locking == "fbar" and spec.basis != "mpm":
        raise InputError(f"locking 'fbar' needs --basis mpm (a cell's points share its nodes), not {spec.basis!r}")
    if isinstance(spec.ppc, bool) or not isinstance(spec.ppc, int) or not 1 <= spec.ppc <= 16:
        raise InputError(f"ppc {spec.ppc!r} is not allowed; it must be an integer from 1 to 16")
    if len(spec.offset) != spec.dim:
        raise InputError(f"offset {tuple(spec.offset)} is not allowed with dim = {spec.dim}; give {spec.dim} "
                         f"components in [0, 1)")
    if not all(math.isfinite(o) and 0 <= o < 1 for o in spec.offset):
        raise InputError(f"offset {tuple(spec.offset)} is not allowed; "
                         f"{'both' if spec.dim == 2 else 'all three'} components must be in [0, 1)")
    if not (math.isfinite(spec.load) and spec.load != 0):
        raise InputError(f"load {spec.load} is not allowed; it must be a finite non-zero number")
    Elastic(spec.E, spec.nu)
    for name in ("load", "E"):     # the error norms square the fields, which must stay finite and nonzero
        value = abs(getattr(spec, name))
        if not 1 / MAGNITUDE <= value <= MAGNITUDE:
            raise InputError(f"{name} {getattr(spec, name)} is not allowed; its magnitude must be from "
                             f"{1 / MAGNITUDE:g} to {MAGNITUDE:g}")
    method = METHODS[spec.method]
    declared = ample_collapse.parameters(spec.method) if spec.problem == ample_collapse.PROBLEM \
        else method.defaults()
    for key, value in spec.method_parameters.items():
        if key not in declared:
            allowed = ", ".join(declared) or "none"
            raise InputError(f"{key.replace('_', '-')} is not a parameter of method {spec.method!r}; "
                             f"its parameters: {allowed.replace('_', '-')}")
        if value is not None:      # a problem may lend a method a parameter another method declares
            (method.parameter(key) if key in method.names else method_parameters()[key][0]).check(value)


def check_angles(angle, tilt) -> None:
    """InputError unless the angle and the tilt are numbers in [0, 360) degrees."""
    for name, value in (("angle", angle), ("tilt", tilt)):
        if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
                and ANGLE_RANGE[0] <= value < ANGLE_RANGE[1]):
            raise InputError(f"{name} {value} is not allowed; it must be a number in [0, 360) degrees")


def _validate_band(spec: CaseSpec) -> None:
    steps = spec.kinematics == "large" or plastic(spec)
    from baselines.registry import check_band
    check_band(spec.band, spec.method, steps and spec.problem not in collapse.PROBLEMS
               and spec.problem != ample_collapse.PROBLEM)


MATERIALS = ("elastic", "von-mises", "j2")      # j2: the same von Mises model, under its older name


def _validate_material(spec: CaseSpec) -> None:
    if spec.material not in MATERIALS:
        raise InputError(f"material {spec.material!r} is not allowed; allowed: {', '.join(MATERIALS)}")
    for name in ("yield_stress", "hardening"):
        value = getattr(spec, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise InputError(f"{name.replace('_', '-')} {value} is not allowed; it must be a finite number >= 0")
    if spec.material == "elastic" and (spec.yield_stress or spec.hardening):
        raise InputError(f"yield-stress and hardening are for --material von-mises (or j2); got yield-stress "
                         f"{spec.yield_stress:g} and hardening {spec.hardening:g} with material 'elastic'")
    if plastic(spec):
        if not spec.yield_stress > 0:
            raise InputError(f"yield-stress {spec.yield_stress} is not allowed for material {spec.material}; it must be > 0")


def traction_error(tractions, body, exact) -> float:
    """Relative error of a method's recovered boundary traction sigma n against the exact one
    (exact(x) -> u, sigma, ...), sqrt(sum w |t_h - t|^2 / sum w |t|^2) over its points (multiplier methods)."""
    _, sigma, _ = exact(tractions.x)
    outward = np.zeros_like(tractions.x)                 # per point: an arc's normal turns
    for k in np.unique(tractions.edge):
        mine = tractions.edge == k
        outward[mine] = body.outward(int(k), tractions.x[mine])
    exact = np.einsum("pij,pj->pi", sigma, outward)
    error = np.sum(tractions.weight * np.sum((tractions.value - exact) ** 2, axis=1))
    return float(np.sqrt(error / np.sum(tractions.weight * np.sum(exact ** 2, axis=1))))


def load_stepped(spec: CaseSpec) -> bool:
    """Whether `spec` runs the load-step loop a checkpoint saves (ibm.large.loadsteps.run, on the grid)."""
    method = METHODS.get(spec.method)
    return spec.dim == 2 and method is not None and not method.supports.body_fitted \
        and spec.problem != ample_collapse.PROBLEM and (
        spec.kinematics == "large" or plastic(spec) or spec.problem in collapse.PROBLEMS)


def check_checkpoint(spec: CaseSpec) -> None:
    """Raise InputError (one line) unless a checkpoint can save `spec`'s run (load_stepped)."""
    if spec.dim == 3:
        raise InputError("--checkpoint is for load steps; a 3D case is one linear solve")
    if spec.problem == ample_collapse.PROBLEM:
        raise InputError(f"--checkpoint is not available for {ample_collapse.PROBLEM!r} yet")
    if METHODS[spec.method].supports.body_fitted:
        raise InputError(f"--checkpoint is not available for method {spec.method!r} (a body-fitted reference has no "
                         "load-step checkpoints)")
    if not load_stepped(spec):
        raise InputError("--checkpoint is for load steps (large kinematics, material von-mises, or a collapse "
                         "problem); small elastic kinematics is one linear solve")


def instance_of(spec: CaseSpec):
    if spec.problem_file:
        from studies.problems.problem_file import load_problem_file, place_file
        return place_file(load_problem_file(spec.problem_file), Elastic(spec.E, spec.nu), spec.angle, spec.offset,
                          spec.cell)
    problem = get_problem(spec.problem, spec.load_type)
    parameters = Parameters(Elastic(spec.E, spec.nu), spec.load, spec.width, spec.height)
    return place(problem, parameters, spec.angle, spec.offset, spec.cell)


def run_case(spec: CaseSpec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
             checkpoint=None) -> dict:
    """Solve one case and return its record (settings, sizes, errors, diagnostics).

    With keep_fields the record also holds the arrays under "fields" (not JSON-able).
    solver: the linear solver backend (ibm.solvers.backends: auto, pardiso, superlu, amg) where the spec's own
    solver is "auto"; the record's "solver" says which one ran. The direct ones agree to round-off.
    progress: show the load steps (and each one's Newton iterations) as a tqdm bar on stderr.
    checkpoint: (load steps: large kinematics, material von-mises, the collapse problems) a file each
    converged load step is saved to; a run that finds it resumes from it (studies.run.large.run_large_case,
    studies.problems.collapse.run_case, ibm.large.checkpoint).
    """
    validate(spec)
    if checkpoint is not None:
        check_checkpoint(spec)
    solver = spec.solver if spec.solver != "auto" else solver
    if spec.dim == 3:
        from studies.run.box_case import run_box_case
        return run_box_case(spec, keep_fields, solver)
    if spec.problem in collapse.PROBLEMS:
        with solvers.choice(solver):
            return collapse.run_case(spec, keep_fields, checkpoint)
    if spec.problem == ample_collapse.PROBLEM:
        if keep_fields:
            raise InputError(f"--vtk is not available for {ample_collapse.PROBLEM!r} yet")
        with solvers.choice(solver):
            return ample_collapse.run_case(spec)
    if spec.kinematics == "large" or plastic(spec):        # the load-step loop
        from studies.run.large import run_large_case
        with solvers.choice(solver):
            return run_large_case(spec, keep_fields, progress, checkpoint)
    start = perf_counter()
    instance = instance_of(spec)
    model = build_model(instance.body, instance.parameters.material, instance.loads, spec.cell, spec.ppc)
    method = METHODS[spec.method]
    with solvers.choice(solver):
        solution = method(model, **spec.method_parameters)
    exact, reference = instance.exact, {"reference": "exact"}
    if exact is None:   # a problem file without an exact field: a refined fem reference
        from studies.run.reference import fem_reference
        found = fem_reference(model.body, model.material, model.loads, spec.cell, lambda candidate: norm_errors(
            model.body, model.grid, model.material, solution.evaluate, candidate, delta=solution.info.get("delta")))
        exact, reference = found.evaluate, found.summary()
    u, sigma, zz = exact(model.points.x)
    errors = point_errors(model.points.volume, solution.u, u, solution.sigma, sigma,
                          solution.sigma_zz, zz, instance.direction)
    errors.update(norm_errors(model.body, model.grid, model.material, solution.evaluate, exact,
                              delta=solution.info.get("delta")))
    if solution.tractions is not None:
        errors["err_traction"] = traction_error(solution.tractions, instance.body, exact)
    forces = reaction_records(model, solution, spec.method, exact if reference["reference"] == "exact" else None)
    if forces and "exact" in forces[0]:
        errors["err_reaction"] = reaction_error(forces)
    used = method.used(spec.method_parameters)
    material = instance.parameters.material
    record = {
        "problem": instance.problem.name if spec.problem_file else spec.problem,
        **({"problem_file": spec.problem_file} if spec.problem_file else {}),
        "method": spec.method, "angle": spec.angle, "cell": spec.cell,
        "ppc": spec.ppc, "offset": list(spec.offset), "E": material.E, "nu": material.nu, "load": spec.load,
        "load_type": spec.load_type, "width": spec.width, "height": spec.height, "kinematics": spec.kinematics,
        "delta_rel": used.get("delta_rel"), **used,
        "ndof": int(solution.info["ndof"]), "npoints": len(model.points),
        **errors, **reference,
        **{k: v for k, v in solution.info.items() if k != "ndof" and np.isscalar(v)},
        "reactions": forces,
        "time_s": perf_counter() - start,
    }
    if keep_fields:
        record["fields"] = {"model": model, "instance": instance, "solution": solution,
                            "exact": (u, sigma, zz)}
    return record


def spec_dict(spec: CaseSpec) -> dict:
    return asdict(spec)
