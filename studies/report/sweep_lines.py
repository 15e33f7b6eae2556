"""Figures of a sweep's errors as lines: each error measure (and the condition estimate) against the swept
setting, one line per series; the errors of every placement; the 3D cases' errors against orientation."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from studies.report.canvas import finish_figure, fit_layout, log_scale  # noqa: E402
from studies.report.panels import (  # noqa: E402
    finish_panel, finish_panels, mark_failed, panel_grid, slope_guides, series_styles
)
from studies.report.tables import (  # noqa: E402
    AXIS_LABELS, ERROR_LABELS, LOG_AXES, ORIENTATION_AXES, row_groups, error_columns, group_columns, orientation_label,
    orientations, series_label
)


def error_vs(rows: pd.DataFrame, axes: dict, x: str, path: Path, quantities: list[str] | None = None,
             title: str = "") -> Path:
    """One panel per error measure: error (log) against setting x, one line per series."""
    quantities = quantities or error_columns(rows)[:4] or ["err_u"]
    groups = group_columns(axes, exclude=(x,))
    fig, panels = panel_grid(len(quantities))
    for ax, quantity in zip(panels, quantities):
        failed_drawn: list = []
        styles = series_styles(rows, groups)
        for key, series in row_groups(rows, groups):
            series = series.sort_values(x)
            good = (series["status"] == "ok") & series[quantity].notna() & (series[quantity] > 0)
            label = series_label(key, groups) if groups else "all cases"
            ax.plot(series.loc[good, x], series.loc[good, quantity], ms=4, lw=1.3, label=label, **styles(key))
            mark_failed(ax, series.loc[series["status"] != "ok", x].to_numpy(float), None, failed_drawn)
        log_scale(ax, "xy" if x in LOG_AXES else "y")
        if x == "angle":
            ax.set_xticks(np.arange(0, 91, 15))
        if x == "cell":   # label the grid sizes themselves; slopes are in the convergence table
            sizes = np.unique(rows[x].dropna().to_numpy(float))
            ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
            ax.minorticks_off()
            slope_guides(ax, sizes, rows.loc[rows["status"] == "ok", quantity].to_numpy(float))
        ax.set_xlabel(AXIS_LABELS.get(x, x))
        ax.set_ylabel(f"relative {ERROR_LABELS.get(quantity, quantity)}")
        ax.grid(True, which="both", alpha=0.3)
    return finish_panels(fig, panels, path, title)


def cond_vs(rows: pd.DataFrame, axes: dict, x: str, path: Path, title: str = "") -> Path:
    groups = group_columns(axes, exclude=(x,))
    fig, ax = plt.subplots(figsize=(5.2, 3.8))
    failed_drawn: list = []
    styles = series_styles(rows, groups)
    for key, series in row_groups(rows, groups):
        series = series.sort_values(x)
        good = (series["status"] == "ok") & series["cond_est"].notna()
        ax.plot(series.loc[good, x], series.loc[good, "cond_est"], ms=4, **styles(key),
                label=series_label(key, groups) if groups else "condition estimate")
        mark_failed(ax, series.loc[series["status"] != "ok", x].to_numpy(float), None, failed_drawn)
    log_scale(ax, "xy" if x in LOG_AXES else "y")
    ax.set_xlabel(AXIS_LABELS.get(x, x))
    ax.set_ylabel("1-norm condition estimate (equilibrated system)")
    ax.grid(True, which="both", alpha=0.3)
    if x == "cell":
        sizes = np.unique(rows[x].dropna().to_numpy(float))
        ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
        ax.minorticks_off()
    return finish_panel(fig, ax, path, title)


def error_vs_placement(rows: pd.DataFrame, axes: dict, path: Path, title: str = "") -> Path:
    """Errors of every placement (dots) per series, with the median as a bar."""
    quantities = error_columns(rows)[:2] or ["err_u"]
    groups = group_columns(axes, exclude=("offset",)) or ["method"]
    fig, panels = plt.subplots(1, len(quantities), figsize=(4.8 * len(quantities), 3.8), squeeze=False)
    for ax, quantity in zip(panels[0], quantities):
        labels = []
        failed_drawn: list = []
        for index, (key, series) in enumerate(row_groups(rows, groups)):
            good = series[(series["status"] == "ok") & (series[quantity] > 0)][quantity].to_numpy(float)
            jitter = np.linspace(-0.15, 0.15, len(good)) if len(good) > 1 else np.zeros(len(good))
            ax.plot(index + jitter, good, "o", color=f"C{index % 10}", ms=4, alpha=0.8)
            if len(good):
                ax.hlines(np.median(good), index - 0.3, index + 0.3, color="black", lw=1.5)
            n_failed = int((series["status"] != "ok").sum())
            mark_failed(ax, np.full(n_failed, float(index)), None, failed_drawn)
            labels.append(series_label(key, groups))
        ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=8)
        log_scale(ax, "y")
        ax.set_ylabel(f"relative {ERROR_LABELS.get(quantity, quantity)}")
        ax.set_xlabel("series (dots: placements, bar: median)")
        ax.grid(True, axis="y", which="both", alpha=0.3)
        if failed_drawn:
            ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    fit_layout(fig)
    return finish_figure(fig, path)


def error_vs_orientation(rows: pd.DataFrame, axes: dict, path: Path, title: str = "") -> Path:
    """One panel per error measure: error (log) at each orientation (angle, tilt) of the sweep, in sweep
    order along x, one line per series."""
    quantities = error_columns(rows)[:4] or ["err_u"]
    groups = group_columns(axes, exclude=ORIENTATION_AXES) or ["method"]
    labels = orientations(rows)
    position = {label: i for i, label in enumerate(labels)}
    fig, panels = panel_grid(len(quantities))
    for ax, quantity in zip(panels, quantities):
        failed_drawn: list = []
        styles = series_styles(rows, groups)
        for key, series in row_groups(rows, groups):
            x = np.array([position[orientation_label(a, t)] for a, t in zip(series["angle"], series["tilt"])], float)
            good = ((series["status"] == "ok") & series[quantity].notna() & (series[quantity] > 0)).to_numpy()
            ax.plot(x[good], series[quantity].to_numpy(float)[good], ms=4, lw=1.3, label=series_label(key, groups),
                    **styles(key))
            mark_failed(ax, x[(series["status"] != "ok").to_numpy()], None, failed_drawn)
        log_scale(ax, "y")
        ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=8)
        ax.set_xlabel("orientation (angle θ, tilt ψ) in degrees")
        ax.set_ylabel(f"relative {ERROR_LABELS.get(quantity, quantity)}")
        ax.grid(True, which="both", alpha=0.3)
    return finish_panels(fig, panels, path, title)
