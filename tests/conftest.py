"""Fixtures shared by several test modules."""
from pathlib import Path

import pytest

from studies.report import plots


@pytest.fixture
def drawn(monkeypatch) -> list[str]:
    """The names of the PNGs the plot functions draw (they draw in this process while patched)."""
    names: list[str] = []
    for name, function in plots.PRISTINE.items():
        if not name.startswith("_"):
            def counted(*args, _function=function, **kwargs):
                path = _function(*args, **kwargs)
                names.append(Path(path).name)
                return path
            monkeypatch.setattr(plots, name, counted)
    return names
