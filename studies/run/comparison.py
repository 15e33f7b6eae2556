"""Every boundary method on the seed's cases: confined block at 90, 45 and 30 degrees,
h = 10, one material point per cell, each method at its default parameters."""
from __future__ import annotations

from baselines.registry import METHODS
from ibm.exceptions import SolveError
from studies.run.case import CaseSpec, run_case
from studies.run.seed import PAPER, markdown

COLUMNS = ["method", "angle", "err_u", "err_sigma", "err_traction", "cond_est", "ndof", "n_multipliers", "time_s"]


def comparison_table(base: CaseSpec = CaseSpec(), methods=None, angles=tuple(PAPER)) -> list[dict]:
    """One row per method and angle; a method that refuses a case gets its error message."""
    rows = []
    for name in methods or METHODS:
        for angle in angles:
            try:
                record = run_case(base.with_(method=name, angle=angle))
                rows.append({c: record.get(c) for c in COLUMNS})
            except SolveError as error:
                rows.append({"method": name, "angle": angle, "failed": str(error)})
    return rows


def report(base: CaseSpec = CaseSpec()) -> str:
    rows = comparison_table(base)
    failed = [r for r in rows if "failed" in r]
    shown = [{c: ("-" if r.get(c) is None else r[c]) for c in COLUMNS} for r in rows if "failed" not in r]
    text = (f"Methods compared: {base.problem}, h = {base.cell:g}, ppc = {base.ppc}, offset = {tuple(base.offset)}, "
            "default parameters\n" + markdown(shown, COLUMNS))
    for r in failed:
        text += f"\n{r['method']} at {r['angle']:g} degrees: {r['failed']}"
    return text
