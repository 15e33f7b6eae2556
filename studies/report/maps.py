"""Maps of per-point errors: the body's outline (coloured by boundary kind) and its grid under the material
points, one panel per case in the plane; a 3D case's points in a perspective view inside its box's edges."""
from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection  # noqa: E402

from ibm.geometry.polyhedron import ridges  # noqa: E402
from ibm.norms import pointwise_relative  # noqa: E402
from studies.report.canvas import finish_figure, log_colorbar  # noqa: E402

KIND_COLOURS = {"roller": "tab:blue", "fixed": "black", "traction": "tab:orange", "free": "tab:gray"}
TITLE_WIDTH = 34        # characters a line in a map panel's title (its 3.3 inches at 9 points)


def draw_setting(ax, fields: dict) -> None:
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


def marker_area(ax, fig, fields: dict) -> float:
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
            draw_setting(ax, fields)
            shown = np.clip(error[row], bottom, None)   # exact zeros would vanish on a log scale
            scatter = ax.scatter(fields["x"][:, 0], fields["x"][:, 1], c=shown, norm=norm, cmap="viridis",
                                 s=marker_area(ax, fig, fields), marker="s", linewidths=0, zorder=1)
            ax.set_title(textwrap.fill(label, TITLE_WIDTH), fontsize=9)    # a long label would run into the next
            ax.set_xlabel("x (position)", fontsize=8)
            ax.set_ylabel("y (position)", fontsize=8)
        log_colorbar(fig, scatter, ax=panels[row, :].tolist(), shrink=0.9, label=name)
    if title:
        fig.suptitle(title, fontsize=10)
    return finish_figure(fig, path)


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
        bar = log_colorbar(fig, scatter, ax=ax, shrink=0.6, pad=0.1)
        bar.set_label(name, fontsize=8)
        bar.ax.tick_params(labelsize=7, which="both")
    shown = list(dict.fromkeys(kinds))
    fig.legend([Patch(color=KIND_COLOURS.get(k, "black"), alpha=0.4) for k in shown], [f"{k} faces" for k in shown],
               loc="lower center", bbox_to_anchor=(0.5, 0.04), ncol=len(shown), fontsize=8, frameon=False)
    fig.suptitle(title or label, fontsize=10)
    return finish_figure(fig, path)
