"""The large-deformation implicit MPM: quasi-static load steps, updated Lagrangian (the driver).

Per load step (docs/large-deformation.md), on the configuration x_n at its start:
    basis of the points (mpm or gimp) -> the method's wall terms (ibm.large.treatment) ->
    Newton-Raphson on the grid increment dU with the consistent tangent (ibm.large.newton) ->
    points move with the method's full displacement, F_n <- F, V = V0 det F, outline moved
    and put back on its walls; the grid is reset (dU = 0) for the next step.
Loads are ramped: body force, pressures and wall motions at the fraction t of their totals.
A small-strain model (ibm.models.small_strain) runs the same steps on the initial configuration: the
points, the outline and the walls stay, x = X + u is kept for the output.
A step that fails (no convergence, NaN, det F <= 0) is retried with its increment halved; past
control.max_cuts halvings StepFailure is raised, the last converged (sub)step on its `progress`.
With a checkpoint file, every converged step is saved (ibm.large.checkpoint) and a killed run
resumes after the last saved step, ending bit-identical to an uninterrupted run.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import shapely
from scipy.spatial import cKDTree

from ibm.discretise.basis import BASES, current_domains, point_basis
from ibm.discretise.grid import Grid
from ibm.discretise.locking import LOCKING
from ibm.discretise.points import MaterialPoints, material_points, merge_slivers
from ibm.discretise.simplex_domains import SimplexDomains
from ibm.exceptions import CheckpointError, DomainLost, GridExit, InputError, NotConverged, SolveError, StepFailure
from ibm.geometry import polyhedron
from ibm.geometry.outline import Body
from ibm.large import checkpoint as checkpoints
from ibm.large.kinematics import is_small
from ibm.large.load_paths import LoadPath
from ibm.large.newton import Control, Kept, newton
from ibm.large.progress import Progress
from ibm.large.treatment import StepContext
from ibm.large.walls import WallLines, outline_of


# Solves of one step an active-set method may take before the step is cut.
ACTIVE_SET_ROUNDS = 30
# A (sub)step's counts that the step's record sums over its cuts.
SUMMED_OVER_CUTS = ("active_set_changes", "active_set_rounds")


@dataclass(frozen=True, eq=False)
class Loading:
    """Totals reached at the last step: body force per unit initial volume (2,) (rho_0 g),
    pressures on traction edges (edge -> p > 0 compressive, on the current edge), and wall
    motions (n_walls,) along each wall's inward normal. Paths that are not proportional
    (ibm.large.load_paths): wall_path, the walls' translations (n_walls, d) by any vector, in place
    of wall_motion; traction_path, edge -> a traction (d,) on a traction edge."""

    body_force: np.ndarray = field(default_factory=lambda: np.zeros(2))
    pressures: dict = field(default_factory=dict)
    wall_motion: np.ndarray | None = None
    wall_path: LoadPath | None = None
    traction_path: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Setup:
    """A large-deformation run: the body, its material model (ibm.models), the loading, the grid's
    cell size h, ppc x ppc points per cell, the point basis (mpm or gimp), the number of load steps
    and the locking remedy."""

    body: Body
    material: object
    loading: Loading
    h: float
    ppc: int = 2
    basis: str = "gimp"
    steps: int = 10
    margin: int = 1               # grid cells around the initial body
    sliver: float = 0.25          # clipped point domains below this fraction of a whole one are merged
    locking: str = "none"         # none, or fbar (the mean dilatation, ibm.discretise.locking: B-bar, F-bar at large strain)
    contact: dict = field(default_factory=dict)   # edge -> ContactLaw (ibm.contact.laws): unilateral walls with friction
    obstacles: dict = field(default_factory=dict)  # a contact edge that is no wall -> the Obstacle or RigidBody


def _covering(x: np.ndarray, domains) -> Callable[[np.ndarray], np.ndarray]:
    """points (m, d) -> index of the material point whose domain holds each (the nearest point where
    none does, or where there are no polygon domains: 3D takes the nearest point); the search tree
    is built on first use (only methods with band or wall points ask)."""
    trees = []
    if isinstance(domains, SimplexDomains):
        domains = None

    def state_of(q: np.ndarray) -> np.ndarray:
        if not trees:
            trees.append(cKDTree(x))
        owner = trees[0].query(q)[1]
        if domains is not None and len(q):
            hit_point, hit_domain = shapely.STRtree(domains).query(shapely.points(q), predicate="within")
            owner[hit_point] = hit_domain
        return owner

    return state_of


def run(setup: Setup, treatment, control: Control = Control(),
        after_step: Callable[[Progress], dict] | None = None,
        checkpoint: str | Path | None = None, extra: dict | None = None) -> Progress:
    """All load steps of `setup` with the walls imposed by `treatment` (ibm.large.treatment).

    checkpoint: a file (ibm.large.checkpoint) the whole Progress is written to after every converged
    step (once after_step has updated its record); when it exists at the start and was written
    for this setup, the run continues after its last step (a finished run returns at once), and
    ends bit-identical to an uninterrupted one. It is left in place at the end.
    extra: the caller's own per-step data (a dict of arrays, lists, dicts, numbers; e.g. the
    snapshots after_step takes), saved with every checkpoint and restored into it in place on
    resume. A checkpoint lacking a key of `extra` is refused (CheckpointError).
    """
    body, h = setup.body, setup.h
    if isinstance(setup.steps, bool) or not isinstance(setup.steps, (int, np.integer)) or setup.steps < 1:
        raise InputError(f"steps {setup.steps!r} is not allowed; it must be an integer >= 1")
    if setup.basis not in BASES:
        raise InputError(f"basis {setup.basis!r} is not allowed; allowed: {', '.join(BASES)}")
    if setup.locking not in LOCKING:
        raise InputError(f"locking {setup.locking!r} is not allowed; allowed: {', '.join(LOCKING)}")
    if setup.locking == "fbar" and setup.basis != "mpm":
        raise InputError(f"locking 'fbar' needs basis 'mpm' (a cell's points share its nodes), not {setup.basis!r}")
    n_walls = len(body.essential_edges)
    motion = np.zeros(n_walls) if setup.loading.wall_motion is None else np.asarray(setup.loading.wall_motion, float)
    _check_walls(setup, treatment)
    grid = Grid.covering(body, h, setup.margin)
    if body.dim == 3:       # the seed's clipped cubes; a sliver's tiny support is tied by the extension
        points = polyhedron.material_points(body, grid, setup.ppc, rule=False, domains=setup.basis == "gimp")
    else:
        points = merge_slivers(material_points(body, grid, setup.ppc, domains=True), grid, setup.ppc, setup.sliver)
    if setup.basis != "gimp":
        points = MaterialPoints(points.x, points.volume, points.cells)
    progress, key = _start(setup, points, treatment, control, checkpoint, extra)
    with Kept() as kept:    # the tangent's pattern and PARDISO's analysis, from step to step while they stand
        for step in range(len(progress.steps) + 1, setup.steps + 1):
            target, cuts, records = step / setup.steps, 0, []
            while progress.t < target - 1e-14:
                increment = min(target - progress.t, (target - (step - 1) / setup.steps) / 2 ** cuts)
                try:
                    result = _one_step(setup, grid, points.domains, progress, treatment, control,
                                       progress.t, progress.t + increment, motion, kept)
                except (GridExit, DomainLost) as stop:      # no smaller step helps: the run stops, naming the step
                    hint = "; the grid does not grow (give the body more room with Setup.margin)" \
                        if isinstance(stop, GridExit) else ""
                    raise type(stop)(f"load step {step}: {stop}{hint}") from None
                except (NotConverged, FloatingPointError, SolveError) as failure:   # a singular tangent: past a limit
                    cuts += 1
                    if cuts > control.max_cuts:     # past a collapse: the caller keeps the last converged state
                        stop = StepFailure(f"load step {step} did not converge after {control.max_cuts} step cuts "
                                           f"({failure})")
                        stop.progress = progress
                        raise stop from None
                    continue
                records.append(result)
                progress.t += increment
            record = {"step": step, "t": progress.t, "cuts": cuts,
                      "newton_iterations": int(sum(r["iterations"] for r in records)),
                      "residuals": [res for r in records for res in r["residuals"]],
                      **{k: v for k, v in records[-1].items() if k not in ("iterations", "residuals")}}
            for name in SUMMED_OVER_CUTS:          # counts of the whole step, like its iterations
                if name in record:
                    record[name] = int(sum(r[name] for r in records))
            progress.steps.append(record)
            if after_step is not None:        # sees this step's record as progress.steps[-1]
                record.update(after_step(progress))
            if checkpoint is not None:
                checkpoints.save(checkpoint, progress, extra, key)

    return progress


def _check_walls(setup: Setup, treatment) -> None:
    """InputError (one line) for walls the treatment cannot impose or a contact edge that is no wall."""
    body, loading = setup.body, setup.loading
    if loading.wall_path is not None:
        shape = (len(body.essential_edges), body.dim)
        if loading.wall_path.values.shape[1:] != shape:
            raise InputError(f"the wall path gives translations of shape {loading.wall_path.values.shape[1:]}; "
                             f"this body's walls need {shape}")
        if loading.wall_motion is not None:
            raise InputError("give the walls' motion once: wall_motion or wall_path, not both")
        normals = body.normals[body.essential_edges]
        along = np.einsum("kwd,wd->kw", loading.wall_path.values, normals)[:, :, None] * normals[None]
        tangential = np.abs(loading.wall_path.values - along).max()
        if tangential > 1e-12 * max(np.abs(loading.wall_path.values).max(), 1e-300) \
                and not getattr(treatment, "vector_walls", False):
            raise InputError(f"this method's walls move only along their normals; a wall that moves along itself "
                             f"(by {tangential:.3g}) needs one that imposes translations by any vector")
    for edge in setup.contact:
        if (edge in body.essential_edges) == (edge in setup.obstacles):
            raise InputError(f"contact edge {edge} must be a wall of the body (its walls: {body.essential_edges}) "
                             "or a free edge with an obstacle, one of the two")
    for edge in setup.obstacles:
        if edge not in setup.contact:
            raise InputError(f"obstacle of edge {edge} has no contact law")
    if setup.contact and not getattr(treatment, "contact", False):
        raise InputError("this method does not impose contact (unilateral walls with friction)")
    if setup.contact and not is_small(setup.material):
        raise InputError("contact walls are imposed on the body as given: small kinematics only (a small-strain "
                         f"material, not {type(setup.material).__name__})")


def _start(setup: Setup, points: MaterialPoints, treatment, control: Control, checkpoint, extra):
    """The Progress to start from (the checkpoint's when it exists for this setup) and the setup's
    checkpoint fingerprint (None without a checkpoint)."""
    n, key = len(points), None
    if checkpoint is not None:
        checkpoint = Path(checkpoint)
        if not checkpoint.parent.is_dir():
            raise InputError(f"the folder of checkpoint {str(checkpoint)!r} does not exist")
        checkpoints.remove_stale_temporaries(checkpoint)
        key = checkpoints.fingerprint(setup, treatment, control)
        if checkpoint.exists():
            return _resume(checkpoint, key, n, setup.steps, extra), key
    body = setup.body
    # the outline is resolved at the point spacing, so a bending free edge is followed (2D)
    outline = outline_of(body, None if body.dim == 3 else np.ceil(body.lengths / (setup.h / setup.ppc)).astype(int))
    progress = Progress(points.x.copy(), points.volume.copy(), points.x.copy(), points.volume.copy(),
                        setup.material.initial(n), np.zeros((n, 3, 3)), outline, WallLines.of(body))
    progress.vertex_owner = cKDTree(points.x).query(progress.outline.vertices)[1]
    return progress, key


def _resume(path: Path, key: str, n: int, steps: int, extra: dict | None) -> Progress:
    """The Progress stored at `path` for this setup (fingerprint `key`); `extra` refilled in place."""
    progress, stored = checkpoints.load(path, key)
    if len(progress.X) != n or len(progress.steps) > steps:
        raise CheckpointError(
            f"checkpoint {str(path)!r} does not fit this setup ({len(progress.X)} points, {len(progress.steps)} "
            f"steps; this run has {n} points, {steps} steps: other code wrote it?); delete it to start afresh")
    if extra is not None:
        missing = [k for k in extra if k not in stored]
        if missing:
            raise CheckpointError(
                f"checkpoint {str(path)!r} was written by a run that did not keep {', '.join(missing)}; "
                f"delete it to start afresh, or resume as that run did")
        for name in extra:
            extra[name] = stored[name]
    return progress


def _one_step(setup: Setup, grid: Grid, initial_domains, progress: Progress, treatment, control: Control,
              t0: float, t1: float, motion: np.ndarray, kept: Kept | None = None) -> dict:
    """Solve one (sub)step from load fraction t0 to t1 and update `progress` when it converges."""
    small = is_small(setup.material)
    body_n = setup.body if small else progress.outline.body()     # small strain: the body as given, arcs too
    domains = None
    if setup.basis == "gimp":
        if small:            # clipped by the body when the points were made
            domains = initial_domains
        else:
            domains = current_domains(initial_domains, progress.X, progress.x, progress.state.F, body_n)
    at = progress.X if small else progress.x          # the configuration the step integrates on
    basis = point_basis(setup.basis, grid, at, domains)
    increments, translations = (t1 - t0) * motion, None
    if setup.loading.wall_path is not None:
        translations = setup.loading.wall_path.at(t1) - setup.loading.wall_path.at(t0)      # (n_walls, d)
        increments = np.einsum("wd,wd->w", translations, progress.lines.normals)
    context = StepContext(grid, body_n, progress.lines, increments, setup.material, at,
                          progress.volume, basis, progress.state, _covering(at, domains), setup.locking,
                          translations, setup.contact, progress.contact, setup.obstacles, (t0, t1))
    terms = treatment.step(context)
    solution = newton(context, terms, setup.loading, t1, progress.V0, control, progress.outline,
                      check_rigid=t0 == 0, kept=kept)
    iterations, residuals, rounds = solution.iterations, list(solution.residuals), 0
    while terms.refine is not None:        # an active-set method: solved again until its set settles
        multipliers = np.zeros(terms.constraints[0].shape[0]) if terms.constraints is not None else np.zeros(0)
        if solution.info.get("constraint_rows") is not None:
            multipliers[solution.info["constraint_rows"]] = solution.info["multipliers"]
        refined = terms.refine(solution.dU, multipliers)
        if refined is None:
            break
        rounds += 1
        if rounds > ACTIVE_SET_ROUNDS:
            raise NotConverged(f"the contact's active set did not settle in {ACTIVE_SET_ROUNDS} rounds")
        terms = refined
        solution = newton(context, terms, setup.loading, t1, progress.V0, control, progress.outline, kept=kept)
        iterations += solution.iterations
        residuals += solution.residuals

    info = {k: v for k, v in {**terms.info, **solution.info}.items() if np.isscalar(v)}
    record = {"iterations": iterations, "residuals": residuals, **info}
    if terms.refine is not None:
        record["active_set_rounds"] = rounds
    if terms.accept is not None:
        progress.contact, measures = terms.accept(solution.dU)
        record.update(measures)
    if small:     # the configuration stays (x = X + u for the output); the state carries the strain
        progress.x = progress.x + terms.displacement(at, basis.interpolate(solution.dU))
        progress.state = solution.state
        progress.sigma = solution.sigma
        return record

    # accept: move the points with the method's full displacement, carry the state on
    plain = basis.interpolate(solution.dU)
    x_n, F_n = progress.x, progress.state.F
    progress.x = progress.x + terms.displacement(progress.x, plain)
    progress.state = solution.state
    progress.sigma = solution.sigma
    progress.volume = progress.V0 * np.linalg.det(solution.state.F)
    # each outline vertex follows the affine motion of its point, x_v -> x_p + dF_p (x_v - x_p,n),
    # as the point's domain corners do (so the outline and the domains stay one tiling; grid
    # nodes beyond a free surface, barely supported, never drive it), then goes back onto its walls
    owner = progress.vertex_owner
    d = grid.dim
    dF = np.linalg.solve(F_n[owner, :d, :d].transpose(0, 2, 1),
                         solution.state.F[owner, :d, :d].transpose(0, 2, 1)).transpose(0, 2, 1)   # F F_n^-1
    vertices = progress.outline.vertices
    moved = progress.x[owner] + np.einsum("pij,pj->pi", dF, vertices - x_n[owner])
    progress.lines = progress.lines.translated(increments)
    progress.outline = progress.outline.moved(moved - vertices, progress.lines)
    return record
