"""AMPLE-m's elasto-plastic collapse (its setupGrid_collapse.m), run by our large-deformation loop.

A 16 x 8 block of von Mises material on Hencky elasticity (E = 1e6, nu = 0.3, no hardening)
slumps under its own weight, rho g = 1000 * 10 ramped over the load steps. Half model: the
square [0, 8]^2 with its corner at the origin, a roller on the smooth base y = 0 and on the
symmetry line x = 0 (both on grid lines, as in AMPLE), the right side and the top free.

AMPLE's yield function is sqrt(2 J2) - rho_Y of the Kirchhoff stress tau with rho_Y = 20e3;
von Mises' sqrt(3 J2) = sigma_y is the same surface at sigma_y = sqrt(3/2) rho_Y, the yield stress
given to ibm.models.plasticity.HenckyJ2 (also on Kirchhoff stress). yield_ratio = max sqrt(2 J2(tau)) / rho_Y.

Measures of the points (X initial, x current, first column of points X < h / ppc the axis):
y_axis (the axis column's highest point), y_peak and x_peak (the highest point), runout (the
furthest x). Two equilibrium identities are exact for any grid method here: with v = x e_x and
v = y e_y, both in the grid's space and both tangential to the frictionless walls through the
origin's grid lines, equilibrium int sigma : grad v = int b . v gives (b = -t rho g e_y at load
fraction t)

    virial_xx = int sigma_xx dv / (t rho g sum V0 y) = 0,
    virial_yy = int sigma_yy dv / (-t rho g sum V0 y) = 1,

the body force's moment sum m_p y_p being exact for standard MPM; GIMP integrates the weight over
each point's domain, so there y is the domain's centroid, not the point (a 1e-6 gap at h = 2).
"""
from __future__ import annotations

import math
from time import perf_counter

import numpy as np
from shapely.errors import GEOSException

from baselines.registry import METHODS, treatment
from ibm.exceptions import InputError, StepFailure
from ibm.geometry.outline import Body
from ibm.large.loadsteps import Loading, Setup, run
from ibm.large.newton import Control
from ibm.models.plasticity import HenckyJ2
from ibm.solvers import backends as solvers
from studies.problems.problem import Problem
from studies.report.peer import AMPLE_COLLAPSE
from studies.run.collapse_runs import IBM_BAND

PROBLEM = "ample-collapse"
E, NU, RHO_Y, RHO, GRAVITY, SIDE = 1e6, 0.3, 20e3, 1000.0, 10.0, 8.0
YIELD_STRESS = math.sqrt(1.5) * RHO_Y
DEFAULTS = {"cell": 1.0, "ppc": 6, "steps": 40}   # AMPLE's run: h = 1, 6 x 6 points per cell, 40 steps
# Tying nodes below 1e-4 of a cell's support (ibm.discretise.support) keeps the free toe's nearly
# empty nodes from a singular solve while it leaves the solution AMPLE's (docs/choices.md).
SUPPORT_THRESHOLD = 1e-4
_FIXED = ("E", "nu", "load", "load_type", "material", "yield_stress", "hardening", "cohesion", "friction_angle",
          "dilation_angle", "width", "height", "locking")


def body():
    """The half model: rollers on the base and the symmetry line, the right side and the top free."""
    return Body(np.array([[0.0, 0.0], [SIDE, 0.0], [SIDE, SIDE], [0.0, SIDE]]), ("roller", "free", "free", "roller"))


def material():
    return HenckyJ2(E, NU, yield_stress=YIELD_STRESS, hardening=0.0)


def parameters(method: str) -> dict:
    """The method's large-deformation parameters on this problem and their defaults."""
    if method not in METHODS:
        return {}
    declared = METHODS[method].defaults(load_steps=True)
    if _runs_here(METHODS[method]):
        declared["support_threshold"] = SUPPORT_THRESHOLD
        if "delta_rel" in declared:            # a band's width, as on the other yielding bodies
            declared["delta_rel"] = IBM_BAND["smooth"]
    return declared


def _runs_here(method) -> bool:
    """Whether `method` runs this problem: a grid method of the load steps."""
    return "load-steps" in method.supports and not method.supports.body_fitted


def measures(X: np.ndarray, x: np.ndarray, h: float, ppc: int) -> dict:
    """y_axis, y_peak, x_peak and runout of the points (X initial, x current)."""
    axis = X[:, 0] < h / ppc
    peak = int(np.argmax(x[:, 1]))
    return {"y_axis": float(x[axis, 1].max()), "y_peak": float(x[peak, 1]), "x_peak": float(x[peak, 0]),
            "runout": float(x[:, 0].max())}


def equilibrium(x: np.ndarray, V0: np.ndarray, volume: np.ndarray, sigma: np.ndarray, t: float) -> dict:
    """virial_xx and virial_yy - 1 (both 0 in equilibrium) and the largest yield ratio."""
    moment = t * RHO * GRAVITY * np.sum(V0 * x[:, 1])
    tau = sigma * (volume / V0)[:, None, None]
    deviator = tau - np.trace(tau, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3
    return {"virial_xx": float(np.sum(sigma[:, 0, 0] * volume) / moment),
            "virial_yy_minus_1": float(np.sum(sigma[:, 1, 1] * volume) / -moment - 1),
            "yield_ratio": float(np.sqrt(np.sum(deviator ** 2, axis=(1, 2))).max() / RHO_Y)}


def side_by_side(result: dict, basis: str, h: float, ppc: int, steps: int) -> dict:
    """Our final measures against AMPLE's at the same setup (studies.report.peer), or {} where it was not run."""
    ample = AMPLE_COLLAPSE.get((basis, float(h), ppc, steps))
    if ample is None or result.get("stopped"):
        return {}
    return {"ample": ample, "runout_vs_ample": result["runout"] / ample["runout"] - 1,
            "y_axis_vs_ample": result["y_axis"] / ample["y_axis"] - 1,
            "y_peak_vs_ample": result["y_peak"] / ample["y_peak"] - 1}


def run_ample_collapse(method: str, h: float = DEFAULTS["cell"], ppc: int = DEFAULTS["ppc"],
                       steps: int = DEFAULTS["steps"], basis: str = "gimp", given: dict | None = None,
                       tolerance: float = 1e-9) -> dict:
    """Ramp the weight over `steps` load steps (cut on failure); the record: the parameters used,
    per step t, Newton iterations, cuts and the measures, the final measures and identities, and
    AMPLE's beside them where it ran the same setup."""
    used = {k: (given or {}).get(k) if (given or {}).get(k) is not None else v for k, v in parameters(method).items()}
    setup = Setup(body(), material(), Loading(body_force=np.array([0.0, -RHO * GRAVITY])), h=h, ppc=ppc, basis=basis,
                  steps=steps, margin=math.ceil(SIDE / h))            # the runout (about 1.7 SIDE) stays on the grid
    history, last = [], {}

    def after_step(progress):
        step = progress.steps[-1]
        history.append({"t": float(progress.t), "newton_iterations": int(step["newton_iterations"]),
                        "cuts": int(step["cuts"]), **measures(progress.X, progress.x, h, ppc)})
        last["progress"] = progress
        return {}

    failure = None
    try:
        run(setup, treatment(method, used), Control(tolerance=tolerance), after_step=after_step)
    except StepFailure as error:                       # the last converged step stands
        failure = str(error)
    except GEOSException as error:                     # the tracked outline folded over itself
        failure = f"load step {len(history) + 1}: the outline folded ({error})"
    record = {"method": method, **used, "npoints": 0, "stopped": failure, "history": history,
              "newton_iterations": [s["newton_iterations"] for s in history],
              "step_cuts": sum(s["cuts"] for s in history), "t_final": history[-1]["t"] if history else 0.0}
    if "progress" in last:
        p = last["progress"]
        record.update(npoints=len(p.X), **measures(p.X, p.x, h, ppc), **equilibrium(p.x, p.V0, p.volume, p.sigma, p.t))
        record.update(side_by_side(record, basis, h, ppc, steps))
    return record


# --- as a problem of a study (studies.problems.problem) -----------------------------------------

def settings(spec) -> tuple[float, int, int]:
    """(h, ppc, steps): the spec's, or the problem's own where the spec keeps CaseSpec's defaults."""
    defaults = type(spec)()
    return tuple(DEFAULTS[name] if getattr(spec, name) == getattr(defaults, name) else getattr(spec, name)
                 for name in ("cell", "ppc", "steps"))


class AmpleCollapse(Problem):
    """AMPLE's collapse: the method, its parameters, cell, ppc, steps and basis may be set; the rest is
    AMPLE's. Its record stands beside AMPLE-m's own run (side_by_side)."""

    name = PROBLEM
    in_specs = False                  # solved by `ibm-study solve`, beside AMPLE-m's own run
    summary = "AMPLE-m's elasto-plastic collapse of a block under its own weight, beside AMPLE's run"

    def area(self, spec) -> float:
        return SIDE ** 2

    def steps_allowed(self, spec) -> bool:
        return True

    def takes_band(self, spec) -> bool:
        return False

    def parameters(self, method: str) -> dict:
        return parameters(method)

    def load_stepped(self, spec) -> bool:
        return False

    def checkpoint_refusal(self, spec) -> str:
        return f"--checkpoint is not available for {PROBLEM!r} yet"

    def fields_refusal(self, spec) -> str:
        return f"--vtk is not available for {PROBLEM!r} yet"

    def validate(self, spec) -> None:
        defaults = type(spec)()
        given = [name for name in _FIXED if getattr(spec, name) != getattr(defaults, name)]
        if spec.kinematics not in (defaults.kinematics, "large"):
            given.append("kinematics")
        if given:
            raise InputError(f"problem {PROBLEM!r} has its own material, geometry and load (AMPLE's collapse: an 8 x 8 "
                             f"half model, E = 1e6, nu = 0.3, sqrt(2 J2) <= 20e3, rho g = 1e4, large kinematics); "
                             f"{', '.join(name.replace('_', '-') for name in given)} cannot be set")
        if spec.angle != 90.0 or tuple(spec.offset) not in ((0.0, 0.0), tuple(defaults.offset)):
            raise InputError(f"angle {spec.angle:g} and offset {tuple(spec.offset)} are not allowed for {PROBLEM!r} "
                             "yet; it is AMPLE's problem, whose walls lie on grid lines (angle 90, offset 0 0)")
        if spec.method in METHODS and not _runs_here(METHODS[spec.method]):
            raise InputError(f"method {spec.method!r} is not available for {PROBLEM!r}; allowed: "
                             f"{', '.join(n for n, m in METHODS.items() if _runs_here(m))}")
        h, ppc, steps = settings(spec)
        cells = SIDE / h
        if not (math.isfinite(cells) and abs(cells - round(cells)) < 1e-9 and 1 <= round(cells) <= 256):
            raise InputError(f"cell {h:g} is not allowed for {PROBLEM!r}; it must divide the side {SIDE:g} into 1 to "
                             "256 cells, so the points fill whole cells as AMPLE's do")
        if ppc < 2:
            raise InputError(f"ppc {ppc} is not allowed for {PROBLEM!r}; it must be >= 2 (one point per cell leaves "
                             "hourglass modes that the collapse sets free)")
        if steps < 5:
            raise InputError(f"steps {steps} is not allowed for {PROBLEM!r}; it must be >= 5 (e.g. 40, AMPLE's)")

    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        """The case's record: the settings, run_ample_collapse's results and the time."""
        start = perf_counter()
        h, ppc, steps = settings(spec)
        with solvers.choice(solver):
            result = run_ample_collapse(spec.method, h, ppc, steps, spec.basis, spec.method_parameters)
        return {"problem": PROBLEM, "angle": 90.0, "offset": [0.0, 0.0], "cell": h, "ppc": ppc, "steps": steps,
                "basis": spec.basis, "E": E, "nu": NU, "yield_stress": YIELD_STRESS, "rho_Y": RHO_Y,
                "density": RHO, "gravity": GRAVITY, "kinematics": "large", **result, "time_s": perf_counter() - start}


COLLAPSE = AmpleCollapse()
