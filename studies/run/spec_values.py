"""The values of a study spec's keys: the kind each CaseSpec field and method parameter takes, and the
checks that read a value, an axis (a value, a list or a range), random offsets, orientations, a delta
law, names and choices, each raising InputError with one line naming the key and what is allowed.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ibm.exceptions import InputError
from studies.problems.library import closest
from studies.run.case import CaseSpec

MAX_CASES = 20000


def case_fields() -> dict[str, str]:
    """CaseSpec field -> kind ('float', 'int', 'str', 'point'), read from its defaults."""
    out = {}
    for f in dataclasses.fields(CaseSpec):
        if f.name == "method_parameters":
            continue
        default = f.default
        if isinstance(default, bool):
            out[f.name] = "bool"
        elif isinstance(default, int):
            out[f.name] = "int"
        elif isinstance(default, float) or (default is None and str(f.type).startswith("float")):
            out[f.name] = "float"           # a float that may be left unset (None)
        elif isinstance(default, str):
            out[f.name] = "str"
        elif isinstance(default, tuple) and len(default) == 2:
            out[f.name] = "point"           # two numbers in 2D, three in 3D
        else:
            out[f.name] = "any"
    return out


def method_parameter_kinds(methods) -> dict[str, str]:
    out = {}
    for method in methods.values():
        for key, default in method.defaults().items():
            kind = "str" if isinstance(default, str) else ("int" if isinstance(default, int)
                                                           and not isinstance(default, bool) else "float")
            out.setdefault(key, kind)
    return out


def check_table(value, where: str) -> None:
    if not isinstance(value, dict):
        raise InputError(f"{where} must be a table, got {type(value).__name__}")


def check_keys(data: dict, allowed: tuple, where: str) -> None:
    for key in data:
        if key not in allowed:
            raise InputError(f"{where}: unknown key {key!r}{closest(key, allowed)}; allowed: {', '.join(allowed)}")


def string(value, where: str) -> str:
    if not isinstance(value, str):
        raise InputError(f"{where} must be a string, got {value!r}")
    return value


def boolean(value, where: str) -> bool:
    if not isinstance(value, bool):
        raise InputError(f"{where} must be true or false, got {value!r}")
    return value


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where} must be a finite number, got {value!r}")
    return float(value)


def scalar(value, kind: str, where: str):
    if kind == "float":
        return _number(value, where)
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(f"{where} must be an integer, got {value!r}")
        return value
    if kind == "str":
        return string(value, where)
    if kind == "bool":
        return boolean(value, where)
    if kind == "point":
        if not isinstance(value, list) or len(value) not in (2, 3):
            raise InputError(f"{where} must be a pair of numbers [x, y] (three, [x, y, z], in 3D), got {value!r}")
        return tuple(_number(v, where) for v in value)
    return value


def axis_values(value, kind: str, where: str) -> list:
    """A value, a list of values, or a range table -> the list of values."""
    if isinstance(value, dict):
        if kind not in ("float", "int"):
            raise InputError(f"{where}: a range {{from, to, ...}} is only allowed for numbers")
        values = _range(value, where)
        if kind == "int":
            if any(v != round(v) for v in values):
                raise InputError(f"{where}: the range gives non-integer values; this axis takes integers")
            values = [int(round(v)) for v in values]
        return values
    if kind == "point":
        if isinstance(value, list) and value and all(isinstance(v, list) for v in value):
            items = value
        else:
            items = [value]
    else:
        items = value if isinstance(value, list) else [value]
    if not items:
        raise InputError(f"{where} is an empty list; give at least one value")
    out = []
    for item in items:
        v = scalar(item, kind, where)
        if v not in out:
            out.append(v)
    return out


def _range(data: dict, where: str) -> list[float]:
    allowed = ("from", "to", "step", "count", "spacing")
    check_keys(data, allowed, where)
    for key in ("from", "to"):
        if key not in data:
            raise InputError(f"{where}: a range needs 'from' and 'to' (and 'step' or 'count')")
    start, stop = _number(data["from"], f"{where}.from"), _number(data["to"], f"{where}.to")
    spacing = string(data.get("spacing", "linear"), f"{where}.spacing")
    if spacing not in ("linear", "log"):
        raise InputError(f"{where}.spacing {spacing!r} is not allowed; allowed: linear, log")
    if ("step" in data) == ("count" in data):
        raise InputError(f"{where}: give exactly one of 'step' or 'count'")
    if "step" in data:
        if spacing == "log":
            raise InputError(f"{where}: spacing = 'log' needs 'count', not 'step'")
        step = _number(data["step"], f"{where}.step")
        if step <= 0 or stop < start:
            raise InputError(f"{where}: step must be > 0 with from <= to, got from {start:g} to {stop:g} step {step:g}")
        n = int(math.floor((stop - start) / step + 1e-9)) + 1
        if n > MAX_CASES:
            raise InputError(f"{where}: the range has {n} values; at most {MAX_CASES} are allowed")
        return [round(start + i * step, 12) for i in range(n)]
    count = data["count"]
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 1000:
        raise InputError(f"{where}.count {count!r} is not allowed; it must be an integer from 1 to 1000")
    if spacing == "log":
        if start <= 0 or stop <= 0:
            raise InputError(f"{where}: spacing = 'log' needs from > 0 and to > 0")
        values = np.geomspace(start, stop, count)
        return [float(f"{v:.12g}") for v in values]
    return [float(f"{v:.12g}") for v in np.linspace(start, stop, count)]


def random_offsets(data, where: str, dim: int = 2) -> list[tuple[float, ...]]:
    check_table(data, where)
    check_keys(data, ("count", "seed"), where)
    count, seed = data.get("count"), data.get("seed", 0)
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 1000:
        raise InputError(f"{where}.count {count!r} is not allowed; it must be an integer from 1 to 1000")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"{where}.seed {seed!r} is not allowed; it must be an integer >= 0")
    draws = np.random.default_rng(seed).random((count, 3 if dim == 3 else 2))
    return [tuple(round(float(v), 6) % 1.0 for v in draw) for draw in draws]


def orientations(value, where: str) -> list[tuple[float, float]]:
    """orientation = [[angle, tilt], ...] (degrees) -> the distinct pairs, in order."""
    items = value if isinstance(value, list) and value and all(isinstance(v, list) for v in value) else [value]
    out = []
    for item in items:
        if not isinstance(item, list) or len(item) != 2:
            raise InputError(f"{where} must be a list of [angle, tilt] pairs (degrees), got {item!r}")
        pair = (_number(item[0], where), _number(item[1], where))
        if pair not in out:
            out.append(pair)
    return out


def delta_law(data, where: str):
    """delta = coefficient * h^power, i.e. delta_rel = coefficient * h^(power - 1)."""
    check_table(data, where)
    check_keys(data, ("coefficient", "power"), where)
    if "coefficient" not in data:
        raise InputError(f"{where}: needs 'coefficient' (delta = coefficient * h^power)")
    coefficient = _number(data["coefficient"], f"{where}.coefficient")
    power = _number(data.get("power", 1.0), f"{where}.power")
    if coefficient <= 0:
        raise InputError(f"{where}.coefficient {coefficient:g} is not allowed; it must be > 0")
    if not 0 <= power <= 4:
        raise InputError(f"{where}.power {power:g} is not allowed; it must be in [0, 4]")
    return lambda h: float(f"{coefficient * h ** (power - 1.0):.12g}")


def given_names(value, registry: dict, where: str, also: tuple[str, ...] = (), every: list | None = None) -> list[str]:
    """The names given (or `every`, by default every name of `registry`, for "all"); `also` are allowed by
    name only."""
    if value == "all":
        return list(registry) if every is None else list(every)
    allowed = list(registry) + [name for name in also if name not in registry]
    items = value if isinstance(value, list) else [value]
    if not items:
        raise InputError(f"{where} is an empty list; give at least one name or \"all\"")
    out = []
    for item in items:
        if not isinstance(item, str):
            raise InputError(f"{where} must hold names (strings), got {item!r}")
        if item not in allowed:
            raise InputError(f"{where}: unknown name {item!r}{closest(item, allowed)}; "
                             f"allowed: {', '.join(allowed)}")
        if item not in out:
            out.append(item)
    return out


def choices(value, allowed: dict, where: str) -> list[str]:
    if not isinstance(value, list):
        raise InputError(f"{where} must be a list of names, got {value!r}")
    for item in value:
        if not isinstance(item, str) or item not in allowed:
            hint = closest(item, allowed) if isinstance(item, str) else ""
            raise InputError(f"{where}: unknown {item!r}{hint}; allowed: {', '.join(allowed)}")
    return list(dict.fromkeys(value))
