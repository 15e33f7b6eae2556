"""One large-deformation case: a problem's setup -> load steps with the method's walls -> errors vs its
exact finite-strain solution (studies.problems.closed_form), per step and at the end, as one flat record.

The body's local frame: xi along the base, eta its inward normal; rotated into the grid.
Errors, at the points' initial positions X_p: err_u = sqrt(sum V0 |u_h - u|^2 / sum V0 |u|^2)
with u_h = x_p - X_p, err_sigma the same for sigma_eta_eta, err_sigma_ample = sum V0 |sigma_h - sigma|
/ (max |sigma| sum V0) (AMPLE's column measure: its denominator is rho_0 g H).
"""
from __future__ import annotations

from time import perf_counter

import numpy as np
from tqdm import tqdm

from baselines.fem.large import run_fem
from baselines.registry import METHODS, treatment
from ibm.discretise.grid import Grid
from ibm.large.loadsteps import Setup, run


def placed_exact(exact, X: np.ndarray, corner, R):
    """An exact local field (field, top, scale) at global points X (n, d) of the body placed at
    corner (d,) with frame R (d, d): u (n, d), sigma_eta_eta (n,), top, scale."""
    field, top, scale = exact
    u_eta, s_eta = field((X - corner) @ R)
    return u_eta[:, None] * R[:, 1][None], s_eta, top, scale


def errors(exact, X, x, sigma, V0, R) -> dict:
    """The error norms at the points' initial positions (see module doc); exact: placed_exact's
    (u, sigma_eta_eta, top, scale)."""
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


def run_large_case(spec, setup: Setup, corner: np.ndarray, R: np.ndarray, exact, keep_fields: bool = False,
                   show_progress: bool = False, checkpoint=None) -> dict:
    """The case's record (see the module doc); with keep_fields its arrays under "fields".

    setup: the problem's load steps, its body placed at corner (2,) with frame R (2, 2); exact(material,
    t) -> (field, top height, stress scale): the exact field at load fraction t, field(X local (n, 2)) ->
    (u_eta (n,), sigma_eta_eta (n,)) (studies.problems.closed_form).

    checkpoint: (grid methods; studies.run.case.check_checkpoint refuses fem) a file every converged
    load step is saved to (ibm.large.loadsteps.run); a run that
    finds it resumes after its last step, with the snapshots of the steps before (kept in the
    checkpoint), so record and fields equal an uninterrupted run's to the bit (time_s aside).
    """
    start = perf_counter()
    method = METHODS[spec.method]
    kept: dict = {"snapshots": []} if keep_fields else {}    # saved with each checkpoint, refilled on resume
    bar = None
    if show_progress:
        bar = tqdm(total=spec.steps, unit="step", desc=f"{spec.method} load steps", leave=False)

    def after_step(p):
        if bar is not None:
            bar.update(len(p.steps) - bar.n)      # a resumed run starts at its checkpoint's step
            if p.steps:
                bar.set_postfix(newton=p.steps[-1]["newton_iterations"], cuts=p.steps[-1]["cuts"])
        exact_now = placed_exact(exact(setup.material, p.t), p.X, corner, R)     # once per step, for both
        if keep_fields:
            kept["snapshots"].append(_snapshot(exact_now, p, R))
        return {**errors(exact_now, p.X, p.x, p.sigma, p.V0, R),
                "penetration": penetration(p.lines, p.x)}

    if method.supports.body_fitted:       # the total-Lagrangian body-fitted reference
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
