"""Figures of the large-deformation column: each error measure and the Newton iterations against the load
step, the stress error against h beside the peer's (AMPLE-m), the stress profile at the last step, and
snapshots of the deformed body."""
from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402

from studies.report.canvas import finish_figure, log_colorbar, log_scale  # noqa: E402
from studies.report.maps import draw_setting, marker_area  # noqa: E402
from studies.report.panels import (  # noqa: E402
    finish_panel, finish_panels, mark_failed, panel_grid, slope_guides, series_styles
)
from studies.report.tables import AXIS_LABELS, ERROR_LABELS, row_groups, group_columns, series_label  # noqa: E402


def _history(rows: pd.DataFrame):
    """(row, steps (k,), {measure: (k,)}, newton iterations (k,)) of every successful large case."""
    for _, row in rows.iterrows():
        if row.get("status") != "ok" or not isinstance(row.get("history"), str):
            continue
        history = json.loads(row["history"])
        measures = {m: np.array([h[m] for h in history], float) for m in ("err_u", "err_sigma", "err_sigma_ample")}
        yield row, np.array([h["step"] for h in history]), measures, np.array(
            [h["newton_iterations"] for h in history])


def error_vs_step(rows: pd.DataFrame, axes: dict, path: Path, title: str = "") -> Path:
    """Each error measure (log) against the load step, one line per case of the sweep."""
    groups = group_columns(axes)
    quantities = ["err_u", "err_sigma", "err_sigma_ample"]
    fig, panels = panel_grid(len(quantities))
    styles = series_styles(rows, groups)
    for row, steps, measures, _ in _history(rows):
        key = tuple(row[g] for g in groups)
        for ax, quantity in zip(panels, quantities):
            values = measures[quantity]
            good = values > 0
            ax.plot(steps[good], values[good], lw=1.2, ms=3, label=series_label(key, groups), **styles(key))
    for ax, quantity in zip(panels, quantities):
        log_scale(ax, "y")
        ax.set_xlabel("load step")
        ax.set_ylabel(f"relative {ERROR_LABELS.get(quantity, quantity)}", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    return finish_panels(fig, panels, path, title)


def newton_iterations(rows: pd.DataFrame, axes: dict, path: Path, title: str = "") -> Path:
    """Newton iterations per load step (step cuts included), one line per case."""
    groups = group_columns(axes)
    fig, ax = plt.subplots(figsize=(5.6, 3.6))
    styles = series_styles(rows, groups)
    for row, steps, _, iterations in _history(rows):
        key = tuple(row[g] for g in groups)
        ax.plot(steps, iterations, lw=1.1, ms=3, label=series_label(key, groups), **styles(key))
    ax.set_xlabel("load step")
    ax.set_ylabel("Newton iterations")
    ax.grid(True, alpha=0.3)
    return finish_panel(fig, ax, path, title)


def error_vs_h_with_peer(rows: pd.DataFrame, axes: dict, path: Path, peer: dict, title: str = "") -> Path:
    """err_sigma_ample against h per series, with the peer's measured points (basis -> [(h, error)]) beside."""
    groups = group_columns(axes, exclude=("cell",))
    fig, ax = plt.subplots(figsize=(5.6, 4.0))
    styles = series_styles(rows, groups)
    failed_drawn: list = []
    for key, series in row_groups(rows, groups):
        series = series.sort_values("cell")
        good = (series["status"] == "ok") & (series["err_sigma_ample"] > 0)
        ax.plot(series.loc[good, "cell"], series.loc[good, "err_sigma_ample"], lw=1.3, ms=4,
                label=series_label(key, groups) if groups else "ours", **styles(key))
        mark_failed(ax, series.loc[series["status"] != "ok", "cell"].to_numpy(float), None, failed_drawn)
    for basis, points in peer.items():
        if points:
            h, error = np.array(points).T
            ax.plot(h, error, "o", ms=10, mfc="none", mec="black", mew=1.2, label=f"AMPLE-m ({basis})")
    sizes = np.unique(rows["cell"].dropna().to_numpy(float))
    log_scale(ax, "xy")
    ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
    ax.minorticks_off()
    slope_guides(ax, sizes, rows.loc[rows["status"] == "ok", "err_sigma_ample"].to_numpy(float))
    ax.set_xlabel(AXIS_LABELS["cell"])
    ax.set_ylabel(f"relative {ERROR_LABELS['err_sigma_ample']}")
    ax.grid(True, which="both", alpha=0.3)
    return finish_panel(fig, ax, path, title)


def stress_profile(cases: list[tuple[str, dict]], path: Path, title: str = "") -> Path:
    """sigma_eta_eta of every point at the last step against its initial height, beside the exact curve."""
    fig, ax = plt.subplots(figsize=(5.6, 4.2))
    markers = "os^vD<>"
    drawn_exact = False
    for index, (label, fields) in enumerate(cases):
        eta = (fields["X"] - fields["corner"]) @ fields["frame"][:, 1]
        order = np.argsort(eta)
        ax.plot(fields["sigma_eta"][-1][order], eta[order], markers[index % len(markers)], ms=3, mfc="none",
                label=label)
        if not drawn_exact:
            ax.plot(fields["sigma_exact"][-1][order], eta[order], "-", color="black", lw=1.2, label="exact")
            drawn_exact = True
    ax.set_xlabel("stress σ_ηη at the last step")
    ax.set_ylabel("initial height η of the point")
    ax.grid(True, alpha=0.3)
    return finish_panel(fig, ax, path, title)


def snapshots(label: str, fields: dict, path: Path, count: int = 4) -> Path:
    """The deformed body, its points (coloured by |sigma_eta - exact| / max |exact|) and the grid at
    `count` stored steps from the first to the last."""
    stored = len(fields["step"])
    chosen = np.unique(np.linspace(0, stored - 1, min(count, stored)).astype(int))
    fig, panels = plt.subplots(1, len(chosen), figsize=(2.6 * len(chosen) + 1.2, 4.6), squeeze=False)
    scale = max(float(np.abs(fields["sigma_exact"][-1]).max()), 1e-300)
    errors = np.abs(fields["sigma_eta"] - fields["sigma_exact"]) / scale
    positive = errors[errors > 0]
    top = positive.max() if len(positive) else 1.0
    norm = LogNorm(vmin=max(positive.min() if len(positive) else top * 1e-6, top * 1e-6), vmax=top)
    for ax, k in zip(panels[0], chosen):
        setting = {"grid_h": fields["grid_h"], "grid_lower": fields["grid_lower"], "grid_shape": fields["grid_shape"],
                   "vertices": fields["outline"][k], "kinds": fields["outline_kind"], "volume": fields["volume"][k]}
        draw_setting(ax, setting)
        scatter = ax.scatter(fields["x"][k][:, 0], fields["x"][k][:, 1], c=np.clip(errors[k], norm.vmin, None),
                             norm=norm, cmap="viridis", s=marker_area(ax, fig, setting), marker="s",
                             linewidths=0, zorder=1)
        ax.set_title(f"step {int(fields['step'][k])} (t = {float(fields['t'][k]):.2f})", fontsize=8)
        ax.set_xlabel("x (current position)", fontsize=8)
        ax.set_ylabel("y (current position)", fontsize=8)
    log_colorbar(fig, scatter, ax=panels[0].tolist(), shrink=0.8, label="|σ_ηη − exact| / max |exact|")
    fig.suptitle(label, fontsize=9)
    return finish_figure(fig, path)
