"""One case: spec -> problem -> model -> method -> errors vs exact, as one flat record.

The defaults of CaseSpec are the settings of the seed reproduction, kept here and only here:
- E = 1e4, nu = 0.3, p = 10: the paper gives none; relative errors of this linear
  problem do not depend on E or p, and nu = 0.3 is a typical soil/metal value.
- delta / h = 1e-5: the IBM's error is O(delta) (docs/seed.md), so a thin band
  puts all six seed numbers well below the paper's while the (equilibrated) condition
  estimate stays near 1e8-1e9, far from round-off trouble.
- offset (0.37, 0.29): a generic placement, so no boundary lies on a grid line and no
  cut is symmetric; the offset sweep of docs/seed.md shows the numbers barely move with it.
- h = 10 and one point per 10-unit square: the paper's resolution.
- dim = 3 (studies.problems.boxes): the box problems as cubes, offset (0.37, 0.29, 0.11) (the seed's and a
  third generic component) unless given.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

from baselines.registry import METHODS, check_band, method_parameters
from ibm.discretise.basis import BASES
from ibm.discretise.locking import LOCKING
from ibm.exceptions import InputError
from ibm.models.elastic import Elastic
from ibm.solvers import backends as solvers
from studies.problems.library import LOAD_TYPES, closest
from studies.problems.materials import check_nonnegative, validate_material
from studies.problems.registry import PROBLEMS, owners_of, problem_of

ANGLE_RANGE = (0.0, 360.0)
MAGNITUDE = 1e100          # the largest load and modulus (and the inverse of the smallest)
KINEMATICS = ("small", "large")
DIMS = (2, 3)
OFFSET_3D = (0.37, 0.29, 0.11)


@dataclass(frozen=True)
class CaseSpec:
    """One case of a study: a problem, a method and every setting that defines its result (the
    fields below, with their defaults). run_case(spec) solves it into a record; validate(spec)
    checks it first; two equal specs have the same case id (studies.run.identity)."""

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
    material: str = "elastic"        # elastic (Hencky at large strain), von-mises (j2), mohr-coulomb or
                                     # drucker-prager (studies.problems.materials)
    yield_stress: float = 0.0        # J2 yield stress (material von-mises; 0 otherwise)
    hardening: float = 0.0           # J2 linear hardening modulus (material von-mises)
    cohesion: float = 0.0            # c (materials mohr-coulomb, drucker-prager; studies.problems.materials)
    friction_angle: float = 0.0      # phi in degrees (materials mohr-coulomb, drucker-prager)
    dilation_angle: float | None = None   # psi in degrees; None: psi = phi (associated flow)
    problem_file: str = ""           # a user's problem (studies.problems.problem_file); replaces `problem`
    locking: str = "none"            # none, or fbar (the mean dilatation at small strain, ibm.discretise.locking)
    footing: str = "smooth"          # problem footing: smooth (a roller), rough (fixed), rigid (a body in contact)
    dim: int = 2                     # 2 (plane strain) or 3 (the box problems, studies.problems.boxes)
    tilt: float = 0.0                # 3D: the tilt about the body's own xi axis after the angle about z
    solver: str = "auto"             # linear solver (ibm.solvers.backends); amg's results differ within its tolerance
    friction: float = 0.0            # Coulomb friction coefficient mu of a contact wall (0: none)
    adhesion: float = 0.0            # Tresca bound tau_max of a contact wall (the adhesion of an undrained interface)
    unit_weight: float = 0.0         # the soil's weight per unit volume (gamma), for a problem that takes it
    surcharge: float = 0.0           # a pressure q0 on the soil's free top, for a problem that takes it
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
    problem = problem_of(spec)
    problem.validate(spec)
    size = problem.size(spec)
    for name, allowed in {k: v for p in PROBLEMS.values() for k, v in p.own_settings.items()}.items():
        value = getattr(spec, name)
        if value not in allowed:
            raise InputError(f"{name} {value!r} is not allowed; allowed: {', '.join(allowed)}")
        owners = [p.name for p in owners_of(name)]
        if value != getattr(CaseSpec, name) and problem.name not in owners:
            raise InputError(f"{name} {value!r} is for problem {', '.join(map(repr, owners))}, not {spec.problem!r}")
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
    if spec.steps != 1 and not problem.steps_allowed(spec):
        raise InputError(f"steps {spec.steps} is not allowed with small kinematics (one linear step); "
                         "use --kinematics large, or --material von-mises (load steps at small strain)")
    if spec.basis not in BASES:
        raise InputError(f"basis {spec.basis!r} is not allowed; allowed: {', '.join(BASES)}")
    check_band(spec.band, spec.method, problem.takes_band(spec))
    validate_material(spec)
    _validate_contact(spec, problem)
    _validate_weight(spec, problem)
    if spec.locking not in LOCKING:
        raise InputError(f"locking {spec.locking!r} is not allowed; allowed: {', '.join(LOCKING)}")
    if spec.locking == "fbar" and not problem.locking_applies(spec):
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
    declared = problem.parameters(spec.method)
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


def _validate_weight(spec: CaseSpec, problem) -> None:
    for name, what, attribute in (("unit_weight", "a soil's weight", "weight"),
                                  ("surcharge", "a surcharge on the soil's free top", "surcharge")):
        check_nonnegative(spec, name)
        value, key = getattr(spec, name), name.replace("_", "-")
        if value and not getattr(problem, attribute):
            takers = [p.name for p in PROBLEMS.values() if getattr(p, attribute)]
            raise InputError(f"{key} {value:g} is for a problem with {what} ({', '.join(takers)}), not "
                             f"{problem.name!r}")


def _validate_contact(spec: CaseSpec, problem) -> None:
    for name in ("friction", "adhesion"):
        check_nonnegative(spec, name)
        value = getattr(spec, name)
        if value and not problem.takes_contact_law(spec):
            takers = [p.name for p in PROBLEMS.values() if p.contact]
            raise InputError(f"{name} {value:g} is for a problem with a contact wall ({', '.join(takers)}) or the "
                             f"rigid footing (--footing rigid), not {problem.name!r} as set")


def load_stepped(spec: CaseSpec) -> bool:
    """Whether `spec` runs the load-step loop a checkpoint saves (ibm.large.loadsteps.run, on the grid)."""
    return spec.method in METHODS and problem_of(spec).load_stepped(spec)


def check_checkpoint(spec: CaseSpec) -> None:
    """Raise InputError (one line) unless a checkpoint can save `spec`'s run (load_stepped)."""
    refusal = problem_of(spec).checkpoint_refusal(spec)
    if refusal:
        raise InputError(refusal)


def instance_of(spec: CaseSpec):
    """The case's problem placed in the grid (small strain: body, loads, exact field)."""
    return problem_of(spec).instance(spec)


def run_case(spec: CaseSpec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
             checkpoint=None) -> dict:
    """Solve one case and return its record (settings, sizes, error norms, diagnostics), by its problem
    (studies.problems.problem.Problem.run).

    With keep_fields the record also holds the arrays under "fields" (not JSON-able).
    solver: the linear solver backend (ibm.solvers.backends: auto, pardiso, superlu, amg) where the spec's own
    solver is "auto"; the record's "solver" says which one ran. The direct ones agree to round-off.
    progress: show the load steps (and each one's Newton iterations) as a tqdm bar on stderr.
    checkpoint: (load steps on the grid, load_stepped) a file each converged load step is saved to; a run
    that finds it resumes from it (ibm.large.checkpoint).
    """
    validate(spec)
    if checkpoint is not None:
        check_checkpoint(spec)
    problem = problem_of(spec)
    if keep_fields and problem.fields_refusal(spec):
        raise InputError(problem.fields_refusal(spec))
    solver = spec.solver if spec.solver != "auto" else solver
    return problem.run(spec, keep_fields, solver, progress, checkpoint)


def spec_dict(spec: CaseSpec) -> dict:
    return asdict(spec)
