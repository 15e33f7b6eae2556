"""Figures of the collapse problems (the footing, the cylinder): every case's load-displacement curve beside
the exact limit, and the plastic zones at the last converged step."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402

from studies.problems.registry import get as get_problem  # noqa: E402
from studies.report.canvas import finish_figure, fit_layout, log_colorbar  # noqa: E402
from studies.report.maps import draw_setting, marker_area  # noqa: E402
from studies.report.panels import figure_legend  # noqa: E402
from studies.report.tables import body_fitted, case_names, setting  # noqa: E402


def _locked(row) -> bool:
    """A grid method run without a remedy for locking (a body-fitted method's elements do not lock)."""
    return not body_fitted(row["method"]) and setting(row, "locking") == "none"


def collapse_curves(rows: pd.DataFrame, path: Path, panels: list[str], title: str = "") -> Path:
    """Every case's curve (footing: q / c against settlement / B; cylinder: p / p_lim against u_b),
    one panel per value of the columns `panels`, one colour per method, B-bar (locking fbar) solid
    and locked (none) dashed, beside the exact limit; failed cases are named in their panel. Cases
    at several offsets (the footing's edge across its cell) get one colour per method and offset."""
    names = case_names(rows)
    methods = list(dict.fromkeys(names))
    groups = list(rows.groupby(panels, sort=False, dropna=False))
    columns = min(len(groups), 2)
    lines = -(-len(groups) // columns)
    fig, axes = plt.subplots(lines, columns, figsize=(5.0 * columns, 3.8 * lines), squeeze=False)
    flat = axes.ravel().tolist()
    for ax in flat[len(groups):]:
        ax.set_visible(False)
    for ax, (_, group) in zip(flat, groups):
        notes = []
        first = group.iloc[0]
        own = get_problem(first["problem"])          # its curve, exact limit and frame (CollapseProblem)
        right = own.x_limit(first)
        for position, row in group.iterrows():
            name = names[position]
            if row["status"] != "ok":
                notes.append(f"failed: {name} ({setting(row, 'locking')})")
                continue
            x, y = own.curve(row)
            index = methods.index(name)
            width = 1.3 + 1.5 * (len(methods) - 1 - index) / max(len(methods) - 1, 1)   # equal curves stay visible
            ax.plot(np.r_[0.0, x], np.r_[0.0, y], color=plt.get_cmap("tab10")(index % 10), lw=width, marker="o",
                    ms=2.5, linestyle="--" if _locked(row) else "-", zorder=2 + index / len(methods),
                    label=name + (" (locked: locking none)" if _locked(row) else ""))
            if len(x) and x.max() > right:
                notes.append(f"{row['method']}{' (locked)' if _locked(row) else ''} runs on to u_b = {x[-1]:.3g} "
                             f"at {y[-1]:.3g} p_lim")
        own.draw_limit(ax, first)
        if notes:
            ax.text(0.98, 0.04, "\n".join(notes), transform=ax.transAxes, ha="right", va="bottom", fontsize=7,
                    color="red")
        ax.set_title(", ".join([first["problem"]] * ("problem" in panels) + [first["method"]] * ("method" in panels)
                               + [own.setting_label(first)]), fontsize=9)
        ax.set_ylim(bottom=0)
        ax.set_xlim(0, right if np.isfinite(right) else None)
        ax.grid(True, alpha=0.3)
    figure_legend(fig, flat[:len(groups)])
    if title:
        fig.suptitle(title, fontsize=10)
    fit_layout(fig)
    return finish_figure(fig, path)


def plastic_zones(cases: list[tuple[str, dict]], path: Path, title: str = "", columns: int = 4) -> Path:
    """The points of each case at its last converged step, coloured by their equivalent plastic strain
    (log scale shared by the panels; elastic points grey), over the grid and the outline; one panel per
    case, `columns` to a row."""
    n = len(cases)
    sizes = [np.ptp(f["outline_points"], axis=0) for _, f in cases]
    aspect = min(max(s[1] / s[0] for s in sizes), 1.2)
    width, rows = min(n, columns), -(-n // columns)
    fig, grid = plt.subplots(rows, width, figsize=(3.4 * width + 1.2, (3.4 * aspect + 0.9) * rows), squeeze=False)
    flat = grid.ravel().tolist()
    for ax in flat[n:]:
        ax.set_visible(False)
    panels = [flat[:n]]
    alpha = np.concatenate([f["alpha"] for _, f in cases])
    positive = alpha[alpha > 0]
    top = float(positive.max()) if len(positive) else 1.0
    norm = LogNorm(vmin=max(float(positive.min()) if len(positive) else top, top * 1e-3), vmax=top)
    if norm.vmin >= norm.vmax:
        norm = LogNorm(vmin=top / 10, vmax=top)
    scatter = None
    for ax, (label, fields) in zip(panels[0], cases):
        draw_setting(ax, fields)
        if "triangles" in fields:           # fem: each triangle coloured by the mean over its Gauss points
            triangles = fields["triangles"]
            per = len(fields["alpha"]) // len(triangles)
            weight = fields["volume"].reshape(len(triangles), per)
            mean = np.sum(weight * fields["alpha"].reshape(len(triangles), per), axis=1) / weight.sum(axis=1)
            elastic = mean <= 0
            ax.add_collection(PolyCollection(triangles[elastic], facecolors="0.8", edgecolors="white",
                                             linewidths=0.2, zorder=1))
            scatter = PolyCollection(triangles[~elastic], array=np.clip(mean[~elastic], norm.vmin, None), norm=norm,
                                     cmap="magma_r", edgecolors="white", linewidths=0.2, zorder=1)
            ax.add_collection(scatter)
        elif len(fields["x"]):
            area = marker_area(ax, fig, fields)
            elastic = fields["alpha"] <= 0
            ax.scatter(fields["x"][elastic, 0], fields["x"][elastic, 1], c="0.8", s=area, marker="s", linewidths=0,
                       zorder=1)
            scatter = ax.scatter(fields["x"][~elastic, 0], fields["x"][~elastic, 1],
                                 c=np.clip(fields["alpha"][~elastic], norm.vmin, None), norm=norm, cmap="magma_r",
                                 s=area, marker="s", linewidths=0, zorder=1)
        share = float(np.sum(fields["volume"][fields["alpha"] > 0]) / np.sum(fields["volume"])) if len(
            fields["x"]) else 0.0
        ax.set_title(f"{label}\n{share:.0%} of the volume yielded", fontsize=8)
        ax.set_xlabel("x", fontsize=8)
        ax.set_ylabel("y", fontsize=8)
    if scatter is not None:
        log_colorbar(fig, scatter, ax=flat, shrink=0.85, label="equivalent plastic strain (grey: elastic)")
    if title:
        fig.suptitle(title, fontsize=10)
    return finish_figure(fig, path)
