"""Figures of a study (matplotlib, Agg): error against a swept setting, error maps, the 3D cases'
errors against orientation and their per-point errors in a perspective view, and the collapse
problems' curves and plastic zones.

Every function takes the results rows of one sweep (and its axes), writes one PNG and
returns its path. Failed cases are drawn as red crosses on the bottom edge of the axes,
never as numbers (on the collapse curves: named in the panel).
"""
from __future__ import annotations

import io
import json
import math
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.collections import LineCollection, PolyCollection  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import LogFormatterSciNotation, MaxNLocator, NullLocator  # noqa: E402
from matplotlib.transforms import Bbox, blended_transform_factory  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection  # noqa: E402
from PIL import Image  # noqa: E402

from ibm.geometry.polyhedron import ridges  # noqa: E402
from ibm.norms import pointwise_relative  # noqa: E402
from studies.problems.registry import get as get_problem  # noqa: E402
from studies.report.tables import (  # noqa: E402
    AXIS_LABELS, ERROR_LABELS, ORIENTATION_AXES, PARAMETERS, _groups, body_fitted, case_names, error_columns,
    group_columns, orientation_label, orientations, series_label, setting
)
from studies.run.store import atomic_write  # noqa: E402

LOG_AXES = {"cell", "E", *(name for name, p in PARAMETERS.items() if p.log_scale)}
KIND_COLOURS = {"roller": "tab:blue", "fixed": "black", "traction": "tab:orange", "free": "tab:gray"}
DPI = 110
MINOR_DECADES = 3
MARGIN = 0.1           # inches of white around what a figure draws
REACH = 0.5            # inches beyond the figure's edges drawn before cropping (see _pixels)
TITLE_WIDTH = 34        # characters a line in a map panel's title (its 3.3 inches at 9 points)
SUPERSCRIPTS = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
# The figure _finish wrote last, {path: (its PNG, its (height, width, 3) uint8 RGB pixels)}: studies.report.page
# makes the page's copy from the pixels instead of decoding the PNG just encoded. One figure's, replaced by
# the next.
DRAWN: dict[Path, tuple[bytes, np.ndarray]] = {}


class _PowerLabels(LogFormatterSciNotation):
    """matplotlib's log tick labels (the same ticks labelled, with the same numbers) as plain text,
    10⁻⁵ and 2×10⁻⁵, instead of the mathtext $10^{-5}$, whose parsing (pyparsing) was a quarter of the
    time of a figure with log axes. DejaVu Sans has the superscript digits and minus."""

    def __call__(self, x, pos=None):
        label = super().__call__(x, pos)         # "" where matplotlib leaves the tick unlabelled
        if not label or x <= 0:
            return label
        power = math.log10(x)
        if math.isclose(power, round(power)):
            return "10" + str(round(power)).translate(SUPERSCRIPTS)
        exponent = math.floor(power)
        coefficient = 10 ** (power - exponent)
        if math.isclose(coefficient, round(coefficient)):
            coefficient = round(coefficient)
        return f"{coefficient:g}×10" + str(exponent).translate(SUPERSCRIPTS)


def _log_labels(axis) -> None:
    """Label a log axis (an Axes' x or y axis, or a colour bar's long axis) with _PowerLabels."""
    axis.set_major_formatter(_PowerLabels())
    axis.set_minor_formatter(_PowerLabels())


def _log_scale(ax, names: str) -> None:
    """A log scale, plain-text labelled, on the axes `names` of ax ("x", "y" or "xy")."""
    for name in names:
        getattr(ax, f"set_{name}scale")("log")
        _log_labels(getattr(ax, f"{name}axis"))


def _log_colorbar(fig, mappable, **kwargs):
    """fig.colorbar of a mappable with a LogNorm, plain-text labelled."""
    bar = fig.colorbar(mappable, **kwargs)
    bar.formatter, bar.minorformatter = _PowerLabels(), _PowerLabels()
    return bar


def _thin_log_ticks(fig) -> None:
    """No minor ticks on log axes spanning more than MINOR_DECADES decades: there they are a
    hundred unlabelled ticks an axis (one artist each, the largest part of drawing such a figure)
    beside a major tick and grid line at every decade."""
    for ax in fig.axes:
        for axis, low_high in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
            low, high = sorted(low_high)
            if axis.get_scale() == "log" and low > 0 and np.log10(high / low) > MINOR_DECADES:
                axis.set_minor_locator(NullLocator())


def _layout(fig) -> None:
    """tight_layout, after thinning the log axes' ticks (it measures every tick label), at the dpi the
    figure is drawn at: the draw reuses the sizes of the texts it measured."""
    fig.set_dpi(DPI)
    _thin_log_ticks(fig)
    fig.tight_layout()


def _finish(fig, path: Path) -> Path:
    """Write the figure to `path`: full colour, cropped to what is drawn plus MARGIN (the page embeds a
    256-colour copy: studies.report.page.page_png). Written atomically, so a killed report never leaves half
    a PNG."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _thin_log_ticks(fig)
    fig.set_dpi(DPI)
    pixels = _pixels(fig)
    plt.close(fig)
    buffer = io.BytesIO()
    # zlib level 3: 30 % less time than the default 6 for files 3 % larger (Pillow's optimize took five
    # times as long as 6 for files 2 % smaller)
    Image.fromarray(pixels).save(buffer, "PNG", dpi=(DPI, DPI), compress_level=3)
    data = buffer.getvalue()
    atomic_write(path, lambda handle: handle.write(data))
    DRAWN.clear()
    DRAWN[path] = (data, pixels)
    return path


def _pixels(fig) -> np.ndarray:
    """The figure drawn once, cropped to its ink plus MARGIN: (height, width, 3) uint8 RGB.

    Measuring what is drawn (fig.get_tightbbox) lays out every tick and label as the draw does, and
    took as long as the draw. Instead the figure is drawn over its own area widened by REACH and by
    its figure legends and texts (cheap to measure, and the legends stand beyond the right edge), and
    the pixels are cropped to what differs from the white background. When the ink comes within MARGIN
    of that area's edge, something may reach past it: then what is drawn is measured and the figure
    drawn again in that box, and cropped the same way."""
    renderer = fig.canvas.get_renderer()
    to_inches = fig.dpi_scale_trans.inverted()
    outside = [artist.get_window_extent(renderer).transformed(to_inches).padded(2 * MARGIN)
               for artist in [*fig.legends, *fig.texts] if artist.get_visible()]
    area = Bbox.union([fig.bbox_inches.padded(REACH), *outside])
    rgba = _draw_rgba(fig, area)
    pixels = _crop(rgba)
    if pixels is None:
        rgba = _draw_rgba(fig, fig.get_tightbbox(renderer).padded(2 * MARGIN))
        pixels = _crop(rgba)
    return pixels if pixels is not None else np.ascontiguousarray(rgba[..., :3])


def _crop(rgba: np.ndarray) -> np.ndarray | None:
    """The RGB pixels of what is not white in rgba, plus MARGIN; None when that margin would reach past
    rgba's edges (or nothing is drawn)."""
    ink = rgba.view(np.uint32)[..., 0] != 0xFFFFFFFF            # not opaque white
    rows, columns = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    if not len(rows):
        return None
    margin = round(MARGIN * DPI)
    top, bottom = rows[0] - margin, rows[-1] + 1 + margin
    left, right = columns[0] - margin, columns[-1] + 1 + margin
    if top < 0 or left < 0 or bottom > rgba.shape[0] or right > rgba.shape[1]:
        return None
    return np.ascontiguousarray(rgba[top:bottom, left:right, :3])


def _draw_rgba(fig, box) -> np.ndarray:
    """The pixels (height, width, 4) of the figure drawn in `box` (inches; it may reach past the figure),
    widened to whole pixels."""
    (x0, y0), (x1, y1) = np.floor(box.p0 * DPI), np.ceil(box.p1 * DPI)
    width, height = int(x1 - x0), int(y1 - y0)
    # half a pixel over: savefig's canvas is the box's size in pixels rounded down, whatever the rounding error
    box = Bbox.from_extents(x0 / DPI, y0 / DPI, (x1 + 0.5) / DPI, (y1 + 0.5) / DPI)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="rgba", dpi=DPI, bbox_inches=box)
    rgba = np.frombuffer(buffer.getbuffer(), np.uint8)
    if rgba.size != 4 * width * height:
        raise RuntimeError(f"savefig drew {rgba.size} bytes for a {width} x {height} box")
    return rgba.reshape(height, width, 4)


def _finish_panel(fig, ax, path: Path, title: str = "") -> Path:
    """A one-panel figure: its legend at the right, the title, then written to `path`."""
    _legend(fig, [ax])
    if title:
        ax.set_title(title, fontsize=10)
    _layout(fig)
    return _finish(fig, path)


def _mark_failed(ax, x: np.ndarray, colour, label_done: list) -> None:
    if len(x) == 0:
        return
    transform = blended_transform_factory(ax.transData, ax.transAxes)
    ax.plot(x, np.full(len(x), 0.02), "x", color="red", markersize=8, mew=2, transform=transform,
            clip_on=False, label=None if label_done else "failed case")
    label_done.append(True)


def error_vs(rows: pd.DataFrame, axes: dict, x: str, path: Path, quantities: list[str] | None = None,
             title: str = "") -> Path:
    """One panel per error measure: error (log) against setting x, one line per series."""
    quantities = quantities or error_columns(rows)[:4] or ["err_u"]
    groups = group_columns(axes, exclude=(x,))
    fig, panels = _panels(len(quantities))
    for ax, quantity in zip(panels, quantities):
        failed_drawn: list = []
        styles = _styles(rows, groups)
        for key, series in _groups(rows, groups):
            series = series.sort_values(x)
            good = (series["status"] == "ok") & series[quantity].notna() & (series[quantity] > 0)
            label = series_label(key, groups) if groups else "all cases"
            ax.plot(series.loc[good, x], series.loc[good, quantity], ms=4, lw=1.3, label=label, **styles(key))
            _mark_failed(ax, series.loc[series["status"] != "ok", x].to_numpy(float), None, failed_drawn)
        _log_scale(ax, "xy" if x in LOG_AXES else "y")
        if x == "angle":
            ax.set_xticks(np.arange(0, 91, 15))
        if x == "cell":   # label the grid sizes themselves; slopes are in the convergence table
            sizes = np.unique(rows[x].dropna().to_numpy(float))
            ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
            ax.minorticks_off()
            _slope_guides(ax, sizes, rows.loc[rows["status"] == "ok", quantity].to_numpy(float))
        ax.set_xlabel(AXIS_LABELS.get(x, x))
        ax.set_ylabel(f"relative {ERROR_LABELS.get(quantity, quantity)}")
        ax.grid(True, which="both", alpha=0.3)
    return _finish_panels(fig, panels, path, title)


def _styles(rows: pd.DataFrame, groups: list[str]):
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


def _slope_guides(ax, sizes: np.ndarray, errors: np.ndarray) -> None:
    """Dotted reference lines of slope 1 and 2 (in log-log), anchored at the smallest error."""
    errors = errors[np.isfinite(errors) & (errors > 0)]
    if len(sizes) < 2 or not len(errors):
        return
    h = np.array([sizes.min(), sizes.max()])
    for order in (1, 2):
        ax.plot(h, errors.min() * (h / h[0]) ** order, color="0.5", lw=0.8, linestyle=(0, (1, 2)))
        ax.annotate(f"slope {order}", (h[1], errors.min() * (h[1] / h[0]) ** order), fontsize=7, color="0.4",
                    ha="right", va="bottom")


def _panels(n: int):
    """n panels, two per row when there are more than two; returns (figure, flat list of axes)."""
    columns = n if n <= 2 else 2
    rows = -(-n // columns)
    fig, panels = plt.subplots(rows, columns, figsize=(4.8 * columns, 3.6 * rows), squeeze=False)
    flat = panels.ravel().tolist()
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def _finish_panels(fig, panels, path: Path, title: str) -> Path:
    """One legend for the panels, the title above them, the PNG written."""
    _legend(fig, panels)
    if title:
        fig.suptitle(title, fontsize=10)
    _layout(fig)
    return _finish(fig, path)


def _legend(fig, panels) -> None:
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


def cond_vs(rows: pd.DataFrame, axes: dict, x: str, path: Path, title: str = "") -> Path:
    groups = group_columns(axes, exclude=(x,))
    fig, ax = plt.subplots(figsize=(5.2, 3.8))
    failed_drawn: list = []
    styles = _styles(rows, groups)
    for key, series in _groups(rows, groups):
        series = series.sort_values(x)
        good = (series["status"] == "ok") & series["cond_est"].notna()
        ax.plot(series.loc[good, x], series.loc[good, "cond_est"], ms=4, **styles(key),
                label=series_label(key, groups) if groups else "condition estimate")
        _mark_failed(ax, series.loc[series["status"] != "ok", x].to_numpy(float), None, failed_drawn)
    _log_scale(ax, "xy" if x in LOG_AXES else "y")
    ax.set_xlabel(AXIS_LABELS.get(x, x))
    ax.set_ylabel("1-norm condition estimate (equilibrated system)")
    ax.grid(True, which="both", alpha=0.3)
    if x == "cell":
        sizes = np.unique(rows[x].dropna().to_numpy(float))
        ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
        ax.minorticks_off()
    return _finish_panel(fig, ax, path, title)


def error_vs_placement(rows: pd.DataFrame, axes: dict, path: Path, title: str = "") -> Path:
    """Errors of every placement (dots) per series, with the median as a bar."""
    quantities = error_columns(rows)[:2] or ["err_u"]
    groups = group_columns(axes, exclude=("offset",)) or ["method"]
    fig, panels = plt.subplots(1, len(quantities), figsize=(4.8 * len(quantities), 3.8), squeeze=False)
    for ax, quantity in zip(panels[0], quantities):
        labels = []
        failed_drawn: list = []
        for index, (key, series) in enumerate(_groups(rows, groups)):
            good = series[(series["status"] == "ok") & (series[quantity] > 0)][quantity].to_numpy(float)
            jitter = np.linspace(-0.15, 0.15, len(good)) if len(good) > 1 else np.zeros(len(good))
            ax.plot(index + jitter, good, "o", color=f"C{index % 10}", ms=4, alpha=0.8)
            if len(good):
                ax.hlines(np.median(good), index - 0.3, index + 0.3, color="black", lw=1.5)
            n_failed = int((series["status"] != "ok").sum())
            _mark_failed(ax, np.full(n_failed, float(index)), None, failed_drawn)
            labels.append(series_label(key, groups))
        ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=8)
        _log_scale(ax, "y")
        ax.set_ylabel(f"relative {ERROR_LABELS.get(quantity, quantity)}")
        ax.set_xlabel("series (dots: placements, bar: median)")
        ax.grid(True, axis="y", which="both", alpha=0.3)
        if failed_drawn:
            ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    _layout(fig)
    return _finish(fig, path)


def _draw_setting(ax, fields: dict) -> None:
    """The background grid (cells around the body; when the fields have one, else a frame 5 % beyond
    the outline) and the body outline coloured by edge kind."""
    vertices = fields.get("outline_points", fields["vertices"])
    if "grid_h" in fields:
        h = float(fields["grid_h"])
        lower, shape = fields["grid_lower"].astype(float), fields["grid_shape"].astype(int)
        x0, y0 = lower * h
        x1, y1 = x0 + shape[0] * h, y0 + shape[1] * h
        xs, ys = x0 + h * np.arange(shape[0] + 1), y0 + h * np.arange(shape[1] + 1)
        lines = [*(((x, y0), (x, y1)) for x in xs), *(((x0, y), (x1, y)) for y in ys)]
        ax.add_collection(LineCollection(lines, colors="0.85", linewidths=0.5, zorder=0),   # one artist, not one a line
                          autolim=False)
    else:
        low, high = vertices.min(axis=0), vertices.max(axis=0)
        (x0, y0), (x1, y1) = low - 0.05 * (high - low), high + 0.05 * (high - low)
    # the outline as one artist too: a piece after the other, its segments (several along an arc) in order,
    # each coloured by its piece's kind
    piece = fields.get("outline_piece", np.arange(len(vertices)))
    colours = [KIND_COLOURS.get(str(kind), "black") for kind in fields["kinds"]]
    starts = [i for k in range(len(colours)) for i in np.flatnonzero(piece == k)]
    ax.add_collection(LineCollection([[vertices[i], vertices[(i + 1) % len(vertices)]] for i in starts],
                                     colors=[colours[piece[i]] for i in starts], linewidths=1.6, zorder=2),
                      autolim=False)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    for axis in (ax.xaxis, ax.yaxis):      # a map's positions need few ticks; each costs a text to lay out
        axis.set_major_locator(MaxNLocator(3))


def _marker_area(ax, fig, fields: dict) -> float:
    """Marker area (points^2) of a square about 80 % of the point spacing sqrt(volume)."""
    spacing = float(np.sqrt(np.median(fields["volume"])))
    width_in = ax.get_position().width * fig.get_figwidth()
    x0, x1 = ax.get_xlim()
    side = 0.8 * spacing / (x1 - x0) * width_in * 72
    return max(side ** 2, 1.0)


def error_maps(cases: list[tuple[str, dict]], path: Path, title: str = "") -> Path:
    """Per-point relative errors |u_h - u| / max|u| (top) and |s_h - s| / max|s| (bottom),
    one column per case, log colour scale shared along each row."""
    n = len(cases)
    # room between the columns for every panel's own y label
    fig, panels = plt.subplots(2, n, figsize=(3.3 * n + 1.0, 6.6), squeeze=False, gridspec_kw={"wspace": 0.45})
    errors = [pointwise_relative(f["u_h"], f["u"], f["sigma_h"], f["sigma"], f["direction"]) for _, f in cases]
    for row, name in enumerate(("relative displacement error", "relative loaded-direction stress error")):
        values = np.concatenate([e[row] for e in errors])
        positive = values[values > 0]
        top = positive.max() if len(positive) else 1.0
        bottom = max(positive.min(), top * 1e-6) if len(positive) else top * 1e-6
        if bottom >= top:
            bottom = top / 10
        norm = LogNorm(vmin=bottom, vmax=top)
        for column, ((label, fields), error) in enumerate(zip(cases, errors)):
            ax = panels[row, column]
            _draw_setting(ax, fields)
            shown = np.clip(error[row], bottom, None)   # exact zeros would vanish on a log scale
            scatter = ax.scatter(fields["x"][:, 0], fields["x"][:, 1], c=shown, norm=norm, cmap="viridis",
                                 s=_marker_area(ax, fig, fields), marker="s", linewidths=0, zorder=1)
            ax.set_title(textwrap.fill(label, TITLE_WIDTH), fontsize=9)    # a long label would run into the next
            ax.set_xlabel("x (position)", fontsize=8)
            ax.set_ylabel("y (position)", fontsize=8)
        _log_colorbar(fig, scatter, ax=panels[row, :].tolist(), shrink=0.9, label=name)
    if title:
        fig.suptitle(title, fontsize=10)
    return _finish(fig, path)


# --- 3D: errors against orientation, per-point errors in a perspective view -----------------------

def error_vs_orientation(rows: pd.DataFrame, axes: dict, path: Path, title: str = "") -> Path:
    """One panel per error measure: error (log) at each orientation (angle, tilt) of the sweep, in sweep
    order along x, one line per series."""
    quantities = error_columns(rows)[:4] or ["err_u"]
    groups = group_columns(axes, exclude=ORIENTATION_AXES) or ["method"]
    labels = orientations(rows)
    position = {label: i for i, label in enumerate(labels)}
    fig, panels = _panels(len(quantities))
    for ax, quantity in zip(panels, quantities):
        failed_drawn: list = []
        styles = _styles(rows, groups)
        for key, series in _groups(rows, groups):
            x = np.array([position[orientation_label(a, t)] for a, t in zip(series["angle"], series["tilt"])], float)
            good = ((series["status"] == "ok") & series[quantity].notna() & (series[quantity] > 0)).to_numpy()
            ax.plot(x[good], series[quantity].to_numpy(float)[good], ms=4, lw=1.3, label=series_label(key, groups),
                    **styles(key))
            _mark_failed(ax, x[(series["status"] != "ok").to_numpy()], None, failed_drawn)
        _log_scale(ax, "y")
        ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=8)
        ax.set_xlabel("orientation (angle θ, tilt ψ) in degrees")
        ax.set_ylabel(f"relative {ERROR_LABELS.get(quantity, quantity)}")
        ax.grid(True, which="both", alpha=0.3)
    return _finish_panels(fig, panels, path, title)


def error_view_3d(label: str, fields: dict, path: Path, title: str = "") -> Path:
    """The material points of one 3D case in a perspective view, coloured by |u_h - u| / max|u| (left)
    and |s_h - s| / max|s| of the loaded-direction stress (right) on log scales, inside the box's
    edges, its faces tinted by boundary kind."""
    x, faces, kinds = fields["x"], fields["faces"], [str(k) for k in fields["kinds"]]
    corners = faces.reshape(-1, 3)
    centre, half = (corners.min(axis=0) + corners.max(axis=0)) / 2, np.ptp(corners, axis=0).max() / 2
    size = 1800.0 / max(len(x), 1) ** (2 / 3)        # about the same ink whatever the number of points
    fig = plt.figure(figsize=(10.5, 4.6))
    measures = (("displacement", "|u_h − u| / max |u|", fields["err_u"]),
                ("loaded-direction stress σ_ηη", "|σ_h − σ|_ηη / max |σ_ηη|", fields["err_sigma"]))
    for column, (what, name, error) in enumerate(measures):
        ax = fig.add_subplot(1, 2, column + 1, projection="3d")
        positive = error[error > 0]
        top = positive.max() if len(positive) else 1.0
        bottom = max(positive.min(), top * 1e-6) if len(positive) else top * 1e-6
        norm = LogNorm(vmin=min(bottom, top / 10), vmax=top)
        ax.add_collection3d(Poly3DCollection(list(faces), facecolors=[KIND_COLOURS.get(k, "black") for k in kinds],
                                             alpha=0.12, edgecolors="none"))
        edges = [np.stack([start, end]) for _, _, start, end in ridges(faces)]
        ax.add_collection3d(Line3DCollection(edges, colors="0.25", linewidths=1.0))
        # exact zeros would vanish on a log scale; the colours are the points' own, not faded with depth
        scatter = ax.scatter(x[:, 0], x[:, 1], x[:, 2], c=np.clip(error, norm.vmin, None), norm=norm, cmap="viridis",
                             s=size, depthshade=False, linewidths=0)
        for axis, set_limits in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
            set_limits(centre[axis] - half, centre[axis] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=22, azim=-58)
        ax.set_xlabel("x", fontsize=8)
        ax.set_ylabel("y", fontsize=8)
        ax.set_zlabel("z", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_title(f"{what}, {len(x)} points", fontsize=9)
        bar = _log_colorbar(fig, scatter, ax=ax, shrink=0.6, pad=0.1)
        bar.set_label(name, fontsize=8)
        bar.ax.tick_params(labelsize=7, which="both")
    shown = list(dict.fromkeys(kinds))
    fig.legend([Patch(color=KIND_COLOURS.get(k, "black"), alpha=0.4) for k in shown], [f"{k} faces" for k in shown],
               loc="lower center", bbox_to_anchor=(0.5, 0.04), ncol=len(shown), fontsize=8, frameon=False)
    fig.suptitle(title or label, fontsize=10)
    return _finish(fig, path)


# --- large deformation: load steps, the column's profile, snapshots ----------------------------

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
    fig, panels = _panels(len(quantities))
    styles = _styles(rows, groups)
    for row, steps, measures, _ in _history(rows):
        key = tuple(row[g] for g in groups)
        for ax, quantity in zip(panels, quantities):
            values = measures[quantity]
            good = values > 0
            ax.plot(steps[good], values[good], lw=1.2, ms=3, label=series_label(key, groups), **styles(key))
    for ax, quantity in zip(panels, quantities):
        _log_scale(ax, "y")
        ax.set_xlabel("load step")
        ax.set_ylabel(f"relative {ERROR_LABELS.get(quantity, quantity)}", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    return _finish_panels(fig, panels, path, title)


def newton_iterations(rows: pd.DataFrame, axes: dict, path: Path, title: str = "") -> Path:
    """Newton iterations per load step (step cuts included), one line per case."""
    groups = group_columns(axes)
    fig, ax = plt.subplots(figsize=(5.6, 3.6))
    styles = _styles(rows, groups)
    for row, steps, _, iterations in _history(rows):
        key = tuple(row[g] for g in groups)
        ax.plot(steps, iterations, lw=1.1, ms=3, label=series_label(key, groups), **styles(key))
    ax.set_xlabel("load step")
    ax.set_ylabel("Newton iterations")
    ax.grid(True, alpha=0.3)
    return _finish_panel(fig, ax, path, title)


def error_vs_h_with_peer(rows: pd.DataFrame, axes: dict, path: Path, peer: dict, title: str = "") -> Path:
    """err_sigma_ample against h per series, with the peer's measured points (basis -> [(h, error)]) beside."""
    groups = group_columns(axes, exclude=("cell",))
    fig, ax = plt.subplots(figsize=(5.6, 4.0))
    styles = _styles(rows, groups)
    failed_drawn: list = []
    for key, series in _groups(rows, groups):
        series = series.sort_values("cell")
        good = (series["status"] == "ok") & (series["err_sigma_ample"] > 0)
        ax.plot(series.loc[good, "cell"], series.loc[good, "err_sigma_ample"], lw=1.3, ms=4,
                label=series_label(key, groups) if groups else "ours", **styles(key))
        _mark_failed(ax, series.loc[series["status"] != "ok", "cell"].to_numpy(float), None, failed_drawn)
    for basis, points in peer.items():
        if points:
            h, error = np.array(points).T
            ax.plot(h, error, "o", ms=10, mfc="none", mec="black", mew=1.2, label=f"AMPLE-m ({basis})")
    sizes = np.unique(rows["cell"].dropna().to_numpy(float))
    _log_scale(ax, "xy")
    ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
    ax.minorticks_off()
    _slope_guides(ax, sizes, rows.loc[rows["status"] == "ok", "err_sigma_ample"].to_numpy(float))
    ax.set_xlabel(AXIS_LABELS["cell"])
    ax.set_ylabel(f"relative {ERROR_LABELS['err_sigma_ample']}")
    ax.grid(True, which="both", alpha=0.3)
    return _finish_panel(fig, ax, path, title)


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
    return _finish_panel(fig, ax, path, title)


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
        _draw_setting(ax, setting)
        scatter = ax.scatter(fields["x"][k][:, 0], fields["x"][k][:, 1], c=np.clip(errors[k], norm.vmin, None),
                             norm=norm, cmap="viridis", s=_marker_area(ax, fig, setting), marker="s",
                             linewidths=0, zorder=1)
        ax.set_title(f"step {int(fields['step'][k])} (t = {float(fields['t'][k]):.2f})", fontsize=8)
        ax.set_xlabel("x (current position)", fontsize=8)
        ax.set_ylabel("y (current position)", fontsize=8)
    _log_colorbar(fig, scatter, ax=panels[0].tolist(), shrink=0.8, label="|σ_ηη − exact| / max |exact|")
    fig.suptitle(label, fontsize=9)
    return _finish(fig, path)


# --- the collapse problems: curves beside the exact limit, plastic zones --------------------------

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
    _legend(fig, flat[:len(groups)])
    if title:
        fig.suptitle(title, fontsize=10)
    _layout(fig)
    return _finish(fig, path)


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
        _draw_setting(ax, fields)
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
            area = _marker_area(ax, fig, fields)
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
        _log_colorbar(fig, scatter, ax=flat, shrink=0.85, label="equivalent plastic strain (grey: elastic)")
    if title:
        fig.suptitle(title, fontsize=10)
    return _finish(fig, path)


# The drawing functions as this module defines them: studies.report.page draws in worker processes only while
# these are untouched here (a test that patches one, to watch or count, gets every figure drawn in its process).
PRISTINE = {name: value for name, value in list(globals().items())
            if callable(value) and getattr(value, "__module__", None) == __name__}
