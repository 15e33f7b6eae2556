"""Every problem by name and dimension: the built-in ones and those of installed packages.

A package adds problems through the entry-point group `ibm_mpm.problems`, each entry naming a
Problem instance (studies.problems.problem), e.g. in its pyproject.toml:

    [project.entry-points."ibm_mpm.problems"]
    two-wave = "my_package.problem:TWO_WAVE"

`problem_of(spec)` is the problem a case solves: the file's when it names a problem file, else
the one of its name in its dimension.
"""
from __future__ import annotations

from baselines.registry import installed
from ibm.exceptions import InputError
from studies.problems import (ample_collapse, boxes, closed_form, collapse, file_placement, footing,
                              frictional_block, hertz, passive_wall)
from studies.problems.library import closest
from studies.problems.problem import Problem

GROUP = "ibm_mpm.problems"
BUILT_IN = (*closed_form.PROBLEMS, collapse.HILL, footing.FOOTING, ample_collapse.COLLAPSE,
            frictional_block.FRICTIONAL_BLOCK, hertz.HERTZ, passive_wall.PASSIVE_WALL, *boxes.PROBLEMS,
            file_placement.PROBLEM_FILE)


PROBLEMS: dict[tuple[str, int], Problem] = {}       # (name, dim) -> problem; the file's problem apart
FROM_FILE: list[Problem] = []


def register(problem: Problem) -> Problem:
    """Add `problem` under its name in each of its dimensions; a name already taken is refused in one line."""
    if problem.from_file:
        FROM_FILE[:] = [problem]
        return problem
    for dim in problem.dims:
        other = PROBLEMS.get((problem.name, dim))
        if other is not None and other is not problem:
            raise InputError(f"problem {problem.name!r} in {dim}D is registered twice ({other!r} and {problem!r})")
        PROBLEMS[problem.name, dim] = problem
    return problem


for _problem in (*BUILT_IN, *installed(GROUP, Problem, "problem")):
    register(_problem)


def names(dim: int | None = 2) -> list[str]:
    """The problems' names in `dim` dimensions (None: in any), in registration order."""
    return list(dict.fromkeys(name for name, d in PROBLEMS if dim is None or d == dim))


def collapse_names() -> list[str]:
    """The problems that measure a collapse load (no exact field)."""
    return list(dict.fromkeys(name for (name, _), p in PROBLEMS.items() if p.collapse))


def get(name: str, dim: int = 2) -> Problem:
    """The problem `name` in `dim` dimensions; InputError naming the allowed ones otherwise."""
    if (name, dim) not in PROBLEMS:
        allowed = names(dim)
        if dim == 2:
            raise InputError(f"unknown problem {name!r}{closest(name, allowed)}; allowed: {', '.join(allowed)}")
        raise InputError(f"problem {name!r} is not available with dim = {dim}{closest(name, allowed)}; "
                         f"allowed: {', '.join(allowed)}")
    return PROBLEMS[name, dim]


def problem_of(spec) -> Problem:
    """The problem a case solves: its problem file's, or its name's in its dimension."""
    if spec.problem_file and spec.dim == 2:
        return FROM_FILE[0]
    return get(spec.problem, spec.dim)


def owners_of(setting: str) -> list[Problem]:
    """The problems that read the CaseSpec field `setting` as their own."""
    return list({id(p): p for p in PROBLEMS.values() if setting in p.own_settings}.values())
