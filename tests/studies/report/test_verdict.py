"""The report's verdict (studies.report.verdict, studies.report.criteria): the scorecard's numbers and bands
from stored rows, "which method when" following the numbers, and the spec's [verdict] refusals."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ibm.exceptions import InputError
from studies.report import criteria
from studies.report.verdict import scorecard
from studies.run.identity import case_id
from studies.run.spec import parse

SPEC = """
title = "verdict"
[base]
problem = "confined-block"
cell = 20.0
[[sweep]]
name = "angles"
methods = ["ibm", "penalty", "lagrange"]
angle = [30, 60]
[[sweep]]
name = "h"
problems = ["manufactured"]
methods = ["ibm", "fem"]
angle = 30
cell = [20.0, 10.0, 5.0]
[[sweep]]
name = "beta"
problems = ["manufactured"]
methods = ["penalty"]
angle = 30
beta0 = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5]
[verdict]
patch-test = ["angles"]
rate-l2 = ["h"]
cost = ["h"]
parameter-range = ["beta"]
failed = "all"
"""
PATCH = {"ibm": 1e-6, "penalty": 1e-3, "lagrange": 1e-14}
RATE = {"ibm": 1.5, "fem": 2.0}
TIME = {"ibm": 1.0, "fem": 3.0}                      # seconds per case at every level
BETA = [0.5, 0.011, 0.010, 0.012, 0.05, np.nan]       # err_u per beta0; the last fails


def results(study, patch=PATCH, failed=()) -> pd.DataFrame:
    """Stored rows for every case of the study, with the errors above (methods in `failed` fail at 60 deg)."""
    rows = []
    for sweep in study.sweeps:
        for index, case in enumerate(sweep.cases):
            row = {"case_id": case_id(case), "status": "ok", "error": "", "problem": case.problem,
                   "method": case.method, "angle": case.angle, "cell": case.cell, "offset_x": 0.37, "offset_y": 0.29,
                   **case.method_parameters}
            if sweep.name == "angles":
                row.update(err_u=patch[case.method], err_sigma=patch[case.method] / 2, time_s=0.1)
                if case.method in failed and case.angle == 60:
                    row.update(status="failed", error="SolveError: indefinite", err_u=np.nan, err_sigma=np.nan)
            elif sweep.name == "h":
                error = 0.1 * (case.cell / 20) ** RATE[case.method]
                row.update(err_u=error, err_sigma=error, err_l2=error, time_s=TIME[case.method] * (20 / case.cell) ** 2)
            else:
                value = BETA[index]
                row.update(err_u=value, err_sigma=value, time_s=0.1)
                if np.isnan(value):
                    row.update(status="failed", error="SolveError: singular")
            rows.append(row)
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def study():
    return parse(SPEC)


def test_the_scorecard_bands_each_measured_number(study):
    card = scorecard(study, results(study))
    assert [c.name for c in card.criteria] == ["patch-test", "rate-l2", "cost", "parameter-range", "failed"]
    assert card.methods == ["ibm", "penalty", "lagrange", "fem"]          # the registry's order
    patch = {m: card.cell(m, "patch-test") for m in ("ibm", "penalty", "lagrange")}
    assert patch["lagrange"].value == pytest.approx(1e-14) and patch["lagrange"].band == "good"
    assert patch["ibm"].value == pytest.approx(1e-6) and patch["ibm"].band == "fair"
    assert patch["penalty"].band == "poor" and patch["penalty"].sweep == "angles"
    assert card.cell("ibm", "rate-l2").value == pytest.approx(1.5) and card.cell("ibm", "rate-l2").band == "fair"
    assert card.cell("fem", "rate-l2").value == pytest.approx(2.0) and card.cell("fem", "rate-l2").band == "good"
    # both reach the ibm's finest error 0.1 / 4 ** 1.5: the ibm at h = 5 in 16 s, fem half-way (in log-log)
    # between 0.025 at h = 10 (12 s) and 0.00625 at h = 5 (48 s), in sqrt(12 * 48) = 24 s
    assert card.cell("fem", "cost").value == pytest.approx(24.0 / 16.0)
    assert card.cell("ibm", "cost").value == pytest.approx(1.0) and card.best["cost"] == ["ibm"]
    # penalty's error within 2x of its best 0.010 from beta0 = 10 to 1000: two decades; the failed case breaks no run
    assert card.cell("penalty", "parameter-range").value == pytest.approx(2.0)
    assert card.cell("penalty", "parameter-range").band == "fair"
    assert card.cell("fem", "parameter-range").text == "none to choose"        # it declares no parameter
    assert card.cell("fem", "parameter-range").band == "good"
    assert card.cell("lagrange", "parameter-range").band == ""                  # declares one, not swept
    assert card.cell("penalty", "failed").text == "1 of 8" and card.cell("penalty", "failed").band == "poor"
    assert card.cell("lagrange", "failed").text == "0 of 2" and card.cell("lagrange", "failed").band == "good"


def test_which_method_when_follows_the_numbers(study):
    card = scorecard(study, results(study))
    patch = next(line for line in card.jobs if line.startswith("Exactness on a patch test"))
    assert patch.startswith("Exactness on a patch test: lagrange (patch test 1.00e-14)") and "poor: penalty" in patch
    penalty = next(line for line in card.weaknesses if line.startswith("penalty:"))
    assert "weakest at patch test (1.00e-03, poor" in penalty
    # the same study with penalty exact and lagrange off by 1e-2: the verdict turns round
    turned = scorecard(study, results(study, patch={"ibm": 1e-6, "penalty": 1e-14, "lagrange": 1e-2}))
    patch = next(line for line in turned.jobs if line.startswith("Exactness on a patch test"))
    assert patch.startswith("Exactness on a patch test: penalty (patch test 1.00e-14)") and "poor: lagrange" in patch
    assert "weakest at patch test (0.01, poor" in next(s for s in turned.weaknesses if s.startswith("lagrange:"))
    assert turned.jobs != card.jobs and turned.weaknesses != card.weaknesses


def test_a_failed_method_and_ties_below_round_off(study):
    rows = results(study, patch={"ibm": 1e-6, "penalty": 3e-15, "lagrange": 1e-14}, failed=("ibm",))
    card = scorecard(study, rows)
    assert card.best["patch-test"] == ["penalty", "lagrange"]               # both exact to round-off
    assert card.cell("ibm", "failed").text == "1 of 5"
    rows.loc[(rows["method"] == "ibm") & rows["case_id"].isin([case_id(c) for c in study.sweep("angles").cases]),
             ["status", "err_u", "err_sigma"]] = ["failed", np.nan, np.nan]
    assert scorecard(study, rows).cell("ibm", "patch-test").text == "failed"


def test_the_reference_is_banded_but_never_the_best(study):
    """fem meshes the body: its rate 2 is banded good, and the best L2 rate named is the best boundary method's."""
    card = scorecard(study, results(study))
    assert card.references == ["fem"] and card.best["rate-l2"] == ["ibm"]
    assert card.cell("fem", "rate-l2").band == "good" and card.cell("ibm", "rate-l2").band == "fair"
    assert next(line for line in card.jobs if line.startswith("Convergence in L2")) == "Convergence in L2: ibm (L2 rate 1.5)."
    assert card.overall.startswith("Of the boundary methods, lagrange is good on the most criteria")
    assert card.overall.endswith("fem, which meshes the body and serves as the reference, is good on 4 of 4.")
    assert next(s for s in card.weaknesses if s.startswith("fem")).startswith("fem (the reference): good at")


def test_only_narrows_the_cases_a_criterion_reads():
    spec = SPEC.replace('patch-test = ["angles"]', 'patch-test = {sweeps = ["angles"], only = {angle = 60}}')
    study = parse(spec)
    rows = results(study, failed=("penalty",))          # penalty fails at 60 degrees only
    card = scorecard(study, rows)
    assert card.cell("penalty", "patch-test").text == "failed"
    assert card.cell("ibm", "patch-test").detail == "worst: confined-block, θ = 60°, h = 20"
    with pytest.raises(InputError, match="verdict.patch-test: no case of the sweeps it names is left"):
        parse(SPEC.replace('patch-test = ["angles"]', 'patch-test = {sweeps = ["angles"], only = {angle = 45}}'))
    with pytest.raises(InputError, match="verdict.patch-test.only: unknown key 'angel'"):
        parse(SPEC.replace('patch-test = ["angles"]', 'patch-test = {sweeps = ["angles"], only = {angel = 60}}'))


def test_a_study_without_a_verdict_has_no_scorecard():
    spec = SPEC[:SPEC.index("[verdict]")]
    assert scorecard(parse(spec), results(parse(spec))) is None


@pytest.mark.parametrize("verdict, message", [
    ('patch = ["angles"]', "verdict: unknown criterion 'patch' (did you mean 'patch-test'?)"),
    ('patch-test = ["angle"]', "verdict.patch-test: no sweep is named 'angle' (did you mean 'angles'?)"),
    ('patch-test = []', "verdict.patch-test: sweeps must be \"all\" or a non-empty list of sweep names, got []"),
    ('patch-test = {sweeps = ["h"], problems = ["kirsch"]}',
     "verdict.patch-test: no sweep it names runs the problem 'kirsch'; they run manufactured"),
    ('patch-test = {sweep = ["h"]}', "verdict.patch-test: unknown key 'sweep'"),
])
def test_bad_verdict_tables_are_refused_in_one_line(verdict, message):
    spec = SPEC[:SPEC.index("[verdict]")] + "[verdict]\n" + verdict + "\n"
    with pytest.raises(InputError) as error:
        parse(spec)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)


def test_bands():
    assert criteria.below(1e-9, 1e-4)(1e-12, 0) == "good" and criteria.below(1e-9, 1e-4)(1e-3, 0) == "poor"
    assert criteria.above(1.8, 1.4)(1.5, 2) == "fair"
    near = criteria.near_best(2.0, 10.0)
    assert near(1.9e-3, 1e-3) == "good" and near(5e-3, 1e-3) == "fair" and near(2e-2, 1e-3) == "poor"
    assert near(1e-12, 1e-15) == "good"        # both below round-off
