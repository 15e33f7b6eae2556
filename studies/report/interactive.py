"""Interactive versions of the report's line figures, drawn in the browser by BokehJS: hovering a point shows
its case (id, method, problem, angle, h, the method's parameters and the value), a click on a legend entry
hides its series, the wheel zooms and a drag pans. Python only writes each figure's data (a small JSON
object, `error_vs` and `cond_vs` below); templates/figures.js builds the plots from it with BokehJS's
plotting API, and the page carries BokehJS inline once (`script`), so the figures work offline. The PNG of
every figure is still drawn (studies.report.sweep_lines) and linked, for papers.

Bokeh was chosen over Plotly and Vega-Lite for what the page must carry and what the build costs: BokehJS
and its plotting API are 1.4 MB inline against Plotly's 4.6 MB, Vega-Lite needs three scripts and a converter
to embed offline, and building the figures in the browser from their data costs the report's build
milliseconds where Bokeh's Python models cost half a second per figure.
"""
from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from studies.report.rows import fmt
from studies.report.tables import AXIS_LABELS, ERROR_LABELS, LOG_AXES, PARAMETERS, error_columns, error_kind, \
    group_columns, row_groups, series_label

COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf")                                  # matplotlib's tab10, as the PNGs
TOOLTIPS = (("case", "@case"), ("status", "@status"), ("method", "@method"), ("problem", "@problem"),
            ("angle", "@angle °"), ("h", "@h"), ("parameters", "@parameters"))


@lru_cache(maxsize=1)
def script() -> str:
    """The page's scripts: BokehJS and its plotting API inline, then the renderer of templates/figures.js."""
    from bokeh.resources import Resources
    bokeh = Resources(mode="inline", components=["bokeh", "bokeh-api"]).render_js()
    renderer = (Path(__file__).parent / "templates" / "figures.js").read_text()
    return bokeh + "\n<script>\n" + renderer + "</script>"


def error_vs(rows: pd.DataFrame, axes: dict, x: str, quantities: list[str] | None = None) -> str:
    """One panel per error measure against the swept setting x, one line per series (as sweep_lines.error_vs)."""
    quantities = quantities or error_columns(rows)[:4] or ["err_u"]
    rows = _narrow(rows, axes, x, quantities)
    hover = _hover(rows)
    return _json([_panel(rows, hover, axes, x, q, f"relative {ERROR_LABELS.get(q, q)}") for q in quantities])


def cond_vs(rows: pd.DataFrame, axes: dict, x: str) -> str:
    """The condition estimate against the swept setting x, one line per series (as sweep_lines.cond_vs)."""
    rows = _narrow(rows, axes, x, ["cond_est"])
    return _json([_panel(rows, _hover(rows), axes, x, "cond_est", "1-norm condition estimate (equilibrated system)")])


def _narrow(rows: pd.DataFrame, axes: dict, x: str, quantities: list[str]) -> pd.DataFrame:
    """Only the columns a figure reads (a study's rows have a hundred and more; each selection copies them)."""
    wanted = [x, *quantities, *group_columns(axes, exclude=(x,)), "status", "error", "case_id", "method", "problem",
              "angle", "cell", *PARAMETERS]
    return rows[[c for c in dict.fromkeys(wanted) if c in rows]]


def _panel(rows: pd.DataFrame, hover: pd.DataFrame, axes: dict, x: str, quantity: str, label: str) -> dict:
    """One panel: a line per series, the failed cases as red crosses at the bottom (never as numbers), and on
    error against h the guides of slope 1 and 2 from the smallest error (as the PNG)."""
    groups = group_columns(axes, exclude=(x,))
    series = []
    values = rows.loc[rows["status"] == "ok", quantity] if quantity in rows else pd.Series(dtype=float)
    values = values[values > 0].to_numpy(float)
    for index, (key, group) in enumerate(row_groups(rows, groups)):
        group = group.sort_values(x)
        if quantity not in group:
            continue
        good = group[(group["status"] == "ok") & group[quantity].notna() & (group[quantity] > 0) & group[x].notna()]
        if good.empty:
            continue
        series.append({"name": series_label(key, groups) if groups else "all cases", "colour": COLOURS[index % 10],
                       "data": {"x": good[x].to_numpy(float).tolist(), "y": good[quantity].to_numpy(float).tolist(),
                                **hover.loc[good.index].to_dict("list")}})
    failed = rows[(rows["status"] != "ok") & rows[x].notna()]
    spec = {"title": label, "x_label": AXIS_LABELS.get(x, x), "y_label": quantity, "x_log": x in LOG_AXES,
            "series": series, "tooltips": [list(t) for t in TOOLTIPS] + [[quantity, "@y{0.000e}"]], "failed": None,
            "guides": []}
    if len(failed) and len(values):
        spec["failed"] = {"x": failed[x].to_numpy(float).tolist(), "y": [float(values.min()) / 2] * len(failed),
                          **hover.loc[failed.index].to_dict("list")}
    if x == "cell" and len(values):
        sizes = np.unique(rows[x].dropna().to_numpy(float))
        if len(sizes) > 1:
            h = np.array([sizes.min(), sizes.max()])
            spec["guides"] = [{"name": f"slope {order}", "x": h.tolist(),
                               "y": (values.min() * (h / h[0]) ** order).tolist()} for order in (1, 2)]
    return spec


def _hover(rows: pd.DataFrame) -> pd.DataFrame:
    """What the hover shows of each row's case, as text (rows' index): computed once for every panel."""
    failed = "failed: " + (error_kind(rows["error"].astype(str)) if "error" in rows else pd.Series("", rows.index))
    given = [name for name in PARAMETERS if name in rows]
    parameters = [", ".join(f"{name} {fmt(v)}" for name, v in zip(given, values) if np.isfinite(v)) or "–"
                  for values in rows[given].to_numpy(float, na_value=np.nan)]
    return pd.DataFrame({"case": rows["case_id"].astype(str), "status": failed.where(rows["status"] != "ok", "ok"),
                         "method": rows["method"].astype(str), "problem": rows["problem"].astype(str),
                         "angle": [fmt(a) for a in rows["angle"].to_numpy(float)],
                         "h": [fmt(h) for h in rows["cell"].to_numpy(float)], "parameters": parameters},
                        index=rows.index)


def _json(panels: list[dict]) -> str:
    """The figure's data as the page embeds it (in a <script type="application/json">: '</' escaped)."""
    text = json.dumps({"panels": panels}, sort_keys=True, separators=(",", ":"), allow_nan=False, default=_plain)
    return text.replace("</", "<\\/")


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot write a {type(value).__name__} into a figure's data")


INTERACTIVE = {"error_vs": error_vs, "cond_vs": cond_vs}     # by the name of the PNG's drawing function
