"""Tables of a study, built from the results rows of one sweep (pandas in, pandas out).

    seed_table          ours beside the seed paper's six numbers
    convergence_tables  level-to-level and least-squares fitted rates against h
    method_angle        one error per method (rows) and angle (columns)
    method_orientation  the same against the orientation (angle, tilt) of 3D cases
    placement_table     error statistics over placements
    cases_table         every case with its settings and errors
    collapse_table      the collapse problems: collapse load over its exact value per case
Failed cases never show a number: their cells read "failed" and the message is listed.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from baselines.registry import METHODS, method_parameters
from studies.problems.registry import get as get_problem
from studies.report.rows import curve, fmt
from studies.run.case import CaseSpec
from studies.run.identity import case_id
from studies.run.seed import PAPER, SEED_METHOD

ERRORS = ("err_u", "err_sigma", "err_sigma_ample", "err_l2", "err_energy")
ERROR_LABELS = {"err_u": "displacement error (material points)", "err_sigma": "loaded-direction stress error",
                "err_l2": "L2 displacement error (quadrature)", "err_energy": "energy-norm error (quadrature)",
                "err_sigma_fro": "stress error (whole tensor)", "cond_est": "condition estimate",
                "err_sigma_ample": "stress error, AMPLE's column measure"}
# the methods' parameters are labelled by their declarations (ibm.boundary_method.Parameter)
PARAMETERS = {name: declared[0] for name, declared in method_parameters().items()}
LOG_AXES = {"cell", "E", *(name for name, p in PARAMETERS.items() if p.log_scale)}     # drawn on log axes


def body_fitted(method: str) -> bool:
    """Whether the named method meshes the body itself (a method no longer installed counts as a grid method)."""
    return method in METHODS and METHODS[method].supports.body_fitted


AXIS_LABELS = {"cell": "cell size h", **{name: p.label or name for name, p in PARAMETERS.items()},
               "angle": "angle θ (degrees)", "offset": "placement",
               "ppc": "points per cell (per direction)", "nu": "Poisson's ratio ν", "E": "Young's modulus E",
               "steps": "load steps", "basis": "point basis", "width": "body width", "height": "body height",
               "kinematics": "kinematics", "step": "load step"}


def axis_columns(axis: str) -> list[str]:
    return {"offset": ["offset_x", "offset_y"], "orientation": ["angle", "tilt"]}.get(axis, [axis])


def sweep_rows(results: pd.DataFrame, cases) -> pd.DataFrame:
    """The stored rows of `cases` (a sweep's), in their order (missing ones left out)."""
    indexed = results.set_index("case_id", drop=False)
    return indexed.loc[[i for i in map(case_id, cases) if i in indexed.index]].reset_index(drop=True)


def error_columns(rows: pd.DataFrame) -> list[str]:
    """The error measures present (with at least one number) in these rows."""
    return [c for c in ERRORS if c in rows.columns and rows[c].notna().any()]


def group_axes(axes: dict, exclude: tuple[str, ...] = ()) -> list[str]:
    """The sweep's axes that take several values (the series of a figure), method first."""
    names = [k for k, v in axes.items() if len(v) > 1 and k not in exclude]
    names.sort(key=lambda k: (k != "problem", k != "method"))
    return names


def group_columns(axes: dict, exclude: tuple[str, ...] = ()) -> list[str]:
    return [c for k in group_axes(axes, exclude) for c in axis_columns(k)]


def series_label(key, columns: list[str]) -> str:
    values = key if isinstance(key, tuple) else (key,)
    parts = []
    for column, value in zip(columns, values):
        if column in ("method", "problem"):
            parts.append(str(value))
        else:
            parts.append(f"{column}={fmt(value)}")
    return ", ".join(parts) or "all"


def ok(rows: pd.DataFrame) -> pd.DataFrame:
    return rows[rows["status"] == "ok"]


def failed_table(rows: pd.DataFrame) -> pd.DataFrame:
    bad = rows[rows["status"] != "ok"]
    tilt = ["tilt"] if "tilt" in bad.columns and bad["tilt"].notna().any() else []     # 3D cases
    columns = ["problem", "method", "angle", *tilt, "cell", "parameters", "error"]
    return bad[[c for c in columns if c in bad.columns]].reset_index(drop=True)


def seed_table(rows: pd.DataFrame) -> pd.DataFrame:
    out = []
    for angle, (paper_u, paper_sigma) in PAPER.items():
        match = rows[(rows["method"] == SEED_METHOD) & (rows["angle"] == angle)]
        if match.empty:
            continue
        row = match.iloc[0]
        good = row["status"] == "ok"
        out.append({"angle": angle,
                    "err_u": row["err_u"] if good else "failed", "paper err_u": paper_u,
                    "err_sigma": row["err_sigma"] if good else "failed", "paper err_sigma": paper_sigma,
                    "ndof": row.get("ndof"), "cond_est": row.get("cond_est"),
                    "at or below paper": bool(good and row["err_u"] <= paper_u and row["err_sigma"] <= paper_sigma)})
    return pd.DataFrame(out)


def rates(h: np.ndarray, error: np.ndarray) -> tuple[np.ndarray, float]:
    """Level-to-level rates (first is NaN) and the least-squares slope of log e against log h."""
    h, error = np.asarray(h, float), np.asarray(error, float)
    good = np.isfinite(error) & (error > 0)
    level = np.full(len(h), np.nan)
    for i in range(1, len(h)):
        if good[i] and good[i - 1]:
            level[i] = np.log(error[i - 1] / error[i]) / np.log(h[i - 1] / h[i])
    fitted = float(np.polyfit(np.log(h[good]), np.log(error[good]), 1)[0]) if good.sum() >= 2 else np.nan
    return level, fitted


def convergence_tables(rows: pd.DataFrame, axes: dict) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(levels, fitted): errors and rates per grid level, and the fitted rate per series."""
    groups = group_columns(axes, exclude=("cell",))
    errors = error_columns(rows)
    levels, fitted = [], []
    for key, series in row_groups(rows, groups):
        series = series.sort_values("cell", ascending=False)
        good = series["status"] == "ok"
        level_rows = {"cell": series["cell"].to_numpy(), "ndof": series.get("ndof")}
        fit = dict(zip(groups, key if isinstance(key, tuple) else (key,)))
        for name in errors:
            values = series[name].where(good).to_numpy(float)
            level, slope = rates(series["cell"].to_numpy(float), values)
            level_rows[name] = np.where(good, values, np.nan)
            level_rows[f"rate {name}"] = level
            fit[f"fitted rate {name}"] = slope
        fit["levels"] = int(good.sum())
        block = pd.DataFrame(level_rows)
        for column, value in reversed(list(zip(groups, key if isinstance(key, tuple) else (key,)))):
            block.insert(0, column, value)
        block.insert(len(groups) + 1, "status", series["status"].to_numpy())
        levels.append(block)
        fitted.append(fit)
    return pd.concat(levels, ignore_index=True), pd.DataFrame(fitted)


def method_angle(rows: pd.DataFrame, axes: dict, error: str) -> pd.DataFrame:
    """error per series (rows: method and other varying settings) and angle (columns)."""
    groups = group_columns(axes, exclude=("angle",)) or ["method"]
    table = {}
    for key, series in row_groups(rows, groups):
        label = series_label(key, groups)
        table[label] = {fmt(a): (v if s == "ok" else "failed")
                        for a, v, s in zip(series["angle"], series[error], series["status"])}
    frame = pd.DataFrame(table).T
    frame.index.name = "series"
    angles = sorted(frame.columns, key=float)
    return frame[angles]


ORIENTATION_AXES = ("angle", "tilt", "orientation")


def orientation_label(angle, tilt) -> str:
    """'(30, 20)': a 3D case's angle about z and tilt about its own xi axis, in degrees."""
    return f"({fmt(float(angle))}, {fmt(float(tilt))})"


def orientations(rows: pd.DataFrame) -> list[str]:
    """The rows' orientation labels, distinct, in row (sweep) order."""
    return list(dict.fromkeys(orientation_label(a, t) for a, t in zip(rows["angle"], rows["tilt"])))


def method_orientation(rows: pd.DataFrame, axes: dict, error: str) -> pd.DataFrame:
    """error per series (rows: method and the other varying settings) and orientation "(angle, tilt)"
    (columns, in sweep order); failed cases read "failed"."""
    groups = group_columns(axes, exclude=ORIENTATION_AXES) or ["method"]
    table = {}
    for key, series in row_groups(rows, groups):
        table[series_label(key, groups)] = {orientation_label(a, t): (v if s == "ok" else "failed") for a, t, v, s
                                            in zip(series["angle"], series["tilt"], series[error], series["status"])}
    frame = pd.DataFrame(table).T
    frame.index.name = "series"
    return frame[[o for o in orientations(rows) if o in frame.columns]]


def placement_table(rows: pd.DataFrame, axes: dict) -> pd.DataFrame:
    groups = group_columns(axes, exclude=("offset",)) or ["method"]
    out = []
    for key, series in row_groups(rows, groups):
        entry = dict(zip(groups, key if isinstance(key, tuple) else (key,)))
        good = ok(series)
        entry["placements"] = len(series)
        entry["failed"] = int((series["status"] != "ok").sum())
        for name in error_columns(rows):
            values = good[name].to_numpy(float)
            entry[f"median {name}"] = float(np.median(values)) if len(values) else np.nan
            entry[f"max {name}"] = float(np.max(values)) if len(values) else np.nan
            entry[f"max/min {name}"] = float(values.max() / values.min()) if len(values) and values.min() > 0 else np.nan
        out.append(entry)
    return pd.DataFrame(out)


def cases_table(rows: pd.DataFrame, axes: dict) -> pd.DataFrame:
    """Every case: its id, status, the sweep's varying settings, errors, sizes, the step cuts of
    load-step cases (where a row has them) and the kind of a failed case's error."""
    columns = ["case_id", "status", "problem", "method"] + [c for c in group_columns(axes) if c not in ("problem", "method")]
    columns += [c for c in error_columns(rows) + ["err_sigma_fro", "cond_est", "ndof", "npoints"] if c in rows.columns]
    columns += [c for c in ("step_cuts", "error") if c in rows.columns and (c != "step_cuts" or rows[c].notna().any())]
    frame = rows[list(dict.fromkeys(columns))].reset_index(drop=True)
    if "error" in frame.columns:   # the kind only; the whole messages are in failed_table
        frame["error"] = error_kind(frame["error"])
    return frame.rename(columns={"step_cuts": STEP_CUTS})


STEP_CUTS = "step cuts"     # the column of the load steps' halvings (ibm.large.loadsteps) in the cases' tables


def step_cuts(row):
    """A row's step cuts (its converged steps'), NaN where the store has none (an older run)."""
    value = row.get("step_cuts")
    return int(value) if value is not None and pd.notna(value) else np.nan


def error_kind(messages: pd.Series) -> pd.Series:
    """'SolveError: ...' -> 'SolveError' (empty stays empty)."""
    return messages.str.split(":", n=1).str[0]


def row_groups(rows: pd.DataFrame, columns: list[str]):
    if not columns:
        yield (), rows
        return
    # dropna=False keeps series whose grouping parameter does not apply (NaN) to some methods
    for key, series in rows.groupby(columns, sort=False, dropna=False):
        yield key, series


def to_html(frame: pd.DataFrame, index: bool = False) -> str:
    return frame.to_html(index=index, border=0, classes="data", na_rep="–",
                         formatters={c: fmt for c in frame.columns}, escape=True)


# --- the collapse problems (studies.problems.collapse) ---------------------------------------------------

def collapse_table(rows: pd.DataFrame, problem: str) -> pd.DataFrame:
    """One row per case of the collapse problem `problem`, in sweep order: method, angle, h, offset, the
    problem's own columns (studies.problems.collapse.CollapseProblem.table_entry: its settings, the collapse
    load over its exact value), steps converged of those asked, Newton iterations (all steps), step cuts
    (of the converged steps) and time; a failed case reads "failed"."""
    out = []
    own = get_problem(problem)
    for _, row in rows[rows["problem"] == problem].iterrows():
        good = row["status"] == "ok"
        iterations = curve(row, "newton_iterations")
        entry = {"method": row["method"], "angle": row["angle"], "h": row["cell"], "offset": offset_of(row)}
        entry.update(own.table_entry(row, good, setting))
        entry["steps"] = f"{len(iterations)} of {int(row['steps'])}" if good else "failed"
        entry["Newton iterations"] = int(iterations.sum()) if good else "failed"
        entry[STEP_CUTS] = step_cuts(row) if good else "failed"
        entry["time (s)"] = row["time_s"] if good else np.nan
        out.append(entry)
    return pd.DataFrame(out)


def setting(row, name: str) -> str:
    """The row's setting `name` (locking, footing): the store leaves out CaseSpec's default."""
    value = row.get(name)
    return value if isinstance(value, str) else getattr(CaseSpec, name)


def offset_of(row) -> str:
    """The row's offset as text, "(ox, oy)" (the footing's: where its edge lies in its cell)."""
    return f"({fmt(float(row['offset_x']))}, {fmt(float(row['offset_y']))})"


def case_names(rows: pd.DataFrame) -> pd.Series:
    """Each row's method, with its offset when the rows' offsets differ (the footing's edge across its cell)."""
    if not len(rows):
        return pd.Series(dtype=str)
    offsets = rows.apply(offset_of, axis=1)
    return rows["method"] + (" at offset " + offsets if offsets.nunique() > 1 else "")


# --- the contact problems (studies.problems.frictional_block, studies.problems.hertz) ---------------------

def contact_table(rows: pd.DataFrame, problem: str) -> pd.DataFrame:
    """One row per case of the contact problem `problem`, in sweep order: method, angle, h, friction law, each
    measure the problem compares (Problem.compared: label -> (column, exact column)) with its exact value and
    their relative difference, the largest penetration, Newton iterations (all steps), step cuts and time; a
    failed case reads "failed"."""
    out = []
    own = get_problem(problem)
    for _, row in rows[rows["problem"] == problem].iterrows():
        good = row["status"] == "ok"
        entry = {"method": row["method"], "angle": row["angle"], "h": row["cell"], "friction": row.get("friction_law")}
        for label, (measured, exact) in own.compared.items():
            value, reference = (row.get(measured), row.get(exact)) if good else (np.nan, np.nan)
            entry[label] = value
            entry[f"{label} exact"] = reference
            entry[f"{label} rel. diff."] = (value - reference) / abs(reference) if good and reference else np.nan
        entry["max penetration"] = row.get("max_penetration") if good else np.nan
        entry["Newton iterations"] = int(curve(row, "newton_iterations").sum()) if good else "failed"
        entry[STEP_CUTS] = int(row["step_cuts"]) if good else "failed"
        entry["time (s)"] = row["time_s"] if good else np.nan
        out.append(entry)
    return pd.DataFrame(out)

