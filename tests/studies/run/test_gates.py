"""CI error gates: every reference case of studies/run/thresholds.toml within its thresholds."""
from __future__ import annotations

import pytest

from ibm.exceptions import InputError
from studies.run import gates

GATES = gates.load()


@pytest.mark.parametrize("gate", GATES, ids=[g.name for g in GATES])
def test_reference_case_within_its_thresholds(gate):
    checks = gates.evaluate(gate)
    assert len(checks) == max(1, len(gate.max) + len(gate.min_rate))
    failures = [c.message for c in checks if not c.passed]
    assert not failures, "\n".join(failures)


def test_thresholds_cover_the_seed_and_every_method():
    from studies.run.spec import load_registries
    methods, _ = load_registries()
    covered = {g.case.method for g in GATES}
    assert covered >= set(methods) - {"lagrange-nodal"}     # the unstable variant has no accuracy to gate
    assert {g.case.angle for g in GATES if g.name.startswith("seed-")} == {90.0, 45.0, 30.0}
    assert any(g.min_rate for g in GATES)


def test_a_regression_fails_with_case_value_and_threshold():
    tight = gates.parse({"gate": [{"name": "too-tight", "case": {"method": "ibm", "angle": 30.0},
                                   "max": {"err_u": 1e-12}}]})[0]
    (check,) = gates.evaluate(tight)
    assert not check.passed and check.kind == "max" and check.value > 1e-12
    assert check.message.startswith("gate 'too-tight' (confined-block, ibm, angle 30, h 10")
    assert f"err_u = {check.value:.3e} exceeds the maximum 1.000e-12" in check.message


def test_a_rate_regression_fails_with_the_fitted_rate():
    steep = gates.parse({"gate": [{"name": "steep", "case": {"problem": "manufactured", "angle": 30.0},
                                   "cells": [25.0, 12.5], "min_rate": {"err_l2": 5.0}}]})[0]
    (check,) = gates.evaluate(steep)
    assert not check.passed and 0.5 < check.value < 3.0
    assert f"fitted rate of err_l2 = {check.value:.3f} is below the minimum 5.000" in check.message


def test_a_case_that_stops_solving_fails_the_gate():
    broken = gates.parse({"gate": [{"name": "indefinite", "case": {"method": "nitsche", "angle": 30.0,
                                                                    "gamma": 0.1}, "max": {"err_u": 1.0}}]})[0]
    (check,) = gates.evaluate(broken)
    assert not check.passed and check.kind == "failed"
    assert "gate 'indefinite'" in check.message and "SolveError" in check.message


@pytest.mark.parametrize("entry, words", [
    ({"name": "a", "case": {"angel": 30.0}, "max": {"err_u": 1.0}}, ["angel", "angle"]),
    ({"name": "a", "case": {"angle": 400.0}, "max": {"err_u": 1.0}}, ["angle 400", "[0, 360)"]),
    ({"name": "a", "max": {"err_x": 1.0}}, ["err_x", "allowed"]),
    ({"name": "a", "max": {"err_u": -1.0}}, ["max.err_u", "> 0"]),
    ({"name": "a", "min_rate": {"err_u": 1.0}}, ["min_rate needs cells"]),
    ({"name": "a", "cells": [10.0], "min_rate": {"err_u": 1.0}}, ["cells", "two distinct"]),
    ({"name": "a"}, ["max and/or min_rate"]),
    ({"name": "a", "limit": 1}, ["unknown key 'limit'"]),
])
def test_bad_thresholds_are_rejected(entry, words):
    with pytest.raises(InputError) as caught:
        gates.parse({"gate": [entry]})
    for word in words:
        assert word in str(caught.value)
