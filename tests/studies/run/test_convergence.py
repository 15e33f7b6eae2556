"""Convergence study: delta laws, rate fitting, the converge command, measured rates per method."""
import json
import re
from functools import lru_cache

import numpy as np
import pytest

import studies.run.convergence as convergence
from baselines.registry import METHODS
from ibm.exceptions import InputError
from studies.run.case import CaseSpec
from studies.cli import main
from studies.run.convergence import (RATE_LAW_SETTINGS, RATE_LAWS, cell_sizes, converge, fitted_rate, level_rates,
                                 parse_delta_law, table)

ANGLES = RATE_LAW_SETTINGS["angles"]
# the gates: fitted L2 and energy rates over >= 3 levels, at every angle
GATES = {"fem": (1.9, 0.9), "nitsche": (1.8, None), "lagrange": (1.8, None)}


@lru_cache(maxsize=None)
def study(method, angle, levels, delta_law=None, parameters=(), problem="manufactured", load_type="pressure"):
    base = CaseSpec(problem=problem, load_type=load_type, method=method, angle=angle,
                    ppc=RATE_LAW_SETTINGS["ppc"], method_parameters=dict(parameters))
    return converge(base, levels, delta_law)


# --- laws and rates ------------------------------------------------------------------

@pytest.mark.parametrize("text,power,c", [("c*h", 1, None), ("c*h^2", 2, None), (" 0.001 * h ^ 2 ", 2, 1e-3),
                                          ("1e-2*h", 1, 1e-2), (".5*h", 1, 0.5)])
def test_delta_laws_parse(text, power, c):
    law = parse_delta_law(text)
    assert (law.power, law.coefficient) == (power, c)


def test_delta_laws_give_delta_over_h_per_level():
    cells = cell_sizes(10.0, 4)
    assert cells == [10.0, 5.0, 2.5, 1.25]
    assert parse_delta_law("c*h").delta_rels(cells, 1e-5) == pytest.approx([1e-5] * 4, rel=1e-15)
    assert parse_delta_law("c*h^2").delta_rels(cells, 1e-5) == pytest.approx([1e-5, 5e-6, 2.5e-6, 1.25e-6])
    assert parse_delta_law("0.001*h^2").delta_rels(cells, 1.0) == pytest.approx([1e-2, 5e-3, 2.5e-3, 1.25e-3])


@pytest.mark.parametrize("text", ["c*h^3", "h", "c*x", "-1*h", "0*h^2", "c*h^", "c**h", ""])
def test_bad_delta_laws_are_named(text):
    with pytest.raises(InputError, match="delta law|coefficient"):
        parse_delta_law(text)


@pytest.mark.parametrize("levels", [1, 9, 2.5, True])
def test_bad_level_counts_are_named(levels):
    with pytest.raises(InputError, match=f"levels {re.escape(repr(levels))} is not allowed"):
        cell_sizes(10.0, levels)


def test_fitted_and_level_rates_recover_a_power_law():
    h = np.array([10.0, 5.0, 2.5, 1.25])
    assert fitted_rate(h, 3 * h**2) == pytest.approx(2.0, abs=1e-12)
    assert fitted_rate(h, 3 * h**2 * (1 + 0.1 * (-1) ** np.arange(4))) == pytest.approx(2.0, abs=0.15)
    assert level_rates(h, 0.5 * h**1.5)[1:] == pytest.approx([1.5] * 3, abs=1e-12)
    assert level_rates(h, h)[0] is None
    assert fitted_rate(h, [1.0, 0.0, 1.0, 1.0]) is None


def test_a_delta_law_needs_a_method_with_a_band():
    with pytest.raises(InputError, match="delta law is not allowed for method 'nitsche'"):
        converge(CaseSpec(method="nitsche"), 2, "c*h^2")


# --- the command -----------------------------------------------------------------------

def test_converge_command_prints_levels_and_rates_as_json(capsys):
    code = main(["converge", "--problem", "column", "--angle", "30", "--levels", "3", "--delta-law", "c*h^2",
                 "--offset", "0.1", "0.6", "--E", "2e4", "--nu", "0.25", "--json"])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert [level["cell"] for level in result["levels"]] == [10.0, 5.0, 2.5]
    assert [level["delta_rel"] for level in result["levels"]] == pytest.approx([1e-5, 5e-6, 2.5e-6])
    assert result["levels"][0]["offset"] == [0.1, 0.6] and result["levels"][0]["nu"] == 0.25
    assert result["levels"][0]["ppc"] == 2                      # the study's default
    assert set(result["rates"]) == {"err_l2", "err_energy", "err_u", "err_sigma"}
    assert result["rates"]["err_l2"] > 1.5                      # the column's quadratic field
    assert result["levels"][0]["rate_err_l2"] is None and result["levels"][2]["rate_err_l2"] > 1.0


def test_converge_command_prints_a_table(capsys):
    assert main(["converge", "--problem", "confined-block", "--load-type", "settlement", "--levels", "2",
                 "--angle", "45"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "confined-block (settlement), method ibm, angle 45"
    assert out[1].split()[:4] == ["h", "ndof", "delta/h", "err_l2"]
    assert out[-1].split()[0] == "fitted" and len(out) == 5


@pytest.mark.parametrize("argv,message", [
    (["--delta-law", "c*h^3"], "delta law 'c*h^3' is not allowed; use 'c*h' or 'c*h^2'"),
    (["--levels", "0"], "levels 0 is not allowed; it must be an integer from 2 to 8"),
    (["--levels", "8", "--cell", "0.01"], "cell size 0.01 is not allowed"),
    (["--load-type", "settlement"], "load type 'settlement' is not allowed for problem 'manufactured'"),
    (["--method", "fem", "--delta-law", "c*h"], "a delta law is not allowed for method 'fem'"),
])
def test_converge_command_rejects_bad_input_in_one_line(capsys, argv, message):
    assert main(["converge", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


# --- measured rates ----------------------------------------------------------------------

@pytest.mark.parametrize("method", ["nitsche", "lagrange"])
@pytest.mark.parametrize("angle", ANGLES)
def test_consistent_methods_converge_at_the_optimal_l2_rate(method, angle):
    result = study(method, angle, 3)
    l2, energy = GATES[method]
    assert result["rates"]["err_l2"] >= l2
    assert result["rates"]["err_energy"] >= 0.9


@pytest.mark.slow   # the fem baseline's point location (scikit-fem element finder) dominates
@pytest.mark.parametrize("angle", ANGLES)
def test_body_fitted_fem_converges_at_the_optimal_rates(angle):
    result = study("fem", angle, 3)
    l2, energy = GATES["fem"]
    assert result["rates"]["err_l2"] >= l2
    assert result["rates"]["err_energy"] >= energy


@pytest.mark.parametrize("law", RATE_LAWS, ids=lambda law: f"{law.method}:{law.law}")
def test_documented_rate_laws_hold(law):
    results = [study(law.method, angle, RATE_LAW_SETTINGS["levels"], law.delta_law, law.method_parameters)
               for angle in ANGLES]
    l2 = min(r["rates"]["err_l2"] for r in results)
    energy = min(r["rates"]["err_energy"] for r in results)
    assert l2 == pytest.approx(law.l2, abs=0.05)
    assert energy == pytest.approx(law.energy, abs=0.05)


def test_rate_laws_are_documented_where_they_are_defined():
    doc = convergence.__doc__
    methods = {law.method for law in RATE_LAWS}
    assert methods == {"ibm", "ibm-limit", "penalty"} and methods <= set(METHODS)
    for law in RATE_LAWS:
        row = re.search(rf"^\s*{re.escape(law.method)}\s+{re.escape(law.law)}\s+(\S+)\s+(\S+)", doc, re.M)
        assert row is not None, law
        assert (float(row[1]), float(row[2])) == (law.l2, law.energy)
        if law.delta_law is not None:   # the law in the table is the one the study runs
            parsed = parse_delta_law(law.delta_law)
            assert f"{parsed.coefficient:g} h" + ("^2" if parsed.power == 2 else "") in law.law
        stated = float(re.search(r"= (\S+)", law.law)[1])       # the coefficient the table states
        parameters = dict(law.method_parameters)
        for name, value in parameters.items():
            assert name in METHODS[law.method].names and stated == value
        if "default" in law.law:                                   # ... is still the method's default
            name = "delta_rel" if law.method.startswith("ibm") else "beta0"
            assert name not in parameters and stated == METHODS[law.method].defaults()[name]


def test_settlement_block_converges_through_its_quadratic_lift():
    result = study("ibm", 30.0, 3, problem="confined-block", load_type="settlement")
    assert result["rates"]["err_l2"] > 1.9
    assert result["rates"]["err_energy"] > 0.9


def test_table_lists_every_level():
    result = study("nitsche", 45.0, 3)
    lines = table(result).splitlines()
    assert len(lines) == 2 + 3 + 1
    assert "delta/h" not in lines[1]
