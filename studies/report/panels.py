"""The pieces the line-plot figures share: a grid of panels, one legend right of them, a style per series,
failed cases as red crosses on the bottom edge of the axes, slope guides, and a figure of panels finished
and written."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.transforms import blended_transform_factory  # noqa: E402

from studies.report.canvas import finish_figure, fit_layout  # noqa: E402


def finish_panel(fig, ax, path: Path, title: str = "") -> Path:
    """A one-panel figure: its legend at the right, the title, then written to `path`."""
    figure_legend(fig, [ax])
    if title:
        ax.set_title(title, fontsize=10)
    fit_layout(fig)
    return finish_figure(fig, path)


def mark_failed(ax, x: np.ndarray, colour, label_done: list) -> None:
    if len(x) == 0:
        return
    transform = blended_transform_factory(ax.transData, ax.transAxes)
    ax.plot(x, np.full(len(x), 0.02), "x", color="red", markersize=8, mew=2, transform=transform,
            clip_on=False, label=None if label_done else "failed case")
    label_done.append(True)


def series_styles(rows: pd.DataFrame, groups: list[str]):
    """key -> plot style: colour by the first grouping column (the method), line and marker by the rest."""
    first = list(dict.fromkeys(rows[groups[0]].tolist())) if groups else []
    rest = list(dict.fromkeys(tuple(r) for r in rows[groups[1:]].itertuples(index=False))) if len(groups) > 1 else []
    palette = plt.get_cmap("tab10" if len(first) <= 10 else "tab20")
    lines, markers = ["-", "--", ":", "-."], ["o", "s", "^", "v", "D", "P"]

    def style(key) -> dict:
        key = key if isinstance(key, tuple) else (key,)
        if not groups:
            return {"color": "C0", "marker": "o", "linestyle": "-"}
        colour = palette(first.index(key[0]) % palette.N) if key[0] in first else "black"
        other = rest.index(tuple(key[1:])) if tuple(key[1:]) in rest else 0
        return {"color": colour, "linestyle": lines[other % len(lines)], "marker": markers[other % len(markers)]}
    return style


def slope_guides(ax, sizes: np.ndarray, errors: np.ndarray) -> None:
    """Dotted reference lines of slope 1 and 2 (in log-log), anchored at the smallest error."""
    errors = errors[np.isfinite(errors) & (errors > 0)]
    if len(sizes) < 2 or not len(errors):
        return
    h = np.array([sizes.min(), sizes.max()])
    for order in (1, 2):
        ax.plot(h, errors.min() * (h / h[0]) ** order, color="0.5", lw=0.8, linestyle=(0, (1, 2)))
        ax.annotate(f"slope {order}", (h[1], errors.min() * (h[1] / h[0]) ** order), fontsize=7, color="0.4",
                    ha="right", va="bottom")


def panel_grid(n: int):
    """n panels, two per row when there are more than two; returns (figure, flat list of axes)."""
    columns = n if n <= 2 else 2
    rows = -(-n // columns)
    fig, panels = plt.subplots(rows, columns, figsize=(4.8 * columns, 3.6 * rows), squeeze=False)
    flat = panels.ravel().tolist()
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def finish_panels(fig, panels, path: Path, title: str) -> Path:
    """One legend for the panels, the title above them, the PNG written."""
    figure_legend(fig, panels)
    if title:
        fig.suptitle(title, fontsize=10)
    fit_layout(fig)
    return finish_figure(fig, path)


def figure_legend(fig, panels) -> None:
    """One legend for the figure (the series are the same in every panel), right of the panels."""
    handles, labels = {}, {}
    for ax in panels:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            if label not in labels:
                labels[label] = label
                handles[label] = handle
    if handles:
        fig.legend(list(handles.values()), list(labels), loc="center left", bbox_to_anchor=(1.0, 0.5),
                   fontsize=8, frameon=False)
