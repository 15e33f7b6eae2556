"""The contact problems' figure: each compared measure against the load fraction beside its exact value,
and the penetration per step; failed cases named in the title."""
import json

import numpy as np
import pandas as pd

from studies.report import contact_figures


def _row(method: str, status: str = "ok", scale: float = 1.0) -> dict:
    history = [{"t": t, "P": scale * 10 * t, "P_exact": 10 * t, "P_rankine": 12.0, "max_penetration": 1e-9 * t}
               for t in (0.5, 1.0)]
    return {"problem": "passive-wall", "method": method, "status": status, "cell": 10.0,
            "history": json.dumps(history) if status == "ok" else None}


def test_measures_beside_exact_values_and_penetration(tmp_path, monkeypatch):
    drawn = {}

    def keep(fig, panels, path, title):
        drawn.update(panels=panels, title=title)
        return path
    monkeypatch.setattr(contact_figures, "finish_panels", keep)
    rows = pd.DataFrame([_row("penalty", scale=1.01), _row("lagrange"), _row("nitsche", status="failed")])
    contact_figures.contact_curves(rows, {"method": ["penalty", "lagrange", "nitsche"]}, tmp_path / "f.png")
    panels = drawn["panels"]
    assert [ax.get_ylabel() for ax in panels] == ["P", "P against Rankine", "largest penetration in the step"]
    lines = {line.get_label(): line.get_ydata() for line in panels[0].get_lines()}
    assert np.allclose(lines["penalty"], [5.05, 10.1]) and np.allclose(lines["lagrange"], [5.0, 10.0])
    assert np.allclose(lines["exact (each case's)"], [5.0, 10.0])
    assert np.allclose(panels[1].get_lines()[1].get_ydata(), [12.0, 12.0])     # Rankine, each step
    assert panels[2].get_yscale() == "log" and np.allclose(panels[2].get_lines()[0].get_ydata(), [5e-10, 1e-9])
    assert "failed: nitsche" in drawn["title"]
