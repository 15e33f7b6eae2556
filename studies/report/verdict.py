"""The verdict at the top of the report: a scorecard (methods as rows, the criteria of
studies.report.criteria as columns, each cell a measured number with a colour band and a link to the
sweep it comes from) and "which method when", sentences generated from the same numbers, so that a change
in the results changes the verdict.

The study's spec chooses the criteria and the sweeps each reads ([verdict], docs/studies.md); a study
without one has no scorecard.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from baselines.registry import METHODS
from studies.report.criteria import BY_NAME, ROUNDOFF, Cell, Criterion
from studies.report.rows import fmt
from studies.report.tables import sweep_rows
from studies.run.identity import case_id
from studies.run.spec import Study

BANDS = ("good", "fair", "poor")
COLOURS = {"good": "#d9f2d9", "fair": "#fdf0c4", "poor": "#f8d4d0", "": "transparent"}     # a cell's by its band


@dataclass
class Scorecard:
    criteria: list[Criterion]
    methods: list[str]
    cells: dict = field(default_factory=dict)          # (method, criterion name) -> Cell, its band set
    best: dict = field(default_factory=dict)           # criterion name -> the boundary methods with its best number
    references: list = field(default_factory=list)     # body-fitted methods: banded, never "the best"
    jobs: list = field(default_factory=list)           # "which method when": the best for each job,
    weaknesses: list = field(default_factory=list)     #   each method's strengths and weakest point,
    overall: str = ""                                  #   and the method good on the most criteria

    def cell(self, method: str, criterion: str) -> Cell:
        return self.cells.get((method, criterion), Cell())

    @property
    def boundary(self) -> list[str]:
        """The boundary methods (every method but the references), in the scorecard's order."""
        return [m for m in self.methods if m not in self.references]


def scorecard(study: Study, results: pd.DataFrame) -> Scorecard | None:
    """The study's scorecard from its stored results (None if its spec declares no [verdict])."""
    if not study.verdict:
        return None
    ids = {case_id(c) for c in study.cases()}
    every = sorted(set(results.loc[results["case_id"].isin(ids), "method"])) if len(results) else []
    columns: dict[str, dict] = {}
    for selection in study.verdict:
        parts = []
        for name in selection.sweeps:
            sweep = study.sweep(name)
            parts.append((sweep, sweep_rows(results, [c for c in sweep.cases if selection.keeps(c)])))
        seen = any(len(rows) for _, rows in parts)
        columns[selection.criterion] = BY_NAME[selection.criterion].measure(parts, every) if seen else {}
    named = {m for cells in columns.values() for m in cells}
    methods = [m for m in METHODS if m in named] + sorted(named - set(METHODS))
    card = Scorecard([BY_NAME[s.criterion] for s in study.verdict], methods,
                     references=[m for m in methods if m in METHODS and METHODS[m].supports.body_fitted])
    for criterion in card.criteria:
        cells = columns[criterion.name]
        values = {m: c.value for m, c in cells.items() if not np.isnan(c.value)}
        if any(m not in card.references for m in values):     # the best among the boundary methods
            values = {m: v for m, v in values.items() if m not in card.references}
        if values:
            top = min(_level(criterion, v) for v in values.values())
            card.best[criterion.name] = [m for m, v in values.items() if _level(criterion, v) == top]
        best = values[card.best[criterion.name][0]] if values else np.nan
        for method, cell in cells.items():
            band = cell.band or (criterion.band(cell.value, best) if values and not np.isnan(cell.value) else "")
            card.cells[(method, criterion.name)] = replace(cell, band=band)
    which_method_when(card)
    return card


def shown(cell: Cell) -> str:
    """A cell's text on the page: its word, or its number to three digits."""
    return cell.text or (fmt(cell.value) if np.isfinite(cell.value) else "")


def _level(criterion: Criterion, value: float) -> float:
    """A number as the criterion ranks it, lower is better (lower-is-better numbers below round-off tie)."""
    return max(value, ROUNDOFF) if criterion.better == "lower" else -value


def _behind(card: Scorecard, criterion: Criterion, method: str) -> float:
    """The fraction of the other methods measured on `criterion` whose number is better than the method's."""
    def level(m):
        return _level(criterion, card.cell(m, criterion.name).value)
    others = [m for m in card.methods if m != method and not np.isnan(card.cell(m, criterion.name).value)]
    if not others or np.isnan(card.cell(method, criterion.name).value):
        return 1.0                                        # a word ("failed", "refuses") is the furthest behind
    return sum(level(m) < level(method) for m in others) / len(others)


def which_method_when(card: Scorecard) -> None:
    """The scorecard's sentences: the best method for each job, each method's strengths and its weakest
    criterion, and the method good on the most criteria."""
    jobs = []
    for criterion in card.criteria:
        best = card.best.get(criterion.name)
        if not criterion.job or not best:
            continue
        value = card.cell(best[0], criterion.name)
        good = [m for m in card.boundary if m not in best and card.cell(m, criterion.name).band == "good"]
        poor = [m for m in card.boundary if card.cell(m, criterion.name).band == "poor"]
        text = f"{criterion.job[0].upper()}{criterion.job[1:]}: {', '.join(best)} ({criterion.label} {shown(value)})"
        if good:
            text += f"; also good: {', '.join(good)}"
        if poor:
            text += f"; poor: {', '.join(poor)}"
        jobs.append(text + ".")
    card.jobs = jobs
    measured = {c.name: sum(not np.isnan(card.cell(m, c.name).value) for m in card.boundary) for c in card.criteria}
    card.weaknesses = [_method_sentence(card, method, measured) for method in card.methods]
    ranking = sorted(card.boundary, key=lambda m: (-_count(card, m, "good"), _count(card, m, "poor"),
                                                   -_count(card, m, "good") / max(_rated(card, m), 1)))
    overall = [f"Of the boundary methods, {m} is good on the most criteria ({_count(card, m, 'good')} of the "
               f"{_rated(card, m)} it was measured on, poor on {_count(card, m, 'poor')})." for m in ranking[:1]]
    overall += [f"{m}, which meshes the body and serves as the reference, is good on {_count(card, m, 'good')} of "
                f"{_rated(card, m)}." for m in card.references]
    card.overall = " ".join(overall)


def _rated(card: Scorecard, method: str) -> int:
    return sum(1 for c in card.criteria if card.cell(method, c.name).band)


def _count(card: Scorecard, method: str, band: str) -> int:
    return sum(1 for c in card.criteria if card.cell(method, c.name).band == band)


def _method_sentence(card: Scorecard, method: str, measured: dict) -> str:
    """measured: criterion name -> how many boundary methods have a number on it."""
    strengths = [c.label for c in card.criteria        # a best shared by half the methods or more is no strength
                 if c.job and method in card.best.get(c.name, ()) and 2 * len(card.best[c.name]) <= measured[c.name]]
    good = [c.label for c in card.criteria if c.job and c.label not in strengths
            and card.cell(method, c.name).band == "good"]
    weak, weakest = None, 0.0
    for band in ("poor", "fair"):
        for criterion in card.criteria:
            cell = card.cell(method, criterion.name)
            if cell.band != band:
                continue
            far = _behind(card, criterion, method)
            if weak is None or far > weakest:
                weak, weakest = (criterion, cell), far
        if weak is not None:
            break
    text = f"{method}{' (the reference)' if method in card.references else ''}: "
    parts = [f"the best at {', '.join(strengths)}"] if strengths else []
    if good:
        parts.append(f"good at {', '.join(good)}")
    text += "; ".join(parts) or "good at none of the criteria"
    if weak is None:
        return text + "; no criterion below good."
    criterion, cell = weak
    text += f"; weakest at {criterion.label} ({shown(cell)}, {cell.band}"
    return text + (f"; {cell.detail})." if cell.detail else ").")
