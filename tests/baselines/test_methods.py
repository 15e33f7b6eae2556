"""The methods' declarations (ibm.boundary_method, baselines.registry): each parameter declared once
drives the command line, the checks and the defaults; capabilities refuse in one line."""
from __future__ import annotations

import math
import re

import pytest

from baselines.registry import METHODS, in_3d, in_load_steps, method_parameters, register
from ibm.boundary_method import BoundaryMethod, Parameter, Supports
from ibm.exceptions import InputError
from studies.cli import main
from studies.problems import registry


def test_every_declared_default_is_allowed_and_every_flag_is_on_the_command_line(capsys):
    with pytest.raises(SystemExit):
        main(["solve", "--help"])
    text = capsys.readouterr().out
    for method in METHODS.values():
        assert re.search(rf"^  {re.escape(method.name)} +{re.escape(method.summary)}$", text, re.MULTILINE)
        for parameter in method.parameters:
            parameter.check(parameter.default)
            parameter.check(parameter.default_for(load_steps=True))
            assert parameter.flag in text


def test_the_help_lists_every_problem_with_its_summary_in_2d_and_3d(capsys):
    with pytest.raises(SystemExit):
        main(["solve", "--help"])
    text = capsys.readouterr().out
    listed = text.split("problems (--problem):")[1]
    two_d, three_d = listed.split("problems with --dim 3:")
    for dim, block in ((2, two_d), (3, three_d.split("boundary methods")[0])):
        for name in registry.names(dim):
            summary = registry.get(name, dim).summary
            assert re.search(rf"^  {re.escape(name)} +{re.escape(summary)}$", block, re.MULTILINE), (name, dim)


@pytest.mark.parametrize("value", [math.nan, math.inf, -1.0, 0.0, 2.0, "big", True, None])
def test_a_parameter_refuses_what_its_range_does_not_hold(value):
    band = Parameter("delta_rel", 1e-5, "band width", high=1.0)
    if value is None:
        return band.check(1e-3)
    with pytest.raises(InputError, match=r"^delta-rel .* is not allowed; it must be in \(0, 1\]$"):
        band.check(value)


def test_capabilities_follow_the_declarations():
    assert in_3d() == ["ibm", "ibm-limit", "penalty", "nitsche", "lagrange", "nodal", "fem"]
    assert in_load_steps(2) == ["ibm", "penalty", "nitsche", "lagrange", "nodal", "fem"]
    assert in_load_steps(3) == ["ibm", "penalty", "nitsche", "lagrange", "nodal"]
    assert set(method_parameters()) == {"delta_rel", "support_threshold", "beta0", "gamma", "augment"}
    assert METHODS["penalty"].used({"beta0": None}, load_steps=True) == {"beta0": 1e6, "support_threshold": 0.1}
    assert METHODS["penalty"].used({"support_threshold": 0.0}) == {"beta0": 1e6, "support_threshold": 0.0}
    with pytest.raises(InputError, match="^method 'lagrange-nodal' refuses 3D cases"):
        METHODS["lagrange-nodal"].require("3d")
    with pytest.raises(ValueError, match="unknown capabilities"):
        Supports({"flying": "no"})


def test_a_method_name_is_registered_once():
    class Impostor(BoundaryMethod):
        name = "penalty"
    with pytest.raises(InputError, match="registered twice"):
        register(Impostor())
    assert type(METHODS["penalty"]).__name__ == "PenaltyMethod"


@pytest.mark.parametrize("arguments, words", [
    (["--dim", "3", "--tilt", "nan"], "tilt nan is not allowed"),
    (["--dim", "3", "--angle", "inf"], "angle inf is not allowed"),
    (["--dim", "3", "--method", "penalty", "--augment", "2"], "augment is not a parameter of method 'penalty'"),
    (["--dim", "3", "--method", "lagrange", "--augment", "-1"], "augment -1.0 is not allowed; it must be a number >= 0"),
    (["--method", "nitsche", "--gamma", "nan"], "gamma nan is not allowed; it must be a number > 0"),
])
def test_bad_values_of_declared_parameters_are_one_line(arguments, words, capsys):
    assert main(["solve", *arguments]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1, err


def test_the_3d_solve_takes_every_declared_parameter():
    from studies.run.solid import solve_box_case
    common = ("confined-block", "lagrange", 30.0, 20.0, (0.37, 0.29, 0.11), 50.0)
    plain, augmented = (solve_box_case(*common, augment=a) for a in (0.0, 2.0))
    assert plain["err_u"] < 1e-6 and augmented["err_u"] < 1e-6
    assert plain["err_u"] != augmented["err_u"]      # the value reaches the solve
