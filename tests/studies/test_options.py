"""Every option of `ibm-study solve` and every key of a study spec, generated with hypothesis over the
declared options (the case settings and every method's Parameters), valid and invalid: NaN, inf,
negative, zero, out of range, wrong type, unknown names. Each run either succeeds, or exits 2 (bad
input) or 3 (a solve that refuses to answer) with one line naming the option or the value."""
from __future__ import annotations

import math

import pytest

from hypothesis import HealthCheck, given, settings, strategies as st

from baselines.registry import METHODS, method_parameters
from ibm.exceptions import InputError
from studies.cli import main, problem_names
from studies.run.spec import parse

# cheap base cases: a 2 x 2 grid of h = 50 (2D) and the 3D box at h = 50
BASE_2D = ["solve", "--cell", "50", "--json"]
BASE_3D = ["solve", "--dim", "3", "--cell", "50", "--json"]
NUMBERS = {   # option -> a strategy of values the option takes on a cheap case
    "angle": st.floats(0, 359.9), "cell": st.floats(34, 60), "ppc": st.integers(1, 3), "E": st.floats(1, 1e9),
    "nu": st.floats(0, 0.45), "load": st.floats(0.1, 1e3), "width": st.floats(60, 150), "height": st.floats(60, 150),
}
NAMES = {     # option -> its allowed names
    "problem": ["confined-block", "manufactured", "lame", "kirsch"], "method": list(METHODS),
    "solver": ["auto", "superlu"], "basis": ["mpm", "gimp"], "locking": ["none"], "footing": ["smooth"],
    "material": ["elastic"], "kinematics": ["small"], "band": ["auto"],
}
BAD_NUMBERS = st.sampled_from(["nan", "inf", "-inf", "-1", "0", "1e300", "-1e-300", "abc", "", "1,5"])
BAD_NAMES = st.sampled_from(["", "IBM", "penalty ", "nope", "nan", "0", "confined_block"])


def parameter_values(parameter):
    """Values inside a declared parameter's range, kept to cheap, well-conditioned solves."""
    high = min(parameter.high, 1e8)
    low = parameter.low if parameter.low_inclusive else max(parameter.low, high * 1e-6)
    return st.floats(low, high, allow_nan=False, allow_infinity=False)


def one_line(code: int, err: str, *names: str) -> bool:
    lines = err.strip().splitlines()
    for name in list(names):          # a number may be named as Python prints it
        try:
            names += (f"{float(name):g}", repr(float(name)))
        except ValueError:
            pass
    if code == 3:          # a solve that refuses to answer says why, not which option
        return len(lines) == 1 and lines[0].startswith("ibm-study: solve failed: ")
    return code == 2 and len(lines) == 1 and any(n and n.lower() in lines[0].lower() for n in names)


@st.composite
def command(draw):
    """(argv, names one of which a refusal must name)."""
    kind = draw(st.sampled_from(["number", "name", "parameter", "tilt"]))
    valid = draw(st.booleans())
    if kind == "tilt":
        value = draw(st.floats(0, 359.9).map(repr) if valid else BAD_NUMBERS)
        return [*BASE_3D, "--method", "ibm", "--tilt", value], ("tilt", value)
    if kind == "number":
        option = draw(st.sampled_from(sorted(NUMBERS)))
        value = repr(draw(NUMBERS[option])) if valid else draw(BAD_NUMBERS)
    elif kind == "name":
        option = draw(st.sampled_from(sorted(NAMES)))
        value = draw(st.sampled_from(NAMES[option]) if valid else BAD_NAMES)
    else:
        declared = method_parameters()
        option = draw(st.sampled_from(sorted(declared)))
        owners = [m for m in METHODS.values() if option in m.names]
        method = draw(st.sampled_from(owners + [METHODS["nodal"]]))     # nodal declares none: "not a parameter"
        value = repr(draw(parameter_values(declared[option][0]))) if valid else draw(BAD_NUMBERS)
        return [*BASE_2D, "--method", method.name, "--" + option.replace("_", "-"), value], (
            option.replace("_", "-"), value, method.name)
    flag = "--" + option.replace("_", "-")
    names = (option, option.replace("_", "-"), option.replace("_", " "), repr(value), value)
    if option == "cell":
        names += ("cell size",)
    return [*BASE_2D, flag, value], names


@pytest.mark.slow
@settings(max_examples=60, deadline=None,          # capsys is read out after every example
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(command())
def test_every_option_succeeds_or_is_refused_in_one_line(capsys, case):
    argv, names = case
    try:
        code = main(argv)
    except SystemExit as stop:            # argparse's own refusal (a value of the wrong type)
        code = stop.code
    captured = capsys.readouterr()
    assert code == 0 or one_line(code, captured.err, *names), (argv, code, captured.err[-2000:])


@st.composite
def spec_key(draw):
    """(spec text, names one of which a refusal must name) with one key of the base or a sweep set."""
    declared = method_parameters()
    key = draw(st.sampled_from(sorted({*NUMBERS, *NAMES, *declared, "tilt", "dim", "steps", "offset", "colour"})))
    value = draw(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10**6),
                           st.text("abcxyzé-_ .,09δ", max_size=8), st.booleans(), st.lists(st.floats(-2, 400), max_size=3),
                           st.sampled_from(problem_names() + list(METHODS))))
    if isinstance(value, float) and not math.isfinite(value):
        text = {True: "nan", False: ("inf" if value > 0 else "-inf")}[math.isnan(value)]
    elif isinstance(value, str):
        text = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    elif isinstance(value, bool):
        text = "true" if value else "false"
    else:
        text = repr(value)
    methods = '["penalty", "nitsche", "lagrange", "ibm"]'
    where = draw(st.sampled_from(["base", "sweep"]))
    cell = "" if key == "cell" else "cell = 50.0\n"
    if where == "base":
        source = f"[base]\n{cell}{key} = {text}\n[[sweep]]\nname = \"a\"\nmethods = {methods}\n"
    else:
        source = f"[base]\n{cell}[[sweep]]\nname = \"a\"\nmethods = {methods}\n{key} = {text}\n"
    plain = text.strip('"')
    return source, (key, key.replace("_", "-"), key.replace("_", " "), plain, *_printed(value))


def _printed(value) -> tuple:
    """The ways a message may print a number."""
    try:
        return (f"{float(value):g}", repr(float(value)), str(value))
    except (TypeError, ValueError):
        return (str(value),)


@settings(max_examples=200, deadline=None)
@given(spec_key())
def test_every_spec_key_is_taken_or_refused_in_one_line(case):
    source, names = case
    try:
        parse(source)
    except InputError as error:
        message = str(error)
        assert "\n" not in message and any(n in message for n in names), (source, message)
