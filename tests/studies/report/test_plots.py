"""The figure machinery of studies.report.canvas on small figures: the plain-text log labels and the crop of
what is drawn."""
from __future__ import annotations

import re

import matplotlib.pyplot as plt
import numpy as np
import pytest
from PIL import Image

from studies.report import canvas


def _mathtext_as_plain(label: str) -> str:
    """matplotlib's log label, $\\mathdefault{2\\times10^{-3}}$, written as _PowerLabels writes it: 2×10⁻³."""
    match = re.fullmatch(r"\$\\mathdefault\{(.*)\}\$", label)
    if not match:
        return label
    text = match.group(1).replace("\\times", "×")
    return re.sub(r"\^\{(-?\d+)\}", lambda power: power.group(1).translate(canvas.SUPERSCRIPTS), text)


def _labels(low: float, high: float, plain: bool) -> list[str]:
    fig, ax = plt.subplots()
    ax.plot([1, 2], [low, high])
    ax.set_yscale("log")
    if plain:
        canvas.log_labels(ax.yaxis)
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.yaxis.get_ticklabels(which="both") if t.get_text()]
    plt.close(fig)
    return labels


@pytest.mark.parametrize("low, high", [(1e-9, 1e-2), (2e-3, 5e-3), (0.3, 0.9), (1.0, 1e6), (0.05, 0.5)])
def test_log_labels_are_matplotlibs_numbers_as_plain_text(low, high):
    plain = _labels(low, high, plain=True)
    assert plain == [_mathtext_as_plain(label) for label in _labels(low, high, plain=False)]
    assert plain and not any("$" in label for label in plain)


def test_log_labels_write_powers_with_superscripts():
    labels = canvas._PowerLabels()
    assert [labels(v) for v in (1e-5, 1.0, 1e3)] == ["10⁻⁵", "10⁰", "10³"]


def _ink(image) -> tuple[int, int, int, int]:
    """Top, bottom, left and right edges (pixels, end exclusive) of what is not white in an image."""
    ink = (np.asarray(Image.open(image).convert("RGB")) != 255).any(axis=2)
    rows, columns = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    return rows[0], rows[-1] + 1, columns[0], columns[-1] + 1


def _figure(title_lines: int):
    """A legend beyond the right edge and an axes title of `title_lines` lines (from 8 on, above the top)."""
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1], [0, 1], label="a line")
    ax.set_title("\n".join(["a title"] * title_lines))
    fig.legend(loc="center left", bbox_to_anchor=(1.0, 0.5))
    return fig


@pytest.mark.parametrize("title_lines, draws", [(2, 1), (12, 2)])
def test_a_figure_is_cropped_to_what_it_draws_even_past_its_edges(tmp_path, monkeypatch, title_lines, draws):
    """What is drawn is written whole, MARGIN inside the file's edges: as much as savefig's
    bbox_inches="tight" shows. Drawn once when the legend is all that reaches far past the figure,
    twice when the title does too."""
    reference = tmp_path / "tight.png"
    _figure(title_lines).savefig(reference, dpi=canvas.DPI, bbox_inches="tight", pad_inches=0)
    top, bottom, left, right = _ink(reference)
    drawn = []
    draw = canvas._draw_rgba
    monkeypatch.setattr(canvas, "_draw_rgba", lambda fig, box: drawn.append(box) or draw(fig, box))
    path = canvas.finish_figure(_figure(title_lines), tmp_path / "figure.png")
    with Image.open(path) as image:
        width, height = image.size
    margin = round(canvas.MARGIN * canvas.DPI)
    assert _ink(path) == (margin, height - margin, margin, width - margin)
    assert abs((bottom - top) - (height - 2 * margin)) <= 1 and abs((right - left) - (width - 2 * margin)) <= 1
    assert width > 3.5 * canvas.DPI and (height > 2.5 * canvas.DPI) == (title_lines > 8)
    assert len(drawn) == draws


def test_the_page_copy_from_the_kept_pixels_is_the_copy_of_the_file(tmp_path):
    """studies.report.figures makes the embedded copy from the pixels finish_figure keeps: the same bytes as from the
    PNG decoded."""
    from studies.report.figures import page_png
    path = canvas.finish_figure(_figure(2), tmp_path / "figure.png")
    data, pixels = canvas.DRAWN.pop(path)
    assert data == path.read_bytes()
    copy = page_png(data, pixels)
    assert copy == page_png(data) and copy[1:] == Image.open(path).size and len(copy[0]) < len(data)
