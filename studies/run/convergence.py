"""Convergence study: one case refined by halving h, errors per level, fitted rates.

    levels     h_l = h_0 / 2^l, l = 0 .. n - 1, with h_0 = L / 10 by default
    delta law  "c*h" or "c*h^2": the band width delta (methods with a delta_rel parameter)
               follows delta = c h^p, i.e. delta_rel = c h^(p - 1). c is a number, or the
               letter c, which takes the method's delta_rel at the coarsest level
               (c = delta_rel_0 h_0^(1 - p)); without a law delta_rel stays fixed (= "c*h").
    rates      fitted: slope of np.polyfit(log h, log err, 1) over all levels (the skfem
               convention); level to level: log(e_(l-1) / e_l) / log(h_(l-1) / h_l).

Measured rate laws (RATE_LAWS; tests/studies/run/test_convergence.py asserts them to +-0.05). Problem
`manufactured`, ppc 2, offset (0.37, 0.29), h = L/10 .. L/80 (4 levels); fitted rates, the
smallest over the angles 90, 45 and 30 degrees (at 90 every method gives L2 2.00, energy 1.00):

    method     parameter law                         L2    energy
    ibm        delta = 1e-5 h (default delta/h)      1.39  0.75   stiff: locks on inclined rollers
    ibm        delta = 0.001 h^2                     1.94  0.98
    ibm-limit  delta = 1e-5 h (default delta/h)      1.39  0.91   stiff: locks on inclined rollers
    ibm-limit  delta = 0.01 h                        2.03  0.99
    penalty    beta = 1e6 M / h (default beta0)      1.07  0.64   stiff: locks on inclined rollers
    penalty    beta = 1e3 M / h                      2.13  1.00

Why: with a band of width delta the IBM acts like a penalty 4 M / (3 delta) (docs/seed.md). Too stiff a penalty over-constrains the bilinear field along an inclined
roller (the normal trace of a Q4 field on a cut line is quadratic) and the error stalls
until h is small; too soft a one leaves an O(delta) (O(h / beta0)) consistency error. In
the band form the strain also jumps across the band, so the energy error carries an
O(sqrt(delta)) part: delta ~ h^2 is needed for energy rate 1 (delta = c h gives 1/2 in
the limit), while the boundary-integral limit form has no band and keeps both rates with
delta = 0.01 h.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from baselines.registry import METHODS
from ibm.exceptions import InputError
from studies.run.case import CaseSpec, run_case, validate

ERROR_KEYS = ("err_l2", "err_energy", "err_u", "err_sigma")
MAX_LEVELS = 8
_LAW = re.compile(r"^\s*(?P<c>c|[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*\*\s*h\s*(?:\^\s*(?P<p>[12]))?\s*$")


@dataclass(frozen=True)
class DeltaLaw:
    """delta = coefficient * h^power; coefficient None means 'fit c to the coarsest level'."""

    text: str
    power: int
    coefficient: float | None = None

    def delta_rels(self, cells: list[float], delta_rel_0: float) -> list[float]:
        """delta / h at each cell size; the first one is delta_rel_0 when c is to be fitted."""
        c = self.coefficient
        if c is None:
            c = delta_rel_0 * cells[0] ** (1 - self.power)
        return [c * h ** (self.power - 1) for h in cells]


@dataclass(frozen=True)
class RateLaw:
    """A parameter law and the smallest fitted rates measured for it (see module doc)."""

    method: str
    law: str                                   # as written in the module doc's table
    l2: float
    energy: float
    delta_law: str | None = None
    method_parameters: tuple[tuple[str, float], ...] = ()


RATE_LAWS = (
    RateLaw("ibm", "delta = 1e-5 h (default delta/h)", 1.39, 0.75),
    RateLaw("ibm", "delta = 0.001 h^2", 1.94, 0.98, delta_law="0.001*h^2"),
    RateLaw("ibm-limit", "delta = 1e-5 h (default delta/h)", 1.39, 0.91),
    RateLaw("ibm-limit", "delta = 0.01 h", 2.03, 0.99, delta_law="0.01*h"),
    RateLaw("penalty", "beta = 1e6 M / h (default beta0)", 1.07, 0.64),
    RateLaw("penalty", "beta = 1e3 M / h", 2.13, 1.00, method_parameters=(("beta0", 1e3),)),
)
RATE_LAW_SETTINGS = {"problem": "manufactured", "ppc": 2, "levels": 4, "angles": (90.0, 45.0, 30.0)}


def parse_delta_law(text: str) -> DeltaLaw:
    match = _LAW.match(text)
    if match is None:
        raise InputError(f"delta law {text!r} is not allowed; use 'c*h' or 'c*h^2' "
                         "(c a number > 0, or the letter c for the method's delta/h at the coarsest level)")
    c = None if match["c"] == "c" else float(match["c"])
    if c is not None and not (math.isfinite(c) and c > 0):
        raise InputError(f"delta law coefficient {match['c']} is not allowed; it must be a number > 0")
    return DeltaLaw(text.strip(), int(match["p"] or 1), c)


def cell_sizes(coarse: float, levels: int) -> list[float]:
    if isinstance(levels, bool) or not isinstance(levels, int) or not 2 <= levels <= MAX_LEVELS:
        raise InputError(f"levels {levels!r} is not allowed; it must be an integer from 2 to {MAX_LEVELS}")
    return [coarse / 2 ** level for level in range(levels)]


def fitted_rate(h, errors) -> float | None:
    """Slope of log err against log h (None when an error is zero or not finite)."""
    h, errors = np.asarray(h, float), np.asarray(errors, float)
    if len(h) < 2 or not np.all(np.isfinite(errors) & (errors > 0)):
        return None
    return float(np.polyfit(np.log(h), np.log(errors), 1)[0])


def level_rates(h, errors) -> list[float | None]:
    """Rate between each level and the one before (None for the first level)."""
    return [None] + [fitted_rate(h[l - 1:l + 1], errors[l - 1:l + 1]) for l in range(1, len(h))]


def converge(base: CaseSpec, levels: int = 5, delta_law: str | DeltaLaw | None = None,
             coarse: float | None = None) -> dict:
    """Run `base` at `levels` cell sizes halving from `coarse` (default size / 10).

    Returns {"problem", "method", "angle", "delta_law", "levels": [record per level with
    rate_<key> level-to-level rates], "rates": {key: fitted rate}}.
    """
    cells = cell_sizes(max(base.width, base.height) / 10 if coarse is None else coarse, levels)
    validate(base.with_(cell=cells[0]))
    parameters = [dict(base.method_parameters) for _ in cells]
    if isinstance(delta_law, str):
        delta_law = parse_delta_law(delta_law)
    if delta_law is not None:
        method = METHODS[base.method]
        if "delta_rel" not in method.names:
            with_band = ", ".join(name for name, m in METHODS.items() if "delta_rel" in m.names)
            raise InputError(f"a delta law is not allowed for method {base.method!r}, which has no band width; "
                             f"it applies to: {with_band}")
        delta_rel_0 = base.method_parameters.get("delta_rel") or method.defaults()["delta_rel"]
        for chosen, delta_rel in zip(parameters, delta_law.delta_rels(cells, delta_rel_0)):
            chosen["delta_rel"] = delta_rel
    specs = [base.with_(cell=h, method_parameters=chosen) for h, chosen in zip(cells, parameters)]
    for spec in specs:   # every level is checked before the first (slow) solve
        validate(spec)
    records = [run_case(spec) for spec in specs]
    for key in ERROR_KEYS:
        for record, rate in zip(records, level_rates(cells, [r[key] for r in records])):
            record[f"rate_{key}"] = rate
    return {
        "problem": base.problem, "load_type": base.load_type, "method": base.method, "angle": base.angle,
        "offset": list(base.offset), "ppc": base.ppc,
        "delta_law": delta_law.text if delta_law is not None else None,
        "levels": records,
        "rates": {key: fitted_rate(cells, [r[key] for r in records]) for key in ERROR_KEYS},
    }


def table(result: dict) -> str:
    """The study as a plain-text table: one row per level, then the fitted rates."""
    def number(value, width=9):
        return f"{'-':>{width}}" if value is None else f"{value:>{width}.3g}"

    head = f"{result['problem']} ({result['load_type']}), method {result['method']}, angle {result['angle']:g}"
    if result["delta_law"]:
        head += f", delta = {result['delta_law']}"
    columns = ["h", "ndof"] + [part for key in ERROR_KEYS for part in (key, "rate")]
    if any(r.get("delta_rel") is not None for r in result["levels"]):
        columns.insert(2, "delta/h")
    lines = [head, "  ".join(f"{c:>9}" for c in columns)]
    for r in result["levels"]:
        row = [number(r["cell"]), f"{r['ndof']:>9d}"]
        if "delta/h" in columns:
            row.append(number(r.get("delta_rel")))
        row += [part for key in ERROR_KEYS for part in (f"{r[key]:>9.3e}", number(r[f"rate_{key}"]))]
        lines.append("  ".join(row))
    blank = ["", ""] + ([""] if "delta/h" in columns else [])
    fitted = [part for key in ERROR_KEYS for part in ("", number(result["rates"][key]))]
    lines.append("  ".join(f"{c:>9}" for c in ["fitted", *blank[1:], *fitted]))
    return "\n".join(lines)
