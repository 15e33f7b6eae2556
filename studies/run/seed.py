"""The seed paper's validation table (Cortis, Coombs & Augarde), reproduced beside ours.

Relative errors in displacement and in the loaded-direction stress for the confined
block at 90, 45 and 30 degrees, h = 10, one material point per 10-unit square.
"""
from __future__ import annotations

from ibm.implicit_boundary import IMPLICIT_BOUNDARY
from studies.run.case import CaseSpec, run_case

SEED_METHOD = IMPLICIT_BOUNDARY.name      # the paper's method, the implicit boundary method
# angle -> (err_u, err_sigma) as printed in the paper
PAPER = {90.0: (5.55e-5, 8.25e-6), 45.0: (1.06e-3, 9.9e-4), 30.0: (3.14e-3, 4.48e-3)}
DELTA_SWEEP = (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
OFFSET_SWEEP = ((0.0, 0.0), (0.37, 0.29), (0.5, 0.5), (0.1, 0.9), (0.73, 0.11), (0.99, 0.01))


def seed_table(base: CaseSpec = CaseSpec()) -> list[dict]:
    rows = []
    for angle, (paper_u, paper_sigma) in PAPER.items():
        record = run_case(base.with_(angle=angle))
        rows.append({"angle": angle, "err_u": record["err_u"], "paper_err_u": paper_u,
                     "err_sigma": record["err_sigma"], "paper_err_sigma": paper_sigma,
                     "ndof": record["ndof"], "npoints": record["npoints"],
                     "cond_est": record.get("cond_est"), "time_s": record["time_s"],
                     "at_or_below_paper": record["err_u"] <= paper_u and record["err_sigma"] <= paper_sigma})
    return rows


def delta_sweep(base: CaseSpec = CaseSpec(), deltas=DELTA_SWEEP) -> list[dict]:
    return [{"angle": angle, "delta_rel": d, **_errors(run_case(base.with_(angle=angle, method_parameters={"delta_rel": d})))}
            for angle in PAPER for d in deltas]


def offset_sweep(base: CaseSpec = CaseSpec(), offsets=OFFSET_SWEEP) -> list[dict]:
    return [{"angle": angle, "offset": list(o), **_errors(run_case(base.with_(angle=angle, offset=o)))}
            for angle in PAPER for o in offsets]


def _errors(record: dict) -> dict:
    return {k: record[k] for k in ("err_u", "err_sigma", "err_u_max", "err_sigma_max", "cond_est")}


def markdown(rows: list[dict], columns: list[str]) -> str:
    def cell(v):
        if isinstance(v, float):
            return f"{v:.3g}" if abs(v) >= 1e-2 and abs(v) < 1e4 else f"{v:.2e}"
        if isinstance(v, list):
            return "(" + ", ".join(f"{x:g}" for x in v) + ")"
        return str(v)
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(r[c]) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def report(base: CaseSpec = CaseSpec()) -> str:
    delta = base.method_parameters.get("delta_rel", 1e-5)
    parts = [
        f"Seed table: confined block, h = {base.cell:g}, ppc = {base.ppc}, delta/h = {delta:g}, "
        f"offset = {tuple(base.offset)}, E = {base.E:g}, nu = {base.nu:g}, p = {base.load:g}",
        markdown(seed_table(base), ["angle", "err_u", "paper_err_u", "err_sigma", "paper_err_sigma",
                                    "ndof", "cond_est", "at_or_below_paper"]),
        "\nErrors against the band width delta/h (offset as above):",
        markdown(delta_sweep(base), ["angle", "delta_rel", "err_u", "err_sigma", "err_sigma_max", "cond_est"]),
        "\nErrors against the placement offset (delta/h as above):",
        markdown(offset_sweep(base), ["angle", "offset", "err_u", "err_sigma", "err_sigma_max", "cond_est"]),
    ]
    return "\n".join(parts)
