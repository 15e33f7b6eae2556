"""What the page template renders: a Section per sweep (its tables, figures and reading) and each
Figure in it. The section builders (studies.report.page) and the figure plan (studies.report.figures)
both fill these in."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Section:
    name: str
    summary: str
    counts: str
    tables: list = field(default_factory=list)     # (title, html, csv path relative to DIR)
    figures: list = field(default_factory=list)    # Figure
    reading: list = field(default_factory=list)    # sentences
    failed: str = ""
    heading: str = ""                              # defaults to "Sweep: <name>"

    @property
    def title(self) -> str:
        return self.heading or f"Sweep: {self.name}"


@dataclass
class Figure:
    title: str
    uri: str          # data:image/png;base64,... (the page's copy)
    png: str          # the full-colour file, relative to DIR
    how: str          # one line: how to read this figure
    width: int = 0    # pixels of the embedded image (0: unknown)
    height: int = 0
    interactive: str = ""   # the data of its interactive version (studies.report.interactive), shown instead

    @property
    def anchor(self) -> str:
        """The id of its interactive version's data in the page."""
        return "data-" + self.png.rsplit("/", 1)[-1].removesuffix(".png")
