"""The data of the report's interactive figures (studies.report.interactive): one panel per measure, a series
per setting with each point's case for the hover, failed cases as crosses below the data (never a number),
slope guides on error against h, and JSON the page can hold in a script element."""
import json

import numpy as np
import pandas as pd

from studies.report import interactive


def rows() -> pd.DataFrame:
    cells = [20.0, 10.0, 5.0]
    out = []
    for method, rate in (("ibm", 1.0), ("fem", 2.0)):
        for cell in cells:
            error = 0.1 * (cell / 20) ** rate
            out.append({"case_id": f"{method}-{cell:g}", "status": "ok", "error": "", "problem": "manufactured",
                        "method": method, "angle": 30.0, "cell": cell, "err_u": error, "err_l2": error,
                        "delta_rel": 1e-5 if method == "ibm" else np.nan})
    out.append({"case_id": "ibm-2.5", "status": "failed", "error": "SolveError: singular </script>",
                "problem": "manufactured", "method": "ibm", "angle": 30.0, "cell": 2.5, "err_u": np.nan,
                "err_l2": np.nan, "delta_rel": 1e-5})
    return pd.DataFrame(out)


def test_error_against_h():
    text = interactive.error_vs(rows(), {"method": ("ibm", "fem"), "cell": (20.0, 10.0, 5.0, 2.5)}, "cell")
    assert "</script" not in text                     # safe inside <script type="application/json">
    spec = json.loads(text.replace("<\\/", "</"))
    panels = spec["panels"]
    assert [p["y_label"] for p in panels] == ["err_u", "err_l2"] and all(p["x_log"] for p in panels)
    ibm, fem = panels[0]["series"]
    assert (ibm["name"], fem["name"]) == ("ibm", "fem") and ibm["colour"] != fem["colour"]
    assert fem["data"]["x"] == [5.0, 10.0, 20.0] and fem["data"]["y"] == [0.1 / 16, 0.1 / 4, 0.1]
    assert ibm["data"]["parameters"] == ["delta_rel 1.00e-05"] * 3 and fem["data"]["parameters"] == ["–"] * 3
    assert ibm["data"]["status"] == ["ok"] * 3 and ibm["data"]["case"] == ["ibm-5", "ibm-10", "ibm-20"]
    failed = panels[0]["failed"]                       # at half the smallest error, with its kind of failure
    assert failed["x"] == [2.5] and failed["y"] == [0.1 / 32] and failed["status"] == ["failed: SolveError"]
    slopes = panels[0]["guides"]
    assert [g["name"] for g in slopes] == ["slope 1", "slope 2"] and slopes[1]["y"] == [0.1 / 16, 0.1 / 16 * 64]   # over every h


def test_condition_against_a_parameter_without_guides():
    frame = rows().assign(cond_est=lambda f: 1e5 / f["cell"])
    spec = json.loads(interactive.cond_vs(frame, {"method": ("ibm", "fem"), "delta_rel": (1e-5,)}, "delta_rel"))
    (panel,) = spec["panels"]
    assert panel["y_label"] == "cond_est" and panel["guides"] == [] and panel["x_log"]


def test_the_page_script_carries_bokeh_inline():
    script = interactive.script()
    assert script.count("<script>") >= 3 and "Bokeh.Plotting.show" in script and "<script src" not in script
