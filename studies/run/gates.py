"""Error gates: reference cases with a maximum error and/or a minimum convergence rate.

studies/run/thresholds.toml holds the gates; tests/studies/run/test_gates.py evaluates every one of them,
so a regression beyond a threshold fails CI with a message naming the case, the value and
the threshold:

    [[gate]]
    name = "seed-ibm-30"                                   # unique
    case = {problem = "confined-block", method = "ibm", angle = 30.0}   # CaseSpec fields and
    max = {err_u = 1e-6, err_sigma = 5e-6}                 #   method parameters
    [[gate]]
    name = "manufactured-ibm-rate"
    case = {problem = "manufactured", method = "ibm", angle = 30.0}
    cells = [20.0, 10.0, 5.0]                              # a refinement: rates are fitted,
    min_rate = {err_l2 = 1.8}                              #   max applies to the finest level
"""
from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ibm.exceptions import InputError
from studies.report.tables import rates
from studies.run.case import CaseSpec, closest, run_case, validate
from studies.run.spec import load_registries
from studies.run.spec_values import case_fields, method_parameter_kinds, scalar

THRESHOLDS = Path(__file__).with_name("thresholds.toml")
GATE_KEYS = ("name", "case", "cells", "max", "min_rate", "note")
QUANTITIES = ("err_u", "err_sigma", "err_sigma_fro", "err_u_max", "err_sigma_max", "err_l2", "err_energy",
              "cond_est")


@dataclass(frozen=True)
class Gate:
    name: str
    case: CaseSpec
    cells: tuple[float, ...] = ()
    max: dict = field(default_factory=dict)
    min_rate: dict = field(default_factory=dict)

    def describe(self) -> str:
        c = self.case
        text = f"{c.problem}, {c.method}, angle {c.angle:g}, h {c.cell:g}"
        if self.cells:
            text = f"{c.problem}, {c.method}, angle {c.angle:g}, h {'/'.join(f'{h:g}' for h in self.cells)}"
        if c.method_parameters:
            text += ", " + ", ".join(f"{k} {v:g}" for k, v in c.method_parameters.items())
        return text


@dataclass(frozen=True)
class Check:
    gate: str
    case: str
    quantity: str
    kind: str             # "max", "min_rate" or "failed"
    value: float
    threshold: float
    passed: bool
    detail: str = ""

    @property
    def message(self) -> str:
        where = f"gate {self.gate!r} ({self.case})"
        if self.kind == "failed":
            return f"{where}: the case failed: {self.detail}"
        if self.kind == "max":
            verdict = "exceeds the maximum" if not self.passed else "is within the maximum"
            return f"{where}: {self.quantity} = {self.value:.3e} {verdict} {self.threshold:.3e}"
        verdict = "is below the minimum" if not self.passed else "meets the minimum"
        return f"{where}: fitted rate of {self.quantity} = {self.value:.3f} {verdict} {self.threshold:.3f}"


def load(path: str | Path = THRESHOLDS) -> list[Gate]:
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise InputError(f"{path}: cannot read thresholds ({error})") from None
    return parse(data, str(path))


def parse(data: dict, source: str = "<thresholds>") -> list[Gate]:
    methods, _ = load_registries()
    fields, parameters = case_fields(), method_parameter_kinds(methods)
    for key in data:
        if key != "gate":
            raise InputError(f"{source}: unknown key {key!r}; allowed: gate")
    gates, names = [], set()
    for index, entry in enumerate(data.get("gate", [])):
        where = f"{source}: gate[{index}]"
        if not isinstance(entry, dict):
            raise InputError(f"{where} must be a table")
        for key in entry:
            if key not in GATE_KEYS:
                raise InputError(f"{where}: unknown key {key!r}{closest(key, GATE_KEYS)}; allowed: {', '.join(GATE_KEYS)}")
        name = entry.get("name")
        if not isinstance(name, str) or not name or name in names:
            raise InputError(f"{where}: name must be a unique non-empty string, got {name!r}")
        names.add(name)
        where = f"{source}: gate {name!r}"
        settings, method_parameters = {}, {}
        for key, value in entry.get("case", {}).items():
            if key in fields:
                settings[key] = scalar(value, fields[key], f"{where}: case.{key}")
            elif key in parameters:
                method_parameters[key] = scalar(value, parameters[key], f"{where}: case.{key}")
            else:
                allowed = tuple(fields) + tuple(parameters)
                raise InputError(f"{where}: unknown case key {key!r}{closest(key, allowed)}; allowed: {', '.join(allowed)}")
        case = CaseSpec(**settings, method_parameters=method_parameters)
        try:
            validate(case)
        except InputError as error:
            raise InputError(f"{where}: {error}") from None
        cells = tuple(scalar(h, "float", f"{where}: cells") for h in entry.get("cells", []))
        if cells and (len(cells) < 2 or any(h <= 0 for h in cells) or len(set(cells)) != len(cells)):
            raise InputError(f"{where}: cells must list at least two distinct sizes > 0, got {list(cells)}")
        limits = {}
        for kind in ("max", "min_rate"):
            table = entry.get(kind, {})
            if not isinstance(table, dict):
                raise InputError(f"{where}: {kind} must be a table quantity = number")
            for quantity, value in table.items():
                if quantity not in QUANTITIES:
                    raise InputError(f"{where}: {kind}.{quantity} is not a known quantity{closest(quantity, QUANTITIES)}; "
                                     f"allowed: {', '.join(QUANTITIES)}")
                number = scalar(value, "float", f"{where}: {kind}.{quantity}")
                if kind == "max" and number <= 0:
                    raise InputError(f"{where}: max.{quantity} {number:g} is not allowed; it must be > 0")
            limits[kind] = {q: float(v) for q, v in table.items()}
        if limits["min_rate"] and not cells:
            raise InputError(f"{where}: min_rate needs cells (a refinement of at least two sizes)")
        if not limits["max"] and not limits["min_rate"]:
            raise InputError(f"{where}: give max and/or min_rate")
        gates.append(Gate(name, case, tuple(sorted(cells, reverse=True)), limits["max"], limits["min_rate"]))
    if not gates:
        raise InputError(f"{source}: no [[gate]] entries")
    return gates


def evaluate(gate: Gate) -> list[Check]:
    """Solve the gate's case(s) and compare every listed quantity with its threshold."""
    load_registries()
    cases = [dataclasses.replace(gate.case, cell=h) for h in gate.cells] or [gate.case]
    records = []
    for case in cases:
        try:
            records.append(run_case(case))
        except Exception as error:      # a reference case that stops solving is a regression too
            return [Check(gate.name, gate.describe(), "", "failed", np.nan, np.nan, False,
                          f"{type(error).__name__}: {' '.join(str(error).split())}")]
    checks = []
    finest = records[-1]
    for quantity, threshold in gate.max.items():
        value = float(finest.get(quantity, np.nan))
        checks.append(Check(gate.name, gate.describe(), quantity, "max", value, threshold,
                            bool(np.isfinite(value) and value <= threshold)))
    for quantity, threshold in gate.min_rate.items():
        values = np.array([r.get(quantity, np.nan) for r in records], float)
        _, fitted = rates(np.array(gate.cells), values)
        checks.append(Check(gate.name, gate.describe(), quantity, "min_rate", fitted, threshold,
                            bool(np.isfinite(fitted) and fitted >= threshold)))
    return checks
