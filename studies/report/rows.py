"""Reading a study's stored rows: numbers as text, curves kept as JSON lists.

The report (studies.report) and the problems' report hooks (studies.problems.collapse) share these.
"""
from __future__ import annotations

import json

import numpy as np


def fmt(value) -> str:
    """Three significant digits for numbers, 'failed' for missing ones."""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        if np.isnan(value):
            return "–"
        if value == 0:
            return "0"
        if value == round(value) and abs(value) < 1e5:
            return f"{value:g}"
        return f"{value:.3g}" if 1e-2 <= abs(value) < 1e4 else f"{value:.2e}"
    return str(value)


def curve(row, name: str) -> np.ndarray:
    """A curve the store keeps as a JSON list (an empty array where the row has none)."""
    value = row.get(name)
    return np.asarray(json.loads(value) if isinstance(value, str) else [], float)
