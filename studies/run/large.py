"""One large-deformation case: spec -> setup -> load steps with the method's walls -> errors vs the
exact finite-strain solution (studies.problems.finite_strain), per step and at the end, as one flat record.

Problems (local frame: xi along the base, eta its inward normal; rotated into the grid):
- confined-block, pressure: rollers on base and sides, pressure p = load on the top (on its
  current length), homogeneous stretch s = exp(-W(p/M));
- confined-block, settlement: the top is a roller wall moved down by load, s = 1 - load/H;
- column: self-weight rho_0 g = load / H along -eta (load is the base stress), free top, the
  Lambert-W solution.
Errors, at the points' initial positions X_p: err_u = sqrt(sum V0 |u_h - u|^2 / sum V0 |u|^2)
with u_h = x_p - X_p, err_sigma the same for sigma_eta_eta, err_sigma_ample = sum V0 |sigma_h - sigma|
/ (max |sigma| sum V0) (AMPLE's column measure: its denominator is rho_0 g H).
"""
from __future__ import annotations

from time import perf_counter

import numpy as np

from baselines.registry import METHODS, treatment
from ibm.models.constitutive import Hencky
from ibm.geometry.outline import rectangle
from ibm.exceptions import InputError
from ibm.large.loadsteps import Loading, Setup, run
from studies.problems import finite_strain
from studies.problems.library import get_problem, plastic

LARGE_PROBLEMS = {("confined-block", "pressure"), ("confined-block", "settlement"), ("column", "pressure")}


def _exact(spec, material: Hencky, t: float):
    """The exact field at load fraction t: X (n, 2) local -> (u_eta (n,), sigma_eta_eta (n,)), top height,
    and the stress scale of err_sigma_ample (the column's base stress rho_0 g H, the block's |sigma_eta_eta|)."""
    H, lam, M = spec.height, material.lam, material.M
    if plastic(spec):
        # homogeneous uniaxial strain: coaxial and proportional, so the radial return from the
        # undeformed state is the exact response at every t, whatever the steps taken
        s = 1 - t * spec.load / H
        response = material.update(np.diag([1.0, s, 1.0])[None], material.initial(1))
        stress = float(response.sigma[0, 1, 1])

        def plastic_field(X):
            return (s - 1) * X[:, 1], np.full(len(X), stress)
        return plastic_field, s * H, max(abs(stress), 1e-300)
    if spec.problem == "column":
        return column_exact(H, spec.load, material, t)
    if spec.load_type == "pressure":
        s = float(finite_strain.compression_stretch_of_pressure(t * spec.load, M))
    else:
        s = 1 - t * spec.load / H

    def field(X):
        state = finite_strain.compression(X[:, 1], s, lam, M)
        return state.u_eta, state.sigma_eta_eta
    return field, s * H, abs(M * np.log(s) / s)


def column_exact(H: float, load: float, material: Hencky, t: float):
    """The self-weight column (rho_0 g = load / H) at load fraction t: X (n, d) local -> (u_eta (n,),
    sigma_eta_eta (n,)), its top's height and the stress scale of err_sigma_ample (rho_0 g H)."""
    weight = t * load / H

    def field(X):
        state = finite_strain.column(X[:, 1], H, weight, material.lam, material.M)
        return state.u_eta, state.sigma_eta_eta
    return field, finite_strain.column_height(H, weight, material.M), weight * H


def setup_of(spec) -> tuple[Setup, np.ndarray, np.ndarray]:
    """The setup, its corner (2,) and frame (2, 2)."""
    if (spec.problem, spec.load_type) not in LARGE_PROBLEMS:
        allowed = ", ".join(f"{p} ({t})" for p, t in sorted(LARGE_PROBLEMS))
        raise InputError(f"problem {spec.problem!r} with load type {spec.load_type!r} has no exact finite-strain "
                         f"solution for load steps (large kinematics, or material von-mises); allowed: {allowed}")
    material = Hencky(spec.E, spec.nu)
    if plastic(spec):
        if (spec.problem, spec.load_type) != ("confined-block", "settlement"):
            raise InputError(f"material {spec.material} has an exact solution only for the confined block's settlement; "
                             f"problem {spec.problem!r} ({spec.load_type}) is not allowed with it")
        if spec.kinematics == "small":       # radial return on the initial configuration
            from ibm.models.small_strain import VonMises
            material = VonMises(spec.E, spec.nu, yield_stress=spec.yield_stress, hardening=spec.hardening)
        else:
            from ibm.models.plasticity import HenckyJ2
            material = HenckyJ2(spec.E, spec.nu, yield_stress=spec.yield_stress, hardening=spec.hardening)
    if spec.problem == "confined-block" and spec.load_type == "settlement":
        if not 0 < spec.load < spec.height:
            raise InputError(f"settlement {spec.load} is not allowed; it must be in (0, height = {spec.height:g})")
    elif spec.load <= 0:
        raise InputError(f"load {spec.load} is not allowed for large kinematics; it must be > 0 (compressive)")
    kinds = get_problem(spec.problem, spec.load_type).kinds
    corner = np.asarray(spec.offset, float) * spec.cell
    body = rectangle(spec.width, spec.height, kinds, spec.angle, corner)
    R = body.frame
    loading = Loading()
    if spec.problem == "column":
        loading = Loading(body_force=-(spec.load / spec.height) * R[:, 1])
    elif spec.load_type == "pressure":
        loading = Loading(pressures={2: spec.load})
    else:
        motion = np.zeros(len(body.essential_edges))
        motion[body.essential_edges.index(2)] = spec.load          # the top wall, along its inward normal
        loading = Loading(wall_motion=motion)
    return Setup(body, material, loading, spec.cell, spec.ppc, spec.basis, spec.steps), corner, R


def exact_at(spec, material, X: np.ndarray, t: float, corner, R):
    """The exact field at the points' initial positions X (n, 2) at load fraction t: u (n, 2) global,
    sigma_eta_eta (n,), the top's height and the stress scale of err_sigma_ample."""
    return placed_exact(_exact(spec, material, t), X, corner, R)


def placed_exact(exact, X: np.ndarray, corner, R):
    """An exact local field (field, top, scale) at global points X (n, d) of the body placed at
    corner (d,) with frame R (d, d): u (n, d), sigma_eta_eta (n,), top, scale."""
    field, top, scale = exact
    u_eta, s_eta = field((X - corner) @ R)
    return u_eta[:, None] * R[:, 1][None], s_eta, top, scale


def errors(exact, X, x, sigma, V0, R) -> dict:
    """The errors of method notes section 5 at the points' initial positions (see module doc);
    exact: exact_at's (u, sigma_eta_eta, top, scale)."""
    u, s_eta, top, scale = exact
    u_h = x - X
    d = len(R)
    s_h = np.einsum("i,pij,j->p", R[:, 1], sigma[:, :d, :d], R[:, 1])

    def relative(error_sq, exact_sq):
        return float(np.sqrt(np.sum(V0 * error_sq) / np.sum(V0 * exact_sq)))
    return {"err_u": relative(np.sum((u_h - u) ** 2, axis=1), np.sum(u ** 2, axis=1)),
            "err_sigma": relative((s_h - s_eta) ** 2, s_eta ** 2),
            "err_sigma_ample": float(np.sum(np.abs(s_h - s_eta) * V0) / (scale * np.sum(V0))),
            "height_exact": float(top)}


SNAPSHOT_BUDGET = 2_000_000   # points x stored steps kept in a case's fields (all steps when they fit)


def _snapshot(exact, p, R) -> dict:
    """One step's arrays for figures and VTK: positions, stresses, exact values at X, the outline."""
    u, s_eta = exact[:2]
    return {"t": p.t, "x": p.x.copy(), "sigma": p.sigma.copy(), "volume": p.volume.copy(), "F": p.state.F.copy(),
            "u_exact": u, "sigma_exact": s_eta,
            "sigma_eta": np.einsum("i,pij,j->p", R[:, 1], p.sigma[:, :2, :2], R[:, 1]),
            "outline": p.outline.vertices.copy()}


def large_fields(spec, progress, snapshots: list[dict], setup: Setup, corner, R) -> dict[str, np.ndarray]:
    """The case's fields as plain arrays: per stored step k (k, n, ...) and the fixed ones.

    step (k,), t (k,), x (k, n, 2), sigma (k, n, 3, 3), volume (k, n), F (k, n, 3, 3), u_exact (k, n, 2),
    sigma_exact, sigma_eta (k, n) (along the body's normal e_eta), outline (k, m, 2) with
    outline_kind (m,) (edge m runs from vertex m), X (n, 2), V0 (n,), frame (2, 2), corner (2,),
    grid_h, grid_lower (2,), grid_shape (2,) of the background grid (the same at every step)."""
    from ibm.discretise.grid import Grid
    n, k = len(progress.X), len(snapshots)
    keep = np.arange(k)
    if n * k > SNAPSHOT_BUDGET:   # evenly spaced steps, always the last
        keep = np.unique(np.r_[np.linspace(0, k - 1, max(2, SNAPSHOT_BUDGET // n)).astype(int), k - 1])
    chosen = [snapshots[i] for i in keep]
    grid = Grid.covering(setup.body, setup.h, setup.margin)
    out = {name: np.stack([c[name] for c in chosen]) for name in chosen[0]}
    return {"step": keep + 1, **out, "outline_kind": np.array(progress.outline.kinds),
            "X": progress.X, "V0": progress.V0, "frame": R, "corner": corner, "grid_h": np.array(grid.h),
            "grid_lower": np.array(grid.lower), "grid_shape": np.array(grid.shape)}


def penetration(lines, x: np.ndarray) -> float:
    """The deepest any point (n, 2) lies beyond a wall line (0 when none crosses)."""
    depth = [-np.min(lines.distance(wall, x)) for wall in range(len(lines.normals))]
    return float(max(0.0, *depth)) if depth else 0.0


def summary(progress, corner, R) -> dict:
    """The record's part every load-step case shares: sizes, the last step's errors (the steps'
    records hold errors() and penetration()), the final height along e_eta, the steps' history."""
    final = progress.steps[-1]
    return {"ndof": int(final.get("ndof", 0)), "npoints": len(progress.X),
            "err_u": final["err_u"], "err_sigma": final["err_sigma"], "err_sigma_ample": final["err_sigma_ample"],
            "height_final": float(np.max((progress.outline.vertices - corner) @ R[:, 1])),
            "height_exact": final["height_exact"],
            "max_penetration": max(s["penetration"] for s in progress.steps),
            "newton_iterations": [s["newton_iterations"] for s in progress.steps],
            "step_cuts": int(sum(s["cuts"] for s in progress.steps)),
            "steps_at_round_off": int(sum(s.get("at_round_off", 0) for s in progress.steps)),
            "history": [{k: s[k] for k in ("step", "t", "newton_iterations", "cuts", "residuals", "err_u",
                                            "err_sigma", "err_sigma_ample")} for s in progress.steps]}


def run_large_case(spec, keep_fields: bool = False, show_progress: bool = False, checkpoint=None) -> dict:
    """The case's record (see the module doc); with keep_fields its arrays under "fields".

    checkpoint: (grid methods; studies.run.case.check_checkpoint refuses fem) a file every converged
    load step is saved to (ibm.large.loadsteps.run); a run that
    finds it resumes after its last step, with the snapshots of the steps before (kept in the
    checkpoint), so record and fields equal an uninterrupted run's to the bit (time_s aside).
    """
    start = perf_counter()
    setup, corner, R = setup_of(spec)
    method = METHODS[spec.method]
    kept: dict = {"snapshots": []} if keep_fields else {}    # saved with each checkpoint, refilled on resume
    bar = None
    if show_progress:
        from tqdm import tqdm
        bar = tqdm(total=spec.steps, unit="step", desc=f"{spec.method} load steps", leave=False)

    def after_step(p):
        if bar is not None:
            bar.update(len(p.steps) - bar.n)      # a resumed run starts at its checkpoint's step
            if p.steps:
                bar.set_postfix(newton=p.steps[-1]["newton_iterations"], cuts=p.steps[-1]["cuts"])
        exact = exact_at(spec, setup.material, p.X, p.t, corner, R)     # once per step, for both
        if keep_fields:
            kept["snapshots"].append(_snapshot(exact, p, R))
        return {**errors(exact, p.X, p.x, p.sigma, p.V0, R),
                "penetration": penetration(p.lines, p.x)}

    if method.supports.body_fitted:       # the total-Lagrangian body-fitted reference
        from baselines.fem.large import run_fem
        progress = run_fem(setup, corner, R, after_step)
    else:
        parameters = {k: spec.method_parameters.get(k) for k in method.names}
        if method.supports.band_kinematics:
            parameters["band"] = spec.band
        progress = run(setup, treatment(spec.method, parameters), after_step=after_step, checkpoint=checkpoint,
                       extra=kept)
    if bar is not None:
        bar.close()
    used = method.used(spec.method_parameters, load_steps=True)
    record = {
        "problem": spec.problem, "method": spec.method, "angle": spec.angle, "cell": spec.cell, "ppc": spec.ppc,
        "offset": list(spec.offset), "E": spec.E, "nu": spec.nu, "load": spec.load, "load_type": spec.load_type,
        "width": spec.width, "height": spec.height, "kinematics": spec.kinematics, "steps": spec.steps, "basis": spec.basis,
        **({"band": spec.band} if method.supports.band_kinematics else {}),
        "material": spec.material, "yield_stress": spec.yield_stress, "hardening": spec.hardening,
        **used, **summary(progress, corner, R), "time_s": perf_counter() - start,
    }
    if keep_fields:
        record["fields"] = large_fields(spec, progress, kept["snapshots"], setup, corner, R)
    return record
