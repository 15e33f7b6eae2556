"""Collapse loads at small strain: Hill's thick cylinder under a ramped inner pressure.

The quarter ring a <= r <= b (rollers on both symmetry lines, the outer arc free, the pressure p
on the inner arc) of von Mises material, perfectly plastic, at the data of de Souza Neto, Peric
and Owen: a = 100, b = 200, E = 210e3, nu = 0.3, sigma_y = 240. With k = sigma_y / sqrt(3) and
the plastic zone out to radius c (Hill; exact for Tresca, close for von Mises in plane strain):

    p(c) = k (1 - c^2 / b^2 + 2 ln(c / a)),   u_b(c) = (k c^2 / b) (1 / (2 (lam + mu)) + 1 / (2 mu)),

from first yield p_y = k (1 - a^2 / b^2) (c = a) to the limit p_lim = 2 k ln(b / a) = 192.09
(c = b). u_b is the outer radius's expansion: the elastic ring c <= r <= b under the pressure
k (1 - c^2 / b^2) at r = c (Lame, plane strain). The pressure is ramped past p_lim in load steps
with step cutting; the last converged pressure is p_final, and the run's pressure-expansion
curve (u_b from the material points of the outermost layer) stands beside Hill's.
"""
from __future__ import annotations

from dataclasses import dataclass
from time import perf_counter

import numpy as np

from baselines.fem.plastic import ORDER, run_fem_plastic
from baselines.registry import METHODS, require, treatment
from ibm.exceptions import InputError
from ibm.large.loadsteps import Loading, Setup, run
from ibm.large.newton import Control
from ibm.models.elastic import Elastic
from ibm.models.small_strain import VonMises
from ibm.solvers import backends as solvers
from studies.problems.library import Parameters, get_problem
from studies.problems.materials import FRICTIONAL, material_record, model_of
from studies.problems.problem import Problem
from studies.report.rows import curve, fmt
from studies.run.collapse_runs import final_fields, step_cuts, until_failure, with_defaults

A, B, E, NU, YIELD = 100.0, 200.0, 210e3, 0.3, 240.0


@dataclass(frozen=True)
class Hill:
    """Hill's solution for the cylinder a, b of a material (E, nu, sigma_y)."""

    a: float = A
    b: float = B
    E: float = E
    nu: float = NU
    yield_stress: float = YIELD

    @property
    def k(self) -> float:
        return self.yield_stress / np.sqrt(3)

    @property
    def p_lim(self) -> float:
        return 2 * self.k * np.log(self.b / self.a)

    @property
    def p_yield(self) -> float:
        return self.k * (1 - self.a ** 2 / self.b ** 2)

    def curve(self, count: int = 101) -> tuple[np.ndarray, np.ndarray]:
        """(u_b (m,), p (m,)): the elastic line from 0 to first yield, then c from a to b."""
        lam = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        mu = self.E / (2 * (1 + self.nu))
        compliance = 1 / (2 * (lam + mu)) + 1 / (2 * mu)
        c = np.linspace(self.a, self.b, count)
        p = self.k * (1 - c ** 2 / self.b ** 2 + 2 * np.log(c / self.a))
        u = self.k * c ** 2 / self.b * compliance
        return np.r_[0.0, u], np.r_[0.0, p]


def frictional_limit(cohesion: float, friction_angle: float, a: float = A, b: float = B) -> float:
    """The limit pressure of the cylinder in Mohr-Coulomb soil (plane strain, sigma_z intermediate): the
    whole ring on sigma_r = N sigma_theta + 2 c sqrt(N) (compression positive, N = (1 + sin phi) / (1 - sin
    phi)) with sigma_r(b) = 0 gives c cot phi ((b / a)^(2 sin phi / (1 + sin phi)) - 1), 2 c ln(b / a) as phi
    -> 0 (docs/plasticity.md)."""
    phi = np.radians(friction_angle)
    if phi == 0:
        return 2 * cohesion * np.log(b / a)
    return cohesion / np.tan(phi) * ((b / a) ** (2 * np.sin(phi) / (1 + np.sin(phi))) - 1)


def hill_body(angle: float, offset, cell: float):
    """The quarter ring a <= r <= b about the grid node + offset * cell, turned like every problem."""
    corner = np.asarray(offset, float) * cell
    return get_problem("lame").body(Parameters(Elastic(E, NU), 1.0, width=B, height=B), angle, corner), corner


def run_hill(method: str, angle: float = 30.0, offset=(0.37, 0.29), cell: float = 10.0, ppc: int = 2,
             steps: int = 20, overshoot: float = 1.05, basis: str = "mpm", parameters: dict | None = None,
             tolerance: float = 1e-9, locking: str = "fbar", keep_fields: bool = False, checkpoint=None,
             soil=None) -> dict:
    """Ramp the inner pressure to overshoot * p_lim in `steps` load steps (cut on failure); the record:
    p_final (the last converged pressure), p_lim, p_yield, the curve (u_b, p) per converged step and
    Hill's, the Newton iterations per step and the step cuts; with keep_fields, "fields"
    (final_fields). checkpoint: (grid methods) a file each converged step is saved to, the curve
    with it; a run that finds it resumes (ibm.large.loadsteps.run) to the same result."""
    hill = Hill()
    body, corner = hill_body(angle, offset, cell)
    # soil: a frictional model (ibm.models.isotropic.FrictionalSoil) in place of von Mises, its limit for p_lim
    p_lim = frictional_limit(soil.cohesion, soil.friction_angle) if soil is not None else hill.p_lim
    target = overshoot * p_lim
    material = soil if soil is not None else VonMises(E, NU, yield_stress=YIELD)
    # (u_b, p) and the Newton iterations per converged step; checkpointed, refilled on resume
    kept: dict = {"curve": [], "iterations": []}
    extra: dict = {}

    def converged(u_b: float, t: float, count: int) -> dict:
        kept["curve"].append((u_b, t * target))
        kept["iterations"].append(int(count))
        return {"p": t * target, "u_b": u_b}

    def after_fem_step(record):
        outer = record["piece_nodes"][1]                     # the outer arc r = b (its nodes lie on it)
        x, u = record["nodes"][outer] - corner, record["displacement"][outer]
        return converged(float(np.mean(np.sum(u * x, axis=1) / np.linalg.norm(x, axis=1))), record["t"],
                         record["newton_iterations"])

    def after_step(progress):
        r = np.linalg.norm(progress.X - corner, axis=1)
        outer = r > B - cell / ppc                           # the outermost layer of points
        radial = (progress.X[outer] - corner) / r[outer, None]
        u_b = float(np.mean(np.sum((progress.x[outer] - progress.X[outer]) * radial, axis=1) * B / r[outer]))
        return converged(u_b, progress.t, progress.steps[-1]["newton_iterations"])

    if METHODS[method].supports.body_fitted:     # body-fitted P2 triangles of size cell (baselines.fem.plastic)
        locking = "none"
        progress, failure = until_failure(run_fem_plastic, body, material, {3: target}, cell, steps,
                                          tolerance=tolerance, after_step=after_fem_step)
        extra = {"p_last_substep": progress.t * target,       # with the cut substeps of the failed step
                 "n_elements": int(progress.polygon.mesh.nelements), "ndof": int(progress.ndof)}
        if keep_fields:
            extra["fields"] = final_fields(body, cell, 0, ORDER, progress)
    else:
        setup = Setup(body, material, Loading(pressures={3: target}), cell, ppc, basis, steps, locking=locking)
        progress, failure = until_failure(run, setup, treatment(method, with_defaults(method, parameters)),
                                          Control(tolerance=tolerance), after_step=after_step, checkpoint=checkpoint,
                                          extra=kept)
        if keep_fields:
            extra["fields"] = final_fields(body, cell, setup.margin, 0, progress)
    u_hill, p_hill = hill.curve() if soil is None else (np.empty(0), np.empty(0))     # Hill's curve: von Mises
    curve = kept["curve"]
    p_final = curve[-1][1] if curve else 0.0
    return {"method": method, "angle": angle, "cell": cell, "ppc": ppc, "steps": steps, "locking": locking,
            "p_final": p_final, "p_lim": p_lim, "p_yield": hill.p_yield if soil is None else np.nan,
            "p_over_p_lim": p_final / p_lim,
            "curve_u": [u for u, _ in curve], "curve_p": [p for _, p in curve],
            "hill_u": u_hill.tolist(), "hill_p": p_hill.tolist(), "stopped": failure,
            "newton_iterations": kept["iterations"], "step_cuts": step_cuts(progress), **extra}


# --- as a problem of a study (studies.problems.problem) -----------------------------------------

_FIXED = ("E", "nu", "load", "load_type", "material", "yield_stress", "hardening", "width", "height")
_SOIL = ("material", "cohesion", "friction_angle", "dilation_angle")     # a frictional soil's own settings


class CollapseProblem(Problem):
    """A problem measuring a collapse load by load steps past it (no exact field): the method, its
    parameters, angle, offset, cell, ppc, steps, basis and locking may be set; its material, geometry
    and load are its own. A subclass gives own_data, capability, run_own and the report's hooks."""

    collapse = True
    large_kinematics = False          # whether the grid methods may run it at large kinematics
    capability = "off-grid"           # what the grid methods must support (ibm.boundary_method.CAPABILITIES)
    materials: tuple[str, ...] = ()   # the materials a case may name in place of its own (studies.problems.materials)

    def own_data(self) -> str:
        """Its material, geometry and load in one line."""
        raise NotImplementedError

    def steps_allowed(self, spec) -> bool:
        return True

    def locking_applies(self, spec) -> bool:
        return True

    def takes_band(self, spec) -> bool:
        return False                  # its treatment is built from its own defaults (studies.run.collapse_runs)

    def validate(self, spec) -> None:
        defaults = type(spec)()                                  # the settings a collapse problem fixes stay at these
        own = _SOIL if spec.material in self.materials else ()
        given = [name for name in dict.fromkeys((*_FIXED, *_SOIL))
                 if name not in own and getattr(spec, name) != getattr(defaults, name)]
        if given:
            raise InputError(f"problem {spec.problem!r} has its own material, geometry and load ({self.own_data()}); "
                             f"{', '.join(name.replace('_', '-') for name in given)} cannot be set")
        if spec.steps < 5:
            raise InputError(f"steps {spec.steps} is not allowed for {spec.problem!r}; it must be >= 5 (e.g. 20): the "
                             "load is ramped past the collapse")
        if spec.method not in METHODS:               # named by studies.run.case.validate
            return
        method = METHODS[spec.method]
        if spec.kinematics == "large" and (not self.large_kinematics or method.supports.body_fitted):
            raise InputError(f"kinematics 'large' is not available for {spec.problem!r} with {spec.method!r}; it is "
                             "for the footing with the grid methods (the tracked outline has no arcs, fem is "
                             "small-strain)")
        if method.supports.body_fitted:
            if spec.locking != "none":
                raise InputError("locking is for the grid methods; fem's P2 triangles (3 Gauss points) do not lock "
                                 "(give --locking none)")
            return
        if spec.ppc < 2:
            raise InputError(f"ppc {spec.ppc} is not allowed for {spec.problem!r}; it must be >= 2 (one point per cell "
                             "leaves hourglass modes that a collapse mechanism sets free)")
        require(spec.method, "load-steps")
        require(spec.method, self.capability)

    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        """The case's record: the settings and the problem's results (run_own), the Newton iterations per
        step, the step cuts and the time. With keep_fields, "fields" holds the final points and their
        plastic strain (studies.run.collapse_runs.final_fields). checkpoint: (grid methods) a file each
        converged load step is saved to; a run that finds it resumes from it to the same record (a run
        stopped past the collapse solves its failing step again)."""
        start = perf_counter()
        parameters = {k: v for k, v in spec.method_parameters.items() if v is not None}
        with solvers.choice(solver):
            record = self.run_own(spec, parameters, keep_fields, checkpoint)
        record["time_s"] = perf_counter() - start
        return record

    def run_own(self, spec, parameters: dict, keep_fields: bool, checkpoint) -> dict:
        """The record without its time."""
        raise NotImplementedError

    # --- the report's hooks (studies.report: rows are pandas Series of the study's table) ----------
    table_title = ""                  # the caption of its collapse table
    curve_figure = ("", "")           # (figure kind, caption) of its load-displacement curves
    target, within = "", 0.0          # the exact limit's name, the fraction of it that counts as close

    def target_name(self, group) -> str:
        """The exact limit's name for a group of rows (one problem, angle and h): `target` unless it varies."""
        return self.target

    def table_entry(self, row, good: bool, setting) -> dict:
        """Its own columns of the collapse table; setting(row, name) reads a setting the store may omit."""
        raise NotImplementedError

    def load_ratio(self, rows):
        """Each solved row's collapse load over the exact one (a Series aligned with `rows`)."""
        raise NotImplementedError

    def reading(self, group, names, angle: float, cell: float) -> tuple[str, object]:
        """The sentence on one group of solved rows at (angle, cell), and their collapse loads over the
        exact one (a Series aligned with `names`)."""
        raise NotImplementedError

    def locked_reading(self, case, lock, remedy) -> str:
        """The sentence on a locked run (its case and row) beside its remedied twin's row."""
        raise NotImplementedError

    def curve(self, row) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of a row's load-displacement curve."""
        raise NotImplementedError

    def x_limit(self, row) -> float:
        """The right end of a panel of its curves (inf: as drawn)."""
        return np.inf

    def draw_limit(self, ax, row) -> None:
        """The exact limit on a matplotlib axis, with the axis labels."""
        raise NotImplementedError

    def setting_label(self, row) -> str:
        return f"θ = {row['angle']:g}°, h = {row['cell']:g}"


class HillCylinder(CollapseProblem):
    name = "hill-cylinder"
    summary = ("Hill's thick cylinder of von Mises (or frictional) material under a ramped inner pressure, beside "
               "p_lim")
    capability = "arcs"                # the bore
    materials = tuple(FRICTIONAL)     # or Mohr-Coulomb / Drucker-Prager soil, beside its own limit
    figures = ("pressure-expansion", "plastic-zones", "locking")

    def own_data(self) -> str:
        return (f"a = {A:g}, b = {B:g}, E = {E:g}, nu = {NU:g}, sigma_y = {YIELD:g}, the pressure ramped to "
                "1.05 p_lim")

    def area(self, spec) -> float:
        return np.pi / 4 * (B ** 2 - A ** 2)

    table_title = "Hill's cylinder: the last converged pressure over p_lim, the expansion beside Hill's"
    curve_figure = ("pressure-expansion", "Pressure-expansion curves of every method beside Hill's")
    target, within = "p_lim", 0.01

    def run_own(self, spec, parameters: dict, keep_fields: bool, checkpoint) -> dict:
        frictional = spec.material in FRICTIONAL
        result = run_hill(spec.method, spec.angle, spec.offset, spec.cell, spec.ppc, spec.steps, basis=spec.basis,
                          parameters=parameters, locking=spec.locking, keep_fields=keep_fields,
                          checkpoint=checkpoint, soil=model_of(spec.with_(E=E, nu=NU), "small") if frictional else None)
        return {"problem": spec.problem, "offset": list(spec.offset), "basis": spec.basis, "E": E, "nu": NU,
                **(material_record(spec) if frictional else {"yield_stress": YIELD}), "a": A, "b": B,
                "kinematics": "small", **result}


    def table_entry(self, row, good: bool, setting) -> dict:
        return {"locking": setting(row, "locking"), "p_final / p_lim": row["p_over_p_lim"] if good else "failed",
                f"u_b gap to Hill (p ≤ {HILL_CURVE_UP_TO:g} p_lim)": hill_gap(row) if good else "failed"}

    def load_ratio(self, rows):
        return rows["p_over_p_lim"]

    def reading(self, group, names, angle: float, cell: float):
        ratio = self.load_ratio(group)
        values = ", ".join(f"{m} {r:.4f}" for m, r in zip(names, ratio))
        gaps = [hill_gap(row) for _, row in group.iterrows()]
        worst = int(np.nanargmax(gaps)) if np.isfinite(gaps).any() else None
        text = f"Hill's cylinder at θ = {fmt(angle)}°, h = {fmt(cell)}: p_final / p_lim {values}"
        if worst is not None:
            text += (f"; the expansion u_b is within {100 * gaps[worst]:.2g} % of Hill's up to "
                     f"{HILL_CURVE_UP_TO:g} p_lim for every method (the largest gap: {names.iloc[worst]})")
        return text, ratio

    def locked_reading(self, case, lock, remedy) -> str:
        steps = len(curve(lock, "curve_p"))
        fate = "carries the whole ramp" if not isinstance(lock.get("stopped"), str) else "stops"
        return (f"Locked (locking none), {case.method} at θ = {fmt(case.angle)}°, "
                f"h = {fmt(case.cell)}: {fate} to {lock['p_over_p_lim']:.4f} p_lim ({steps} of "
                f"{case.steps} steps converged), where B-bar collapses at {remedy['p_over_p_lim']:.4f} p_lim.")

    def curve(self, row):
        return curve(row, "curve_u"), curve(row, "curve_p") / row["p_lim"]

    def x_limit(self, row) -> float:
        hill = curve(row, "hill_u")                # 1.5 times Hill's expansion at the limit: a locked ring runs on
        return 1.5 * hill[-1] if len(hill) else np.inf

    def draw_limit(self, ax, row) -> None:
        u, p = curve(row, "hill_u"), curve(row, "hill_p") / row["p_lim"]
        ax.plot(u, p, color="black", lw=2.2, alpha=0.35, label="Hill", zorder=1)
        frictional = not len(u)                    # Hill's curve is von Mises'; a soil has its limit alone
        ax.axhline(1.0, color="black", lw=1.0, linestyle=(0, (4, 2)), zorder=3,
                   label="p_lim = c cot φ ((b/a)^(2 sin φ/(1 + sin φ)) − 1)" if frictional else "p_lim = 2k ln(b/a)")
        ax.set_xlabel("outer expansion u_b")
        ax.set_ylabel("inner pressure p / p_lim")


HILL_CURVE_UP_TO = 0.95        # the curves are compared with Hill's up to this fraction of p_lim


def hill_gap(row) -> float:
    """The largest relative gap of the run's outer expansion u_b from Hill's at the same pressure,
    over its converged steps up to HILL_CURVE_UP_TO p_lim (NaN without such steps, or without Hill's curve: a frictional soil)."""
    u, p = curve(row, "curve_u"), curve(row, "curve_p")
    hill_u, hill_p = curve(row, "hill_u"), curve(row, "hill_p")
    shown = (p > 0) & (p <= HILL_CURVE_UP_TO * row["p_lim"])
    if not shown.any() or not len(hill_p):         # no Hill's curve for a frictional soil
        return np.nan
    exact = np.interp(p[shown], hill_p, hill_u)          # Hill's p rises with u_b
    return float(np.max(np.abs(u[shown] - exact) / exact))


HILL = HillCylinder()
