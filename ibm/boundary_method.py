"""What a boundary method is: one object that declares its parameters and what it supports, and
does three things, its small-strain solve, its wall treatment inside the load steps and its
reaction on each essential piece.

    method.solve(model, **values) -> Solution          one linear solve (2D and, where supported, 3D)
    method.treatment(**values) -> treatment             treatment.step(StepContext) -> StepTerms (ibm.large.treatment)
    method.reactions(model, solution) -> {piece: F}     F (d,) the force the support puts on the body

Everything else about a method is read from its declaration: the command line's flags, the study
specs' keys, the checks of given values, the labels of tables and figures. A method of another
package is such an object too, registered under the entry-point group `ibm_mpm.methods`
(baselines.registry).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ibm.exceptions import InputError


@dataclass(frozen=True)
class Parameter:
    """One numeric parameter of a method: its spec key `name` (the flag is --name with dashes),
    its default, the allowed interval (low, high] or [low, high] when low_inclusive, what it means,
    a short label and symbol for tables and figures, and its default in the load steps where that
    differs (None: the same)."""

    name: str
    default: float
    meaning: str
    low: float = 0.0
    high: float = math.inf
    low_inclusive: bool = False
    label: str = ""
    symbol: str = ""
    log_scale: bool = False
    load_step_default: float | None = None

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")

    @property
    def allowed(self) -> str:
        """The allowed values in words: "in (0, 1]", "a number >= 0", "a number > 0"."""
        if math.isinf(self.high):
            return f"a number {'>=' if self.low_inclusive else '>'} {self.low:g}"
        return f"in {'[' if self.low_inclusive else '('}{self.low:g}, {self.high:g}]"

    def check(self, value) -> None:
        """InputError naming the value unless it is a finite number in the allowed interval."""
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if not (number and math.isfinite(value) and (self.low < value or (self.low_inclusive and value == self.low))
                and value <= self.high):
            raise InputError(f"{self.flag[2:]} {value!r} is not allowed; it must be {self.allowed}")

    def default_for(self, load_steps: bool) -> float:
        return self.load_step_default if load_steps and self.load_step_default is not None else self.default


# What a method can be asked to do, each with the words of its refusal.
CAPABILITIES = ("3d", "load-steps", "load-steps-3d", "arcs", "off-grid", "amg", "contact")
# Capabilities a method has only where it declares them (Supports.granted), with the refusal otherwise.
OPT_IN = {"contact": "it has no contact treatment (unilateral walls with friction)"}


@dataclass(frozen=True)
class Supports:
    """What a method supports: for each capability it lacks, the one-line reason it refuses.

    3d: box problems in 3D; load-steps: large kinematics and plasticity in 2D; load-steps-3d: the
    same in 3D; arcs: curved essential pieces; off-grid: walls that do not lie on grid lines;
    amg: systems that CG with algebraic multigrid can solve (symmetric positive definite);
    contact: contact walls in the load steps (ibm.contact), opt-in: only where `granted` names it.
    body_fitted: the method meshes the body itself (no background grid, no material points of
    its own); band_kinematics: it takes the --band choice of the load steps."""

    refusals: dict = field(default_factory=dict)     # capability -> why not
    body_fitted: bool = False
    band_kinematics: bool = False
    granted: tuple = ()                              # the opt-in capabilities it has (OPT_IN)

    def __post_init__(self):
        unknown = (set(self.refusals) | set(self.granted)) - set(CAPABILITIES)
        if unknown:
            raise ValueError(f"unknown capabilities {sorted(unknown)}; known: {', '.join(CAPABILITIES)}")

    def __contains__(self, capability: str) -> bool:
        if capability in OPT_IN and capability not in self.granted:
            return False
        return capability not in self.refusals

    def refusal(self, capability: str) -> str:
        """Why the method lacks `capability` (its own words, or the opt-in's)."""
        return self.refusals.get(capability) or OPT_IN[capability]


class BoundaryMethod:
    """A boundary method: subclasses set the class attributes and implement what they support."""

    name: str = ""
    summary: str = ""
    parameters: tuple[Parameter, ...] = ()
    supports: Supports = Supports()

    # --- what every method does ------------------------------------------------------------------
    def solve(self, model, **values):
        """One linear elastic solve of `model` with the method's parameter values -> ibm.small.model.Solution."""
        raise NotImplementedError

    def treatment(self, **values):
        """The method's walls inside a load step (ibm.large.treatment's interface)."""
        self.require("load-steps")
        raise NotImplementedError

    def reactions(self, model, solution) -> dict:
        """F_e (d,) on every essential piece e of a solved small-strain case, by the method's definition."""
        raise InputError(f"method {self.name!r} has no reaction definition")

    # --- read from the declaration -------------------------------------------------------------
    def parameter(self, name: str) -> Parameter:
        for parameter in self.parameters:
            if parameter.name == name:
                return parameter
        raise InputError(f"{name.replace('_', '-')} is not a parameter of method {self.name!r}; its parameters: "
                         f"{', '.join(p.flag[2:] for p in self.parameters) or 'none'}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def defaults(self, load_steps: bool = False) -> dict:
        return {p.name: p.default_for(load_steps) for p in self.parameters}

    def used(self, given: dict, load_steps: bool = False, defaults: dict | None = None) -> dict:
        """The value of each parameter a run uses: given (not None), else `defaults` (a problem's own),
        else the declared default (in the load steps where that differs)."""
        base = {**self.defaults(load_steps), **(defaults or {})}
        return {k: given[k] if given.get(k) is not None else v for k, v in base.items()}

    def check(self, values: dict) -> None:
        """InputError for the first value that is no parameter of the method or out of its range."""
        for name, value in values.items():
            if value is not None:
                self.parameter(name).check(value)

    def require(self, capability: str, allowed=()) -> None:
        """InputError in one line with the method's reason unless it supports `capability` (naming the
        `allowed` methods that do, when given)."""
        if capability not in self.supports:
            others = f"; allowed: {', '.join(allowed)}" if allowed else ""
            raise InputError(f"method {self.name!r} refuses {_WORDS[capability]}: "
                             f"{self.supports.refusal(capability)}{others}")

    def __call__(self, model, **settings):
        """Solve, reading only this method's own parameters from `settings` (None: the default)."""
        return self.solve(model, **self.used({k: settings.get(k) for k in self.names}))

    def __repr__(self) -> str:
        return f"<boundary method {self.name!r}>"


_WORDS = {"3d": "3D cases (dim = 3)", "load-steps": "large kinematics and the load steps of plasticity",
          "load-steps-3d": "large kinematics in 3D", "arcs": "essential arcs",
          "off-grid": "walls off the grid lines", "amg": "the amg solver",
          "contact": "contact walls (unilateral, with friction)"}
