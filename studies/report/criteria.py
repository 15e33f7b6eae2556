"""The criteria of the report's scorecard (studies.report.verdict): what each column measures, per method,
from the stored rows of the sweeps a study assigns to it, and how its number is banded.

A study's spec names, under [verdict], the sweeps each criterion reads (docs/studies.md):

    [verdict]
    patch-test = ["angles", "settlement-patch"]
    parameter-range = {sweeps = ["delta", "penalty", "nitsche"], problems = ["manufactured"]}

Every measure takes `parts` (a list of (Sweep, rows) pairs, rows already narrowed to the named problems)
and the scorecard's methods, and returns a Cell per method it has a number (or a word) for. Bands are
"good", "fair" or "poor"; a value below ROUNDOFF counts as exact.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from baselines.registry import METHODS
from studies.problems.registry import get as get_problem
from studies.report import tables
from studies.report.rows import curve, fmt

ROUNDOFF = 1e-9          # an error below it is exact to round-off (the patch tests' floor)


@dataclass(frozen=True)
class Cell:
    value: float = np.nan     # the banded number (NaN: none)
    text: str = ""            # shown in place of the number ("none to choose", "3 of 40")
    detail: str = ""          # where the number comes from (the worst case), shown on hover
    sweep: str = ""           # the sweep it comes from (the cell links to its section)
    band: str = ""            # set for a word that carries its own band ("none to choose" is good)


@dataclass(frozen=True)
class Criterion:
    name: str                                   # the spec's key under [verdict]
    label: str                                  # the column's header
    meaning: str                                # one line: what the number is
    measure: Callable                           # (parts, methods) -> {method: Cell}
    band: Callable                              # (value, best of the column) -> "good" | "fair" | "poor"
    better: str = "lower"                       # or "higher"
    job: str = ""                               # the job it answers, for "which method when"


def below(good: float, fair: float) -> Callable:
    """Absolute bands of a lower-is-better number."""
    return lambda value, best: "good" if value <= good else "fair" if value <= fair else "poor"


def above(good: float, fair: float) -> Callable:
    """Absolute bands of a higher-is-better number."""
    return lambda value, best: "good" if value >= good else "fair" if value >= fair else "poor"


def near_best(good: float = 2.0, fair: float = 10.0) -> Callable:
    """Bands by the ratio to the column's best (lower is better; values below ROUNDOFF count as ROUNDOFF)."""
    def band(value, best):
        ratio = max(value, ROUNDOFF) / max(best, ROUNDOFF)
        return "good" if ratio <= good else "fair" if ratio <= fair else "poor"
    return band


# --- helpers over the parts ------------------------------------------------------------------------------

def _frame(parts) -> pd.DataFrame:
    """Every part's rows in one frame with a 'sweep' column and the derived columns: err_patch (the larger of
    err_u and err_sigma) and penetration_h (the largest penetration over the cell size)."""
    frames = [rows.assign(sweep=sweep.name) for sweep, rows in parts if len(rows)]
    if not frames:
        return pd.DataFrame(columns=["method", "status", "sweep"])
    frame = pd.concat(frames, ignore_index=True)
    frame["err_patch"] = frame[[c for c in ("err_u", "err_sigma") if c in frame]].max(axis=1)
    if "max_penetration" in frame:
        frame["penetration_h"] = frame["max_penetration"] / frame["cell"]
    return frame


def _where(row) -> str:
    """'confined-block, θ = 30°, h = 10' for a row."""
    return f"{row['problem']}, θ = {fmt(row['angle'])}°, h = {fmt(row['cell'])}"


def _failed_only(frame: pd.DataFrame, cells: dict) -> dict:
    """'failed' for each method with rows but none solved."""
    for method, rows in frame.groupby("method", sort=False):
        if method not in cells and (rows["status"] != "ok").all():
            cells[method] = Cell(text="failed", sweep=rows["sweep"].iloc[0], band="poor")
    return cells


def _series(sweep, rows: pd.DataFrame, exclude: tuple[str, ...]):
    """(method, rows) per series of a sweep: its varying settings but `exclude`, the method always."""
    groups = ["method"] + [c for c in tables.group_columns(sweep.axes, exclude=exclude) if c != "method"]
    for key, series in tables.row_groups(rows, groups):
        yield key[0], series


def _keep(cells: dict, method: str, cell: Cell, lower_is_worse: bool = False) -> None:
    """Keep the method's worse cell of the one it has and `cell` (the larger value, or the smaller)."""
    kept = cells.get(method)
    if kept is None or (cell.value < kept.value if lower_is_worse else cell.value > kept.value):
        cells[method] = cell


def worst(column: str) -> Callable:
    """The largest `column` over each method's solved rows."""
    def measure(parts, methods) -> dict:
        frame = _frame(parts)
        cells = {}
        good = frame[frame["status"] == "ok"].dropna(subset=[column]) if column in frame else frame.iloc[:0]
        for method, rows in good.groupby("method", sort=False):
            row = rows.loc[rows[column].idxmax()]
            cells[method] = Cell(float(row[column]), detail=f"worst: {_where(row)}", sweep=row["sweep"])
        return _failed_only(frame, cells)
    return measure


def fitted_rate(column: str) -> Callable:
    """The median over each method's series of the fitted rate of `column` against h (two levels or more)."""
    def measure(parts, methods) -> dict:
        found: dict[str, list] = {}
        for sweep, rows in parts:
            for method, series in _series(sweep, rows[rows["status"] == "ok"], ("cell",)):
                if column not in series or series[column].notna().sum() < 2:
                    continue
                _, rate = tables.rates(series["cell"].to_numpy(float), series[column].to_numpy(float))
                if np.isfinite(rate):
                    found.setdefault(method, []).append((rate, series.iloc[0], sweep.name))
        cells = {}
        for method, entries in found.items():
            lowest = min(entries, key=lambda e: e[0])
            cells[method] = Cell(float(np.median([e[0] for e in entries])), sweep=entries[0][2],
                                 detail=f"median of {len(entries)} series; lowest {lowest[0]:.2f} "
                                        f"({lowest[1]['problem']}, θ = {fmt(lowest[1]['angle'])}°)")
        return cells
    return measure


def placement_spread(parts, methods) -> dict:
    """The largest ratio of the worst to the best err_u over the placements of one series."""
    cells = {}
    for sweep, rows in parts:
        for method, series in _series(sweep, rows[rows["status"] == "ok"], ("offset",)):
            errors = np.maximum(series["err_u"].to_numpy(float), ROUNDOFF)
            if len(errors) > 1:
                _keep(cells, method, Cell(float(errors.max() / errors.min()), sweep=sweep.name,
                                          detail=f"{len(errors)} placements, err_u {fmt(errors.min())} to "
                                                 f"{fmt(errors.max())}"))
    return cells


def parameter_range(parts, methods) -> dict:
    """Decades of a method's swept parameter over which err_u stays within 2x of its best (the unbroken run
    of solved values around the best); the narrowest over its series. A method that declares no parameter
    has none to choose."""
    cells = {}
    for sweep, rows in parts:
        for axis in [a for a in tables.PARAMETERS if len(sweep.axes.get(a, ())) > 1]:
            for method, series in _series(sweep, rows.dropna(subset=[axis]), (axis,)):
                series = series.sort_values(axis)
                error = np.maximum(series["err_u"].where(series["status"] == "ok").to_numpy(float), ROUNDOFF)
                if not np.isfinite(error).any():
                    continue
                best = int(np.nanargmin(error))
                inside = np.isfinite(error) & (error <= 2 * error[best])
                lo = hi = best
                while lo > 0 and inside[lo - 1]:
                    lo -= 1
                while hi < len(error) - 1 and inside[hi + 1]:
                    hi += 1
                values = series[axis].to_numpy(float)
                where = f"{series['problem'].iloc[0]}, θ = {fmt(series['angle'].iloc[0])}°"
                _keep(cells, method, Cell(float(np.log10(values[hi] / values[lo])), sweep=sweep.name,
                                          detail=f"{axis} from {fmt(values[lo])} to {fmt(values[hi])} ({where})"),
                      lower_is_worse=True)
    for method in methods:
        if method in METHODS and not METHODS[method].parameters:
            cells.setdefault(method, Cell(np.inf, text="none to choose", band="good"))
    return cells


def newton_per_step(parts, methods) -> dict:
    """The mean Newton iterations per converged load step over each method's solved rows."""
    frame = _frame(parts)
    cells = {}
    for method, rows in frame[frame["status"] == "ok"].groupby("method", sort=False):
        counts = [curve(row, "newton_iterations") for _, row in rows.iterrows()]
        counts = np.concatenate(counts) if counts else np.empty(0)
        if len(counts):
            cells[method] = Cell(float(counts.mean()), detail=f"{len(counts)} steps, at most {int(counts.max())}",
                                 sweep=rows["sweep"].iloc[0])
    return _failed_only(frame, cells)


def total(column: str) -> Callable:
    """The sum of `column` over each method's solved rows."""
    def measure(parts, methods) -> dict:
        frame = _frame(parts)
        cells = {}
        for method, rows in frame[frame["status"] == "ok"].groupby("method", sort=False):
            values = rows[column].dropna() if column in rows else pd.Series(dtype=float)
            if len(values):
                cells[method] = Cell(float(values.sum()), detail=f"over {len(values)} cases",
                                     sweep=rows["sweep"].iloc[0])
        return _failed_only(frame, cells)
    return measure


def _finest(sweep, rows: pd.DataFrame):
    """(method, rows at the smallest h) per series of a sweep."""
    for method, series in _series(sweep, rows, ("cell",)):
        yield method, series[series["cell"] == series["cell"].min()]


def collapse_error(parts, methods) -> dict:
    """The largest |collapse load / exact - 1| at each series' finest h (the problem's own ratio)."""
    cells = {}
    for sweep, rows in parts:
        good = rows[rows["status"] == "ok"]
        for method, finest in _finest(sweep, good):
            for problem, group in finest.groupby("problem", sort=False):
                own = get_problem(problem)
                if own.collapse:
                    error = (own.load_ratio(group) - 1).abs()
                    _keep(cells, method, Cell(float(error.max()), detail=f"worst: {_where(group.loc[error.idxmax()])}",
                                              sweep=sweep.name))
    return cells


def contact_error(parts, methods) -> dict:
    """The largest relative difference of a contact measure from its exact value at each series' finest h."""
    cells = {}
    for sweep, rows in parts:
        for method, finest in _finest(sweep, rows[rows["status"] == "ok"]):
            for _, row in finest.iterrows():
                for label, (measured, exact) in get_problem(row["problem"]).compared.items():
                    value, reference = row.get(measured), row.get(exact)
                    if reference is not None and np.isfinite(reference) and reference != 0:
                        _keep(cells, method, Cell(float(abs(value - reference) / abs(reference)), sweep=sweep.name,
                                                  detail=f"worst: {label}, {_where(row)}"))
    return cells


def cost_at_equal_error(parts, methods) -> dict:
    """Each method's time to reach the error every method of a refinement series reaches (log-log
    interpolation between its levels), over the fastest one's; the median over the series."""
    found: dict[str, list] = {}
    for sweep, rows in parts:
        good = rows[(rows["status"] == "ok") & rows["time_s"].notna()]
        column = "err_energy" if "err_energy" in good and good["err_energy"].notna().all() else "err_u"
        for key, series in tables.row_groups(good, tables.group_columns(sweep.axes, exclude=("cell", "method"))):
            curves = {m: s.sort_values(column) for m, s in series.groupby("method", sort=False) if len(s) >= 2}
            if len(curves) < 2:
                continue
            target = max(s[column].min() for s in curves.values())
            times = {m: float(np.exp(np.interp(np.log(target), np.log(s[column].to_numpy(float)),
                                               np.log(s["time_s"].to_numpy(float)))))
                     for m, s in curves.items()}
            fastest = min(times.values())
            for method, time in times.items():
                found.setdefault(method, []).append((time / fastest, target, sweep.name))
    return {m: Cell(float(np.median([e[0] for e in entries])), sweep=entries[0][2],
                    detail=f"median of {len(entries)} series, at {fmt(entries[0][1])} and like errors")
            for m, entries in found.items()}


def amg_iterations(parts, methods) -> dict:
    """The mean conjugate-gradient iterations with algebraic multigrid; a method that refuses it says so."""
    frame = _frame(parts)
    cells = {}
    for method, rows in frame[frame["status"] == "ok"].groupby("method", sort=False):
        if "amg_iterations" in rows and rows["amg_iterations"].notna().any():
            cells[method] = Cell(float(rows["amg_iterations"].mean()), sweep=rows["sweep"].iloc[0],
                                 detail=f"mean over {int(rows['amg_iterations'].notna().sum())} cases, at most "
                                        f"{int(rows['amg_iterations'].max())}")
    for method in methods:
        if method in METHODS and "amg" in METHODS[method].supports.refusals:
            cells[method] = Cell(text="refuses", detail=METHODS[method].supports.refusals["amg"], band="poor")
    return _failed_only(frame, cells)


def failures(parts, methods) -> dict:
    """The fraction of each method's cases that failed (by design, as an indefinite system, or by error)."""
    frame = _frame(parts)
    cells = {}
    for method, rows in frame.groupby("method", sort=False):
        failed = int((rows["status"] != "ok").sum())
        sweeps = rows.loc[rows["status"] != "ok", "sweep"]
        cells[method] = Cell(failed / len(rows), text=f"{failed} of {len(rows)}",
                             sweep=sweeps.iloc[0] if failed else "",
                             detail=("failed in " + ", ".join(dict.fromkeys(sweeps)))[:200] if failed else "")
    return cells


PATCH = below(ROUNDOFF, 1e-4)
CRITERIA = (
    Criterion("patch-test", "patch test", "the largest err_u or err_sigma on fields a consistent method "
              "reproduces exactly (linear small strain, homogeneous finite strain)",
              worst("err_patch"), PATCH, job="exactness on a patch test"),
    Criterion("rate-l2", "L2 rate", "the median fitted rate of err_l2 against h (2 is optimal for bilinear cells)",
              fitted_rate("err_l2"), above(1.8, 1.4), "higher", job="convergence in L2"),
    Criterion("rate-energy", "energy rate", "the median fitted rate of err_energy against h (1 is optimal)",
              fitted_rate("err_energy"), above(0.9, 0.7), "higher", job="convergence in energy"),
    Criterion("placements", "worst / best placement", "the largest ratio of the worst to the best err_u over "
              "random placements of the body in the grid", placement_spread, below(2.0, 10.0),
              job="indifference to where the boundary cuts the grid"),
    Criterion("parameter-range", "parameter range (decades)", "the decades of the method's parameter (δ, β₀, γ) "
              "over which err_u stays within 2x of its best", parameter_range, above(3.0, 1.0), "higher",
              job="freedom from tuning"),
    Criterion("corners", "corners, partial walls", "the largest err_u on a non-convex body whose walls meet at "
              "a re-entrant corner or cover part of a side", worst("err_u"), near_best(),
              job="corners and partial walls"),
    Criterion("curved", "curved walls", "the largest err_u on bodies with curved essential or free boundaries",
              worst("err_u"), near_best(), job="curved walls"),
    Criterion("large-error", "large deformation err_u", "the largest err_u over load-step cases whose material "
              "slides along inclined walls", worst("err_u"), near_best(), job="large deformation"),
    Criterion("large-newton", "Newton / step", "the mean Newton iterations per converged load step",
              newton_per_step, near_best(1.25, 2.0), job="Newton's convergence in the load steps"),
    Criterion("large-cuts", "step cuts", "the load steps halved because Newton failed, summed over cases",
              total("step_cuts"), below(0, 10), job="robust load steps"),
    Criterion("penetration", "penetration / h", "the largest penetration of a wall, over the cell size",
              worst("penetration_h"), below(1e-3, 1e-1), job="keeping material out of walls"),
    Criterion("collapse", "collapse load", "the largest |collapse load / exact - 1| at the finest grid",
              collapse_error, below(0.05, 0.15), job="collapse loads"),
    Criterion("contact", "contact", "the largest relative difference of a contact force, slip or width from "
              "its exact value at the finest grid", contact_error, below(0.01, 0.05), job="contact and friction"),
    Criterion("three-d", "3D", "the largest err_u or err_sigma on the 3D patch test over orientations",
              worst("err_patch"), PATCH, job="3D walls at any orientation"),
    Criterion("cost", "cost at equal error", "time to reach the error every method reaches, over the fastest "
              "method's (median over refinement series)", cost_at_equal_error, below(2.0, 5.0),
              job="cost at a given accuracy"),
    Criterion("amg", "AMG iterations", "the mean iterations of conjugate gradients with algebraic multigrid",
              amg_iterations, near_best(1.5, 3.0), job="iterative solvers"),
    Criterion("failed", "cases failed", "the cases that failed of those run (indefinite systems by design "
              "included)", failures, below(0.0, 0.1)),
)
BY_NAME = {criterion.name: criterion for criterion in CRITERIA}
