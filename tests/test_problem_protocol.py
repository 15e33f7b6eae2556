"""One protocol for every problem (studies.problems.problem): the registry holds every family, the
case runner dispatches through it, and no module outside a problem's or a method's own switches on
its name."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from baselines.registry import METHODS
from ibm.exceptions import InputError
from studies.problems import registry
from studies.problems.problem import Problem
from studies.run.case import CaseSpec, check_checkpoint, load_stepped, validate

ROOT = Path(__file__).resolve().parents[1]
# the modules that define the problems and the methods: each may name its own
PROBLEM_MODULES = {ROOT / "studies" / "problems"}
METHOD_MODULES = {ROOT / "baselines", ROOT / "ibm" / "implicit_boundary.py"}


def _names_compared(path: Path, names: set[str]) -> list[str]:
    """`line: source` of each comparison in `path` with a literal name of `names` on either side
    (x == "name", x in ("a", "b"), ...)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Compare):
            continue
        for side in (node.left, *node.comparators):
            items = side.elts if isinstance(side, (ast.Tuple, ast.List, ast.Set)) else [side]
            if any(isinstance(i, ast.Constant) and i.value in names for i in items):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {ast.unparse(node)}")
                break
    return found


def _sources(outside: set[Path]) -> list[Path]:
    paths = [p for package in ("ibm", "baselines", "studies") for p in (ROOT / package).rglob("*.py")]
    return [p for p in paths if not any(p == o or o in p.parents for o in outside)]


def test_no_module_outside_a_problem_s_own_switches_on_a_problem_name():
    names = set(registry.names(None))
    found = [line for path in _sources(PROBLEM_MODULES) for line in _names_compared(path, names)]
    assert not found, "\n".join(found)


def test_no_module_outside_a_method_s_own_switches_on_a_method_name():
    found = [line for path in _sources(METHOD_MODULES) for line in _names_compared(path, set(METHODS))]
    assert not found, "\n".join(found)


def test_the_check_finds_a_switch(tmp_path):
    source = tmp_path / "switch.py"
    source.write_text('def f(spec):\n    return spec.problem == "footing" or spec.method in ("ibm", "x")\n')
    global ROOT
    root, ROOT = ROOT, tmp_path
    try:
        assert len(_names_compared(source, {"footing"})) == 1 and len(_names_compared(source, {"ibm"})) == 1
    finally:
        ROOT = root


def test_every_family_is_a_problem_and_registered_once():
    problems = list({id(p): p for p in registry.PROBLEMS.values()}.values())
    assert all(isinstance(p, Problem) for p in problems)
    families = {type(p).__name__ for p in problems}
    assert families >= {"ClosedFormProblem", "HillCylinder", "Footing", "AmpleCollapse", "BoxProblem"}
    assert registry.FROM_FILE and registry.FROM_FILE[0].from_file
    assert registry.names(3) == ["confined-block", "column", "manufactured"]
    assert set(registry.collapse_names()) == {"hill-cylinder", "footing"}
    with pytest.raises(InputError, match="registered twice"):
        registry.register(type(registry.get("footing"))())


@pytest.mark.parametrize("spec, family", [
    (CaseSpec(), "ClosedFormProblem"), (CaseSpec(problem="column", dim=3), "BoxProblem"),
    (CaseSpec(problem="footing", steps=20, ppc=2, locking="fbar", basis="mpm"), "Footing"),
    (CaseSpec(problem="ample-collapse", method="nodal"), "AmpleCollapse")])
def test_a_case_goes_to_its_problem(spec, family):
    validate(spec)
    assert type(registry.problem_of(spec)).__name__ == family


def test_the_problem_says_what_a_checkpoint_can_save():
    assert load_stepped(CaseSpec(problem="column", kinematics="large", steps=4))
    assert load_stepped(CaseSpec(problem="column", dim=3, kinematics="large", steps=4, method="penalty"))
    assert not load_stepped(CaseSpec(problem="column", dim=3))
    with pytest.raises(InputError, match="3D small-strain case is one linear solve"):
        check_checkpoint(CaseSpec(problem="column", dim=3))
    with pytest.raises(InputError, match="not available for 'ample-collapse' yet"):
        check_checkpoint(CaseSpec(problem="ample-collapse", method="nodal"))


def test_a_setting_of_another_problem_is_refused_in_one_line():
    with pytest.raises(InputError, match="footing 'rough' is for problem 'footing', not 'column'"):
        validate(CaseSpec(problem="column", footing="rough"))
    with pytest.raises(InputError, match="problem 'lame' is not available with dim = 3"):
        validate(CaseSpec(problem="lame", dim=3))
