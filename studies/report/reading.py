"""A short reading of the results: plain sentences with the numbers that matter, generated from the
stored rows, for each sweep's section and for the overview at the top of the page."""
from __future__ import annotations

import numpy as np
import pandas as pd

from studies.problems.registry import collapse_names, get as get_problem
from studies.report import tables
from studies.report.sweep_figures import view_case, view_label
from studies.run.identity import case_id
from studies.run.spec import Study, Sweep, locking_pairs


def reading(sweep: Sweep, rows: pd.DataFrame) -> list[str]:
    """Plain sentences with the numbers that matter, generated from the rows."""
    good = tables.ok(rows)
    out = []
    if "seed" in sweep.tables:
        seed = tables.seed_table(rows)
        if len(seed):
            both = seed["at or below paper"].all()
            pairs = "; ".join(f"{tables.fmt(r['angle'])}°: {tables.fmt(r['err_u'])} / {tables.fmt(r['err_sigma'])} "
                              f"(paper {tables.fmt(r['paper err_u'])} / {tables.fmt(r['paper err_sigma'])})"
                              for _, r in seed.iterrows())
            out.append(f"Seed cases, err_u / err_sigma: {pairs}. "
                       + ("All six are at or below the paper's numbers." if both
                          else "Not all six are at or below the paper's numbers."))
    if "convergence" in sweep.tables:
        _, fitted = tables.convergence_tables(rows, sweep.axes)
        groups = tables.group_columns(sweep.axes, exclude=("cell",))
        for _, fit in fitted.iterrows():
            rates = ", ".join(f"{c.removeprefix('fitted rate ')} {tables.fmt(fit[c])}"
                              for c in fitted.columns if c.startswith("fitted rate") and np.isfinite(fit[c]))
            label = tables.series_label(tuple(fit[g] for g in groups), groups) if groups else "all cases"
            out.append(f"Fitted rates against h for {label}: {rates or 'not enough levels'}.")
    if ("method-angle" in sweep.tables or "error-vs-angle" in sweep.figures) and len(good):
        by = ["problem", "method"] if len(sweep.axes["problem"]) > 1 else ["method"]
        for error in tables.error_columns(rows)[:2]:
            worst = good.groupby(by)[error].max().sort_values()
            text = ", ".join(f"{tables.series_label(k, by)} {tables.fmt(v)}" for k, v in worst.items())
            out.append(f"Worst {error} over the angles {tables.fmt(min(sweep.axes['angle']))}–"
                       f"{tables.fmt(max(sweep.axes['angle']))}° (best first): {text}.")
    for axis in tables.PARAMETERS:
        if axis in sweep.axes and len(sweep.axes[axis]) > 1:
            groups = tables.group_columns(sweep.axes, exclude=(axis,))
            for key, series in tables.row_groups(good, groups):
                series = series.dropna(subset=[axis]).sort_values(axis)
                if len(series) < 2:
                    continue
                lo, hi = series.iloc[0], series.iloc[-1]
                text = (f"{tables.series_label(key, groups)}: from {axis} = {tables.fmt(lo[axis])} to "
                        f"{tables.fmt(hi[axis])}, err_u goes from {tables.fmt(lo['err_u'])} to {tables.fmt(hi['err_u'])}")
                if "cond_est" in series and series["cond_est"].notna().all():
                    text += f" and the condition estimate from {tables.fmt(lo['cond_est'])} to {tables.fmt(hi['cond_est'])}"
                best = series.loc[series["err_u"].idxmin()]
                out.append(text + f"; the smallest err_u, {tables.fmt(best['err_u'])}, is at {axis} = {tables.fmt(best[axis])}.")
    if ("method-orientation" in sweep.tables or "error-vs-orientation" in sweep.figures) and len(good):
        shown = ", ".join(tables.orientations(rows))
        for error in tables.error_columns(rows)[:2]:
            by = tables.group_columns(sweep.axes, exclude=tables.ORIENTATION_AXES) or ["method"]
            worst = good.groupby(by, sort=False)[error].max().sort_values()
            text = ", ".join(f"{tables.series_label(k, by)} {tables.fmt(v)}" for k, v in worst.items())
            out.append(f"Worst {error} over the orientations (θ, ψ) = {shown} (best first): {text}.")
    if "error-view-3d" in sweep.figures:
        case = view_case(sweep)
        row = rows[rows["case_id"] == case_id(case)]
        if len(row) and row["status"].iloc[0] == "ok":
            row = row.iloc[0]
            out.append(f"The 3D view shows {view_label(case)}: {int(row['npoints'])} points, the largest "
                       f"|u_h − u| / max |u| {tables.fmt(row['err_u_max'])} (err_u {tables.fmt(row['err_u'])}), "
                       f"the largest stress error over max |σ_ηη| {tables.fmt(row['err_sigma_max'])}.")
    collapse_sweep = bool(set(sweep.axes["problem"]) & set(collapse_names()))
    if "offset" in sweep.axes and len(sweep.axes["offset"]) > 1 and len(good) and not collapse_sweep:
        groups = tables.group_columns(sweep.axes, exclude=("offset",)) or ["method"]
        for key, series in tables.row_groups(good, groups):
            values = series["err_u"].to_numpy(float)
            if len(values) > 1 and values.min() > 0:
                out.append(f"{tables.series_label(key, groups)}: over {len(values)} placements err_u ranges from "
                           f"{tables.fmt(values.min())} to {tables.fmt(values.max())} "
                           f"(a factor {tables.fmt(values.max() / values.min())}).")
    if collapse_sweep and len(good):
        out += collapse_reading(sweep, good)
    bad = rows[rows["status"] != "ok"]
    if len(bad):
        kinds = tables.error_kind(bad["error"]).value_counts()
        by_method = bad.groupby("method").size()
        out.append(f"{len(bad)} case(s) failed and show no numbers ("
                   + ", ".join(f"{m}: {n}" for m, n in by_method.items()) + "; "
                   + ", ".join(f"{k} ×{n}" for k, n in kinds.items()) + "); their messages are listed below.")
    return out


def collapse_reading(sweep: Sweep, good: pd.DataFrame) -> list[str]:
    """Sentences on the collapse cases (solved rows): per problem, angle and h, each method's collapse
    load against the exact one and which are close; then each locked case beside its remedied twin
    (the sentences are the problem's, studies.problems.collapse.CollapseProblem)."""
    out = []
    locked = ~good["method"].map(tables.body_fitted) & (good.apply(tables.setting, axis=1, args=("locking",)) == "none")
    for (problem, angle, cell), group in good[~locked].groupby(["problem", "angle", "cell"], sort=False):
        names = tables.case_names(group)
        own = get_problem(problem)
        text, ratio = own.reading(group, names, angle, cell)
        target, within = own.target_name(group), own.within
        close = names[(ratio - 1).abs() <= within].tolist()
        if close:
            text += f". Within {100 * within:g} % of {target}: {', '.join(close)}."
        else:
            best = int(np.argmin((ratio - 1).abs().to_numpy()))
            text += (f". None is within {100 * within:g} % of {target}; the closest is {names.iloc[best]} "
                     f"({100 * (ratio.iloc[best] - 1):+.1f} %).")
        out.append(text)
    by_id = good.set_index("case_id")
    for none, fbar in locking_pairs(sweep.cases):
        a, b = case_id(none), case_id(fbar)
        if a not in by_id.index or b not in by_id.index:
            continue
        out.append(get_problem(none.problem).locked_reading(none, by_id.loc[a], by_id.loc[b]))
    return out


def overview(study: Study, results: pd.DataFrame, run: dict) -> list[str]:
    ids = {case_id(c) for c in study.cases()}
    rows = results[results["case_id"].isin(ids)]
    times = rows["time_s"].dropna() if "time_s" in rows else pd.Series(dtype=float)
    out = [f"{len(ids)} distinct cases in {len(study.sweeps)} sweeps; {int((rows['status'] == 'ok').sum())} solved, "
           f"{int((rows['status'] != 'ok').sum())} failed, {len(ids) - len(rows)} not run yet."]
    if len(times):
        out.append(f"Solver time summed over cases {times.sum():.1f} s (median {times.median() * 1e3:.0f} ms per case).")
    if run:
        where = f"on the dask scheduler {run['scheduler']}" if run.get("scheduler") else f"with {run.get('jobs')} worker processes"
        out.append(f"Last run: {run.get('run')} cases run, {run.get('reused')} reused from earlier runs, {where}, "
                   f"wall time {run.get('wall_s')} s, finished {run.get('finished')}"
                   + (" (interrupted)" if run.get("interrupted") else "") + ".")
    return out
