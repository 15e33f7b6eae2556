"""Figures of the contact problems (studies.problems.contact): each measure a problem compares (its wall
force, slip length, contact half-width, ...) against the load fraction, every case beside its exact value,
and the penetration each method allows."""
from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from studies.problems.registry import get as get_problem  # noqa: E402
from studies.report.canvas import log_scale  # noqa: E402
from studies.report.panels import finish_panels, panel_grid, series_styles  # noqa: E402
from studies.report.tables import group_columns, series_label  # noqa: E402


def contact_curves(rows: pd.DataFrame, axes: dict, path: Path, title: str = "") -> Path:
    """One panel per measure the problem compares (Problem.compared: label -> (column, exact column)) against
    the load fraction t, one line per case (coloured by method), its exact value as a thin black line with
    dots; a last panel with each step's largest penetration (log). Failed cases are left out and named in
    the title."""
    problem = get_problem(rows["problem"].iloc[0])
    measures = list(problem.compared.items())
    fig, panels = panel_grid(len(measures) + 1)
    groups = group_columns(axes)
    styles = series_styles(rows, groups)
    exact_drawn, failed = False, []
    for _, row in rows.iterrows():
        key = tuple(row[g] for g in groups)
        if row.get("status") != "ok" or not isinstance(row.get("history"), str):
            failed.append(series_label(key, groups))
            continue
        history = json.loads(row["history"])
        t = np.array([s["t"] for s in history], float)

        def values(name):
            return np.array([np.nan if s.get(name) is None else s[name] for s in history], float)
        for ax, (label, (measured, exact)) in zip(panels, measures):
            ax.plot(t, values(measured), lw=1.3, ms=3, label=series_label(key, groups),
                    **styles(key))
            ax.plot(t, values(exact), color="black", lw=0.7, marker=".", ms=3, zorder=5,
                    label=None if exact_drawn else "exact (each case's)")
            exact_drawn = True
            ax.set_ylabel(label, fontsize=8)
        penetration = values("max_penetration")
        good = penetration > 0
        panels[-1].plot(t[good], penetration[good], lw=1.3, ms=3, **styles(key))
    for ax in panels:
        ax.set_xlabel("load fraction t")
        ax.grid(True, alpha=0.3)
    log_scale(panels[-1], "y")
    panels[-1].set_ylabel("largest penetration in the step", fontsize=8)
    if failed:
        title = f"{title} (failed: {'; '.join(failed)})" if title else f"failed: {'; '.join(failed)}"
    return finish_panels(fig, panels, path, title)
