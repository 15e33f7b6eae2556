"""The figures of a sweep's section: for each figure kind the spec asks for, which rows or field files
it draws, under what caption, put into the figure plan (studies.report.figures.Plan)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from studies.problems.registry import collapse_names, get as get_problem
from studies.report import interactive, peer as peer_data, tables
from studies.report.content import Section
from studies.report.figures import PATH, Fields, Plan
from studies.run.identity import case_id
from studies.run.seed import SEED_METHOD
from studies.run.spec import COLLAPSE_FIGURES, FIGURES, LARGE_FIGURES, Sweep, locking_pairs


def view_case(sweep: Sweep):
    """The case the sweep's error-view-3d shows: the IBM's (else the first method's) at the finest h, at
    the most oblique orientation (the largest tilt, then the angle farthest from the grid's axes)."""
    method = SEED_METHOD if SEED_METHOD in sweep.axes["method"] else sweep.axes["method"][0]
    mine = [c for c in sweep.cases if c.method == method]
    return min(mine, key=lambda c: (c.cell, -c.tilt, -min(c.angle % 90, 90 - c.angle % 90)))


def _fields(out: Path, key: str, needs: str = "") -> Fields | None:
    """The case's stored fields (None if it kept none, or none with the array `needs`)."""
    path = out / "fields" / f"{key}.npz"
    if not path.is_file():
        return None
    if needs:
        with np.load(path) as data:
            if needs not in data.files:
                return None
    return Fields(path)


def add_figures(out: Path, plan: Plan, section: Section, kind: str, rows: pd.DataFrame, sweep: Sweep) -> None:
    stem = f"{section.name}-{kind}"
    axes = sweep.axes
    x = FIGURES[kind]
    if kind in LARGE_FIGURES:
        _add_large_figure(out, plan, section, kind, rows, sweep, f"{stem}.png")
    elif kind in COLLAPSE_FIGURES:
        _add_collapse_figure(out, plan, section, kind, rows, sweep, stem)
    elif kind == "contact-curves":       # one figure per contact problem of the sweep
        for index, problem in enumerate(dict.fromkeys(rows["problem"])):
            plan.add(section, f"{problem}: its measures against the load, beside the exact ones, and the penetration",
                     kind, f"{stem}-{index}.png", "plots.contact_curves", rows[rows["problem"] == problem], axes, PATH)
    elif kind == "error-vs-placement":
        plan.add(section, "Errors over placements of the body in the grid", kind, f"{stem}.png",
                 "plots.error_vs_placement", rows, axes, PATH)
    elif kind == "error-vs-orientation":
        plan.add(section, "Relative errors against the orientation (angle θ, tilt ψ)", kind, f"{stem}.png",
                 "plots.error_vs_orientation", rows, axes, PATH)
    elif kind == "error-view-3d":
        case = view_case(sweep)
        fields = _fields(out, case_id(case), needs="faces")
        if fields is not None:
            label = view_label(case)
            plan.add(section, f"Per-point relative errors in 3D, {label} (log colour scale)", kind, f"{stem}.png",
                     "plots.error_view_3d", label, fields, PATH)
    elif kind.startswith("error-vs-"):
        plan.add(section, f"Relative errors against {tables.AXIS_LABELS.get(x, x)}", kind, f"{stem}.png",
                 "plots.error_vs", rows, axes, x, PATH)
        section.figures[-1].interactive = interactive.error_vs(rows, axes, x)
    elif kind.startswith("cond-vs-"):
        plan.add(section, f"Condition estimate against {tables.AXIS_LABELS.get(x, x)}", kind, f"{stem}.png",
                 "plots.cond_vs", rows, axes, x, PATH)
        section.figures[-1].interactive = interactive.cond_vs(rows, axes, x)
    elif kind == "error-maps":
        others = tables.group_axes(axes, exclude=("method",))
        for method in axes["method"]:
            cases = []
            for case in sweep.cases:
                if case.method != method:
                    continue
                fields = _fields(out, case_id(case))
                if fields is not None:
                    label = ", ".join(f"{_short(k)} = {_value(case, k)}" for k in others) or case.problem
                    cases.append((label, fields))
            if cases:
                plan.add(section, f"Per-point relative errors, method {method} (log colour scale)", kind,
                         f"{stem}-{method}.png", "plots.error_maps", cases, PATH, title=f"method {method}")


def _add_collapse_figure(out: Path, plan: Plan, section: Section, kind: str, rows: pd.DataFrame, sweep: Sweep,
                         stem: str) -> None:
    drawing = [get_problem(p) for p in collapse_names() if get_problem(p).curve_figure[0] == kind]
    if drawing:         # one problem's load-displacement curves beside its exact limit
        plan.add(section, drawing[0].curve_figure[1], kind, f"{stem}.png", "plots.collapse_curves",
                 rows[rows["problem"] == drawing[0].name], PATH, ["angle", "cell"])
    elif kind == "locking":
        ids = [case_id(c) for pair in locking_pairs(sweep.cases) for c in pair]
        shown = rows[rows["case_id"].isin(ids)]
        if len(shown):
            plan.add(section, "Locked (locking none) beside remedied (B-bar, fbar), on the same axes", kind,
                     f"{stem}.png", "plots.collapse_curves", shown, PATH, ["problem", "method", "angle", "cell"])
    else:           # at the sweep's finest h, one figure per problem and angle
        finest = min(sweep.axes["cell"]) if "cell" in sweep.axes else sweep.cases[0].cell
        groups: dict[tuple, list] = {}
        for case in sweep.cases:
            fields = _fields(out, case_id(case), needs="alpha") if case.cell == finest else None
            if fields is not None:
                setting = (case.problem, case.angle, case.cell)
                groups.setdefault(setting, []).append((f"{case.method}, locking {case.locking}", fields))
        for index, ((problem, angle, cell), cases) in enumerate(groups.items()):
            label = f"{problem}, θ = {tables.fmt(angle)}°, h = {tables.fmt(cell)}"
            plan.add(section, f"Plastic zones at collapse: {label}", kind, f"{stem}-{index}.png",
                     "plots.plastic_zones", cases, PATH, title=label)


def view_label(case) -> str:
    return (f"{case.method} on {case.problem} at (θ, ψ) = ({tables.fmt(case.angle)}°, {tables.fmt(case.tilt)}°), "
            f"h = {tables.fmt(case.cell)}")


def _add_large_figure(out: Path, plan: Plan, section: Section, kind: str, rows: pd.DataFrame, sweep: Sweep,
                      name: str) -> None:
    axes = sweep.axes
    if kind == "error-vs-step":
        plan.add(section, "Relative errors against the load step", kind, name, "plots.error_vs_step", rows, axes, PATH)
    elif kind == "newton-iterations":
        plan.add(section, "Newton iterations per load step (tolerance 1e-9)", kind, name,
                 "plots.newton_iterations", rows, axes, PATH)
    elif kind == "error-vs-h-peer":
        peer = {basis: peer_data.ample_points(rows[rows["basis"] == basis], basis)
                for basis in sorted(set(rows["basis"].dropna()))}
        plan.add(section, "AMPLE's column measure against h, with AMPLE-m's measured errors (circles)", kind, name,
                 "plots.error_vs_h_with_peer", rows, axes, PATH, peer)
    else:
        others = tables.group_axes(axes)
        cases = []
        for case in sweep.cases:
            fields = _fields(out, case_id(case), needs="outline")
            if fields is not None:
                label = ", ".join(f"{_short(k)} = {_value(case, k)}" for k in others) or case.problem
                cases.append((label, fields))
        if not cases:
            return
        if kind == "stress-profile":
            plan.add(section, "σ_ηη of every point at the last step against its initial height, and the exact curve",
                     kind, name, "plots.stress_profile", cases, PATH)
        else:
            stem = name.removesuffix(".png")
            for index, (label, fields) in enumerate(cases[:6]):   # a few cases: snapshots are large figures
                plan.add(section, f"Deformed body and points at chosen steps: {label}", kind, f"{stem}-{index}.png",
                         "plots.snapshots", label, fields, PATH)


def _short(key: str) -> str:
    symbols = {name: p.symbol for name, p in tables.PARAMETERS.items() if p.symbol}
    return {"angle": "θ", "tilt": "ψ", "orientation": "(θ, ψ)", "cell": "h", **symbols, "nu": "ν"}.get(key, key)


def _value(case, key: str) -> str:
    if key == "offset":
        return "(" + ", ".join(f"{o:.3g}" for o in case.offset) + ")"
    if key == "orientation":
        return f"({tables.fmt(case.angle)}°, {tables.fmt(case.tilt)}°)"
    if key == "problem_file":       # the file's name: its folder says where it was run, not what it is
        return Path(case.problem_file).name if case.problem_file else "-"
    value = getattr(case, key) if hasattr(case, key) and key != "method_parameters" else case.method_parameters.get(key)
    return tables.fmt(value) + ("°" if key == "angle" else "")

