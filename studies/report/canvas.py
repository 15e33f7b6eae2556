"""The canvas every figure of a study is drawn on and written from (matplotlib, Agg): log axes labelled
in plain text, the layout, and the PNG cropped to what is drawn (DRAWN keeps the last one's pixels for the
page)."""
from __future__ import annotations

import io
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import LogFormatterSciNotation, NullLocator  # noqa: E402
from matplotlib.transforms import Bbox  # noqa: E402
from PIL import Image  # noqa: E402

from studies.run.store import atomic_write  # noqa: E402

DPI = 110
MINOR_DECADES = 3
MARGIN = 0.1           # inches of white around what a figure draws
REACH = 0.5            # inches beyond the figure's edges drawn before cropping (see _pixels)
SUPERSCRIPTS = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
# The figure finish_figure wrote last, {path: (its PNG, its (height, width, 3) uint8 RGB pixels)}: the report
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


def log_labels(axis) -> None:
    """Label a log axis (an Axes' x or y axis, or a colour bar's long axis) with _PowerLabels."""
    axis.set_major_formatter(_PowerLabels())
    axis.set_minor_formatter(_PowerLabels())


def log_scale(ax, names: str) -> None:
    """A log scale, plain-text labelled, on the axes `names` of ax ("x", "y" or "xy")."""
    for name in names:
        getattr(ax, f"set_{name}scale")("log")
        log_labels(getattr(ax, f"{name}axis"))


def log_colorbar(fig, mappable, **kwargs):
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


def fit_layout(fig) -> None:
    """tight_layout, after thinning the log axes' ticks (it measures every tick label), at the dpi the
    figure is drawn at: the draw reuses the sizes of the texts it measured."""
    fig.set_dpi(DPI)
    _thin_log_ticks(fig)
    fig.tight_layout()


def finish_figure(fig, path: Path) -> Path:
    """Write the figure to `path`: full colour, cropped to what is drawn plus MARGIN (the page embeds a
    256-colour copy: studies.report.figures.page_png). Written atomically, so a killed report never leaves half
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
