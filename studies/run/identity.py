"""Case identity: the settings that define a case, its id (a hash of them and of the code that computes
it), and that code's fingerprint. Results are stored and resumed by case id.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from functools import lru_cache
from pathlib import Path

from baselines.registry import BUILT_IN, METHODS
from studies.problems.problem_file import file_digest
from studies.run.case import CaseSpec
from studies.run.spec_values import case_fields


def case_settings(case: CaseSpec) -> dict:
    """The settings that define a case, JSON-able, with canonical numeric types."""
    settings = dataclasses.asdict(case)
    for name, kind in case_fields().items():   # 30 and 30.0 are the same angle
        if kind == "float" and _is_number(settings[name]):
            settings[name] = float(settings[name])
    settings["offset"] = [float(o) for o in case.offset]
    settings["method_parameters"] = {k: _canonical_parameter(k, v) for k, v in sorted(case.method_parameters.items())}
    if settings.get("dilation_angle") is not None and settings["dilation_angle"] == settings.get("friction_angle"):
        settings["dilation_angle"] = None       # associated flow given explicitly is the unset default: one case
    for name, default in (("locking", "none"), ("footing", "smooth"), ("solver", "auto"), ("band", "auto"),
                          ("friction", 0.0), ("adhesion", 0.0), ("unit_weight", 0.0), ("surcharge", 0.0),
                          ("cohesion", 0.0), ("friction_angle", 0.0), ("dilation_angle", None)):
        if settings.get(name) == default:       # the default leaves the ids of cases from before it unchanged
            del settings[name]
    if case.dim == 2:                           # so do a 2D case's dim and tilt (always 0); a 3D case keeps both
        del settings["dim"], settings["tilt"]
    return settings


def _canonical_parameter(name: str, value):
    if not _is_number(value) or (isinstance(value, int) and not _float_parameter(name)):
        return value
    return float(value)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _float_parameter(name: str) -> bool:
    defaults = [m.defaults()[name] for m in METHODS.values() if name in m.names]
    return not defaults or not all(isinstance(d, int) and not isinstance(d, bool) for d in defaults)


_KNOWN: dict[tuple, str] = {}   # (code, repr(case)) -> its id: a study asks for each case's id many times
_KNOWN_AT_MOST = 100_000


def case_id(case: CaseSpec) -> str:
    """A short hash of the case's settings and of the code that computes it: equal settings,
    equal id, whatever the spec; a stored result of other code is never reused."""
    if case.problem_file:          # the file may change between two calls: hashed each time
        return _case_id(case)
    key = (code_fingerprint(), repr(case))
    found = _KNOWN.get(key)
    if found is None:
        if len(_KNOWN) >= _KNOWN_AT_MOST:
            _KNOWN.clear()
        found = _KNOWN[key] = _case_id(case)
    return found


def _case_id(case: CaseSpec) -> str:
    settings = case_settings(case)
    if case.problem_file:   # the file's content defines the case, not where it lies
        settings["problem_file"] = file_digest(case.problem_file)
    text = json.dumps(settings, sort_keys=True, separators=(",", ":")) + code_fingerprint()
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@lru_cache(maxsize=None)
def code_fingerprint() -> str:
    """Hash of the sources that compute a case (the core, the baselines, the problems, the case, the
    3D case and the runs of large kinematics and of the collapse problems), and of the modules of the
    methods that installed packages add."""
    root = Path(__file__).resolve().parents[2]
    plugins = {Path(sys.modules[type(m).__module__].__file__) for m in METHODS.values() if m not in BUILT_IN}
    files = sorted([*(root / "ibm").rglob("*.py"), *(root / "baselines").rglob("*.py"), *plugins,
                    *(root / "studies" / "problems").rglob("*.py"),
                    *(root / "studies" / "run" / name for name in ("case.py", "reference.py", "large.py",
                                                                  "collapse_runs.py", "small.py", "solid.py",
                                                                  "reactions.py"))])
    digest = hashlib.sha256()
    for path in files:
        digest.update(path.name.encode() + path.read_bytes())
    return digest.hexdigest()[:16]
