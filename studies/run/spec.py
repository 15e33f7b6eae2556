"""Study specs: a TOML file naming problems, methods and parameter sweeps, validated on load.

    title = "..."                     # optional
    description = "..."               # optional
    [base]                            # settings every case starts from (CaseSpec fields and
    nu = 0.3                          #   method parameters such as delta_rel, beta0, gamma)
    [output]
    vtk = false                       # write VTK files for the sweeps that keep fields
    [[sweep]]
    name = "angles"                   # unique, [a-z0-9-]
    summary = "..."                   # optional, shown in the report
    problems = ["confined-block"]     # or "all"; default: [base.problem]
    methods = "all"                   # or a list; default: [base.method]
    angle = {from = 0, to = 90, step = 5}   # any axis: a value, a list, or a range
    cell = [20, 10, 5]
    offset = [[0.37, 0.29], [0.5, 0.5]]     # or random_offsets = {count = 8, seed = 1}; [x, y, z] in 3D
    delta_rel = {from = 1e-6, to = 1e-1, count = 6, spacing = "log"}   # or delta_law
    fields = true                     # keep per-point fields (error maps, VTK)
    tables = ["method-angle"]         # what to produce from this sweep
    figures = ["error-vs-angle"]

3D sweeps (dim = 3, studies.problems.boxes) take the box problems and
the methods that support 3D ("all" means those), tilt as an axis like angle, three offset components,
and `orientation = [[angle, tilt], ...]`: pairs swept together instead of the product of the two
axes. Their report goes into the page's "Three dimensions" section (studies.report.page).

A sweep is the product of its axes, per problem and per method; a method parameter axis
applies only to the methods that declare it. Every key, type and value is checked here
(and each expanded case by studies.run.case.validate): a bad one raises InputError with one
line naming the key and what is allowed.

The collapse problems (Problem.collapse: studies.problems.collapse, studies.problems.footing) have no
exact field and no err_* columns: a sweep of them takes only them, the table "collapse" and the
figures of COLLAPSE_FIGURES that each declares, and is never part of problems = "all". Their locking axis applies to the grid
methods; fem's cases take locking = "none" (its P2 triangles do not lock).
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib
import json
import math
import pkgutil
import re
import sys
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

import baselines
from baselines.registry import BUILT_IN, METHODS, in_3d
from ibm.exceptions import InputError
from studies.problems.library import closest
from studies.problems.problem_file import file_digest, load_problem_file
from studies.problems.registry import PROBLEMS, collapse_names, get as get_problem, names as problem_names
from studies.run.case import CaseSpec, validate
from studies.run.seed import PAPER, SEED_METHOD

TOP_KEYS = ("title", "description", "base", "output", "sweep")
OUTPUT_KEYS = {"vtk": bool}
SWEEP_KEYS = ("name", "summary", "problems", "methods", "random_offsets", "delta_law", "orientation", "fields", "vtk",
              "tables", "figures")
TABLES = {
    "seed": "the seed paper's six numbers beside ours (ibm at 90, 45, 30 degrees)",
    "convergence": "fitted and level-to-level rates against the cell size (needs cell to vary)",
    "method-angle": "errors per method (rows) and angle (columns) (needs angle to vary)",
    "placements": "error statistics over placements per method and angle (needs offset to vary)",
    "cases": "every case of the sweep with its errors",
    "method-orientation": "errors per method (rows) and orientation (angle, tilt) (columns) (3D; needs the "
                          "orientation to vary)",
    "collapse": "the collapse load of every case against its exact value, with locking, steps, Newton iterations "
                "and time (collapse problems)",
}
FIGURES = {   # kind -> the axis that must take at least two values
    "error-vs-h": "cell", "error-vs-delta": "delta_rel", "error-vs-beta0": "beta0", "error-vs-gamma": "gamma",
    "error-vs-angle": "angle", "error-vs-ppc": "ppc", "error-vs-nu": "nu",
    "cond-vs-delta": "delta_rel", "cond-vs-beta0": "beta0", "cond-vs-gamma": "gamma", "cond-vs-h": "cell",
    "error-vs-placement": "offset", "error-maps": None,
    # 3D
    "error-vs-orientation": "orientation", "error-view-3d": None,
    # large kinematics
    "error-vs-step": None, "newton-iterations": None, "error-vs-h-peer": "cell", "stress-profile": None,
    "snapshots": None,
    # collapse problems
    "load-settlement": None, "pressure-expansion": None, "plastic-zones": None, "locking": None,
}
FIELD_FIGURES = ("error-maps", "stress-profile", "snapshots", "plastic-zones",   # need the sweep's fields = true
                 "error-view-3d")
SOLID_KINDS = ("method-orientation", "error-vs-orientation", "error-view-3d")     # tables and figures of 3D sweeps
LARGE_FIGURES = ("error-vs-step", "newton-iterations", "error-vs-h-peer", "stress-profile", "snapshots")
COLLAPSE_TABLES = ("collapse",)
COLLAPSE_FIGURES = ("load-settlement", "pressure-expansion", "plastic-zones", "locking")   # a problem's `figures`
AXIS_ORDER_FIRST = ("problem", "method")
MAX_CASES = 20000
NAME = re.compile(r"^[a-z0-9][a-z0-9-]*$")


def load_registries() -> tuple[dict, dict]:
    """Import every baseline module so its methods register; return (METHODS, the 2D problems a spec
    names: name -> Problem, those with an exact field first; the collapse problems by name only)."""
    for module in pkgutil.iter_modules(baselines.__path__):
        importlib.import_module(f"baselines.{module.name}")
    problems = {name: get_problem(name) for name in problem_names(2)}
    return METHODS, {name: p for name, p in problems.items() if p.in_specs and not p.collapse}


@dataclass(frozen=True)
class Sweep:
    name: str
    summary: str
    cases: tuple[CaseSpec, ...]
    axes: dict            # axis name -> tuple of the distinct values it takes
    fields: bool = False
    vtk: bool = False
    tables: tuple[str, ...] = ()
    figures: tuple[str, ...] = ()


@dataclass(frozen=True)
class Study:
    title: str
    description: str
    base: CaseSpec
    sweeps: tuple[Sweep, ...]
    vtk: bool = False
    text: str = ""                     # the TOML source, copied into the output folder
    source: str = ""

    def cases(self) -> list[CaseSpec]:
        """Every distinct case in sweep order (a case shared by sweeps appears once)."""
        seen, out = set(), []
        for sweep in self.sweeps:
            for case in sweep.cases:
                key = case_id(case)
                if key not in seen:
                    seen.add(key)
                    out.append(case)
        return out

    def ids_with(self, flag: str) -> set[str]:
        """Ids of the cases in sweeps whose `flag` ("fields" or "vtk") is set."""
        return {case_id(c) for s in self.sweeps if getattr(s, flag) for c in s.cases}

    def sweep(self, name: str) -> Sweep:
        return next(s for s in self.sweeps if s.name == name)


# --- case identity ----------------------------------------------------------------------

def case_settings(case: CaseSpec) -> dict:
    """The settings that define a case, JSON-able, with canonical numeric types."""
    settings = dataclasses.asdict(case)
    for name, kind in _case_fields().items():   # 30 and 30.0 are the same angle
        if kind == "float" and _is_number(settings[name]):
            settings[name] = float(settings[name])
    settings["offset"] = [float(o) for o in case.offset]
    settings["method_parameters"] = {k: _canonical_parameter(k, v) for k, v in sorted(case.method_parameters.items())}
    for name, default in (("locking", "none"), ("footing", "smooth"), ("solver", "auto"), ("band", "auto")):
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


def case_id(case: CaseSpec) -> str:
    """A short hash of the case's settings and of the code that computes it: equal settings,
    equal id, whatever the spec; a stored result of other code is never reused."""
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


# --- loading ----------------------------------------------------------------------------

def load(path: str | Path) -> Study:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"spec file {str(path)!r} does not exist")
    text = path.read_text()
    return parse(text, source=str(path))


def parse(text: str, source: str = "<spec>") -> Study:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InputError(f"{source}: not valid TOML ({error})") from None
    methods, problems = load_registries()
    _check_keys(data, TOP_KEYS, "top level")
    title = _string(data.get("title", Path(source).stem), "title")
    description = _string(data.get("description", ""), "description")
    output = data.get("output", {})
    _check_table(output, "output")
    _check_keys(output, tuple(OUTPUT_KEYS), "[output]")
    vtk = _boolean(output.get("vtk", False), "output.vtk")

    base_data = data.get("base", {})
    _check_table(base_data, "base")
    fields = _case_fields()
    parameters = _method_parameters(methods)
    _check_keys(base_data, tuple(fields) + tuple(parameters), "[base]")
    base_values = {}
    for key, value in base_data.items():
        kind = fields.get(key) or parameters[key]
        base_values[key] = _scalar(value, kind, f"base.{key}")
    base_parameters = {k: base_values.pop(k) for k in list(base_values) if k in parameters}
    folder = Path(source).resolve().parent if source != "<spec>" else Path.cwd()
    if base_values.get("problem_file"):
        base_values["problem_file"] = _beside(folder, base_values["problem_file"])
    base = CaseSpec(**base_values)

    sweeps_data = data.get("sweep", [])
    if not isinstance(sweeps_data, list) or not sweeps_data:
        raise InputError("sweep: a spec needs at least one [[sweep]] table")
    sweeps, names = [], set()
    for index, sweep_data in enumerate(sweeps_data):
        sweep = _sweep(sweep_data, index, base, base_parameters, fields, parameters, methods, problems, folder,
                       load_type_given="load_type" in base_values)
        if sweep.name in names:
            raise InputError(f"sweep.name {sweep.name!r} is used twice; sweep names must be unique")
        names.add(sweep.name)
        sweeps.append(sweep)
    total = len({case_id(c) for s in sweeps for c in s.cases})
    if total > MAX_CASES:
        raise InputError(f"the spec expands to {total} cases; at most {MAX_CASES} are allowed")
    return Study(title, description, base, tuple(sweeps), vtk, text, source)


def _beside(folder: Path, path: str) -> str:
    """A problem file named relative to the spec's folder, as an absolute path."""
    return str(Path(path) if Path(path).is_absolute() else folder / path)


def _sweep(data, index, base, base_parameters, fields, parameters, methods, problems, folder: Path,
           load_type_given: bool = False) -> Sweep:
    where = f"sweep[{index}]"
    _check_table(data, where)
    axes_allowed = tuple(k for k in fields if k not in ("problem", "method")) + tuple(parameters)
    _check_keys(data, SWEEP_KEYS + axes_allowed, where)
    name = _string(data.get("name", ""), f"{where}.name")
    if not NAME.match(name):
        raise InputError(f"{where}.name {name!r} is not allowed; use lower-case letters, digits and '-'")
    where = f"sweep {name!r}"
    summary = _string(data.get("summary", ""), f"{where}: summary")
    dims = _axis(data["dim"], "int", f"{where}: dim") if "dim" in data else [base.dim]
    solid = set(dims) == {3}                        # "all" means what 3D has
    chosen_problems = _names(data.get("problems", [base.problem]), problems, f"{where}: problems",
                             also=tuple(collapse_names()), every=problem_names(3) if solid else None)
    mixed = [p for p in chosen_problems if p in collapse_names()]
    if mixed and len(mixed) < len(chosen_problems):
        raise InputError(f"{where}: the collapse problems ({', '.join(mixed)}) have no exact field; give them a sweep "
                         f"of their own, without {', '.join(p for p in chosen_problems if p not in mixed)}")
    chosen_methods = _names(data.get("methods", [base.method]), methods, f"{where}: methods",
                            every=in_3d() if solid else None)

    axes: dict[str, list] = {}
    for key in axes_allowed:
        if key in data:
            axes[key] = _axis(data[key], fields.get(key) or parameters[key], f"{where}: {key}")
    if "problem_file" in axes:
        axes["problem_file"] = [_beside(folder, path) if path else path for path in axes["problem_file"]]
    if "random_offsets" in data:
        if "offset" in data:
            raise InputError(f"{where}: give either offset or random_offsets, not both")
        if len(set(dims)) > 1:
            raise InputError(f"{where}: random_offsets needs one dim per sweep (2 or 3 components), got dim {dims}")
        axes["offset"] = _random_offsets(data["random_offsets"], f"{where}: random_offsets", dims[0])
    if "orientation" in data:
        if "angle" in data or "tilt" in data:
            raise InputError(f"{where}: give either orientation or angle and tilt, not both")
        axes["orientation"] = _orientations(data["orientation"], f"{where}: orientation")
    law = None
    if "delta_law" in data:
        if "delta_rel" in data:
            raise InputError(f"{where}: give either delta_rel or delta_law, not both")
        law = _delta_law(data["delta_law"], f"{where}: delta_law")

    used_parameters = {p for m in chosen_methods for p in methods[m].names}
    for key in axes:
        if key in parameters and key not in used_parameters:
            owners = ", ".join(f"{m}: {', '.join(methods[m].names) or 'none'}" for m in chosen_methods)
            raise InputError(f"{where}: {key} is not a parameter of any method in this sweep ({owners})")
    if law is not None and "delta_rel" not in used_parameters:
        raise InputError(f"{where}: delta_law needs a method with parameter delta_rel")

    cases = []
    spec_axes = [k for k in axes if k in fields or k == "orientation"]
    for problem in chosen_problems:
        for method in chosen_methods:
            own = [k for k in axes if k in parameters and k in methods[method].names]
            names_ = spec_axes + own
            for combo in _product([axes[k] for k in names_]):
                values = dict(zip(names_, combo))
                if "orientation" in values:         # angle and tilt swept together
                    values["angle"], values["tilt"] = values.pop("orientation")
                settings = {k: v for k, v in values.items() if k in fields}
                # large kinematics: the load steps' own defaults
                defaults = methods[method].defaults(settings.get("kinematics", base.kinematics) == "large")
                method_parameters = {k: base_parameters.get(k, default) for k, default in defaults.items()}
                method_parameters.update({k: v for k, v in values.items() if k in parameters})
                case = dataclasses.replace(base, problem=problem, method=method, **settings,
                                           method_parameters=method_parameters)
                if "load_type" not in settings and not load_type_given:
                    known = PROBLEMS.get((problem, case.dim))       # an unknown one is named by validate below
                    if known is not None:
                        case = dataclasses.replace(case, load_type=known.default_load_type())
                if case.problem_file:   # a user's problem goes by the name its file gives
                    try:
                        case = dataclasses.replace(case, problem=load_problem_file(case.problem_file).name)
                    except InputError as error:
                        raise InputError(f"{where}: {error}") from None
                if law is not None and "delta_rel" in method_parameters:
                    case.method_parameters["delta_rel"] = law(case.cell)
                if problem in collapse_names() and methods[method].supports.body_fitted:   # locking: grid methods
                    case = dataclasses.replace(case, locking="none")
                if not methods[method].supports.band_kinematics:   # the band's: the other methods' cases are one
                    case = dataclasses.replace(case, band="auto")
                try:
                    validate(case)
                except InputError as error:
                    raise InputError(f"{where}: {error}") from None
                cases.append(case)
    cases = list({case_id(c): c for c in cases}.values())        # fem's cases of a locking axis are one
    distinct = {}
    for key in ("problem", "method") + tuple(axes):   # a delta law ties delta to h: not an axis of its own
        distinct[key] = _distinct(_axis_value(c, key) for c in cases)

    tables = tuple(_choices(data.get("tables", []), TABLES, f"{where}: tables"))
    figures = tuple(_choices(data.get("figures", []), FIGURES, f"{where}: figures"))
    fields_wanted = _boolean(data.get("fields", False), f"{where}: fields")
    vtk = _boolean(data.get("vtk", False), f"{where}: vtk")
    _check_collapse(chosen_problems, cases, tables, figures, where)
    _check_solid(cases, tables, figures, vtk, where)
    needs = {"convergence": "cell", "method-angle": "angle", "placements": "offset",
             "method-orientation": "orientation"}
    taken = {**distinct, "orientation": _distinct((c.angle, c.tilt) for c in cases)}   # from either key
    for kind in list(figures) + list(tables):
        axis = FIGURES.get(kind) if kind in figures else needs.get(kind)
        if axis is not None and len(taken.get(axis, ())) < 2:
            named = "orientation (angle, tilt)" if axis == "orientation" else axis
            raise InputError(f"{where}: {kind} needs {named} to take at least two values in this sweep")
    for kind in FIELD_FIGURES:
        if kind in figures and not fields_wanted:
            raise InputError(f"{where}: figure {kind} needs fields = true")
    small = [c for c in cases if c.kinematics != "large"]
    for kind in LARGE_FIGURES:
        if kind in figures and small:
            raise InputError(f"{where}: figure {kind} needs kinematics = \"large\" in every case of the sweep")
    if "error-maps" in figures and len(small) < len(cases):
        raise InputError(f"{where}: figure error-maps is drawn for small kinematics only (use snapshots)")
    if vtk and not fields_wanted:
        raise InputError(f"{where}: vtk = true needs fields = true")
    if "seed" in tables:
        angles = {c.angle for c in cases if c.method == SEED_METHOD}
        if not set(PAPER) <= angles:
            raise InputError(f"{where}: table seed needs method {SEED_METHOD} at angles {sorted(PAPER)}")
    return Sweep(name, summary, tuple(cases), distinct, fields_wanted, vtk, tables, figures)


def _check_solid(cases: list[CaseSpec], tables: tuple, figures: tuple, vtk: bool, where: str) -> None:
    """3D sweeps take the 3D tables and figures and no 2D-only ones; 2D sweeps none of the 3D ones."""
    solid = [c for c in cases if c.dim == 3]
    kinds = [("table", kind) for kind in tables] + [("figure", kind) for kind in figures]
    for what, kind in kinds:
        if kind in SOLID_KINDS and len(solid) < len(cases):
            raise InputError(f"{where}: {what} {kind} needs dim = 3 in every case of the sweep")
    if not solid:
        return
    for what, kind in kinds:
        if kind in ("error-maps", "seed"):
            instead = "error-view-3d" if kind == "error-maps" else "method-orientation"
            raise InputError(f"{where}: {what} {kind} is for 2D sweeps only; a 3D sweep takes {instead}")
    if vtk:
        raise InputError(f"{where}: vtk = true is not available with dim = 3 yet; "
                         f"`ibm-study solve --dim 3 --vtk DIR` writes a 3D case's files")


def _check_collapse(problems: list[str], cases: list[CaseSpec], tables: tuple, figures: tuple, where: str) -> None:
    """A sweep of collapse problems takes the collapse table and figures only; other sweeps none of them."""
    chosen = [p for p in problems if p in collapse_names()]
    kinds = [("table", kind) for kind in tables] + [("figure", kind) for kind in figures]
    if not chosen:
        for what, kind in kinds:
            if kind in COLLAPSE_TABLES or kind in COLLAPSE_FIGURES:
                raise InputError(f"{where}: {what} {kind} is for the collapse problems "
                                 f"({', '.join(collapse_names())}); this sweep has {', '.join(problems)}")
        return
    for what, kind in kinds:
        if kind not in COLLAPSE_TABLES and kind not in COLLAPSE_FIGURES:
            raise InputError(f"{where}: {what} {kind} needs errors against an exact field, and {' and '.join(chosen)} "
                             f"{'has' if len(chosen) == 1 else 'have'} none; a collapse sweep takes the table "
                             f"{', '.join(COLLAPSE_TABLES)} and the figures {', '.join(COLLAPSE_FIGURES)}")
        drawn_by = [p for p in collapse_names() if kind in get_problem(p).figures]
        if kind in COLLAPSE_FIGURES and not set(drawn_by) & set(chosen):
            raise InputError(f"{where}: figure {kind} needs problem {' or '.join(map(repr, drawn_by))} in the sweep")
    if "locking" in figures and not locking_pairs(cases):
        raise InputError(f"{where}: figure locking needs a grid-method case with both locking = \"none\" and "
                         f"\"fbar\" (give locking = [\"none\", \"fbar\"])")


def locking_pairs(cases) -> list[tuple[CaseSpec, CaseSpec]]:
    """(locked, remedied): the cases of a sweep that differ only in locking, none and fbar."""
    remedied = {case_id(dataclasses.replace(c, locking="none")): c for c in cases if c.locking == "fbar"}
    return [(c, remedied[case_id(c)]) for c in cases if c.locking == "none" and case_id(c) in remedied]


def _axis_value(case: CaseSpec, key: str):
    if key in ("problem", "method"):
        return getattr(case, key)
    if key == "offset":
        return tuple(case.offset)
    if key == "orientation":
        return (case.angle, case.tilt)
    if hasattr(case, key) and key != "method_parameters":
        return getattr(case, key)
    return case.method_parameters.get(key)


def _distinct(values) -> tuple:
    out = []
    for v in values:
        if v is not None and v not in out:
            out.append(v)
    return tuple(out)


def _product(lists):
    if not lists:
        yield ()
        return
    for head in lists[0]:
        for rest in _product(lists[1:]):
            yield (head,) + rest


# --- kinds and checks ---------------------------------------------------------------------

def _case_fields() -> dict[str, str]:
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
        elif isinstance(default, float):
            out[f.name] = "float"
        elif isinstance(default, str):
            out[f.name] = "str"
        elif isinstance(default, tuple) and len(default) == 2:
            out[f.name] = "point"           # two numbers in 2D, three in 3D
        else:
            out[f.name] = "any"
    return out


def _method_parameters(methods) -> dict[str, str]:
    out = {}
    for method in methods.values():
        for key, default in method.defaults().items():
            kind = "str" if isinstance(default, str) else ("int" if isinstance(default, int)
                                                           and not isinstance(default, bool) else "float")
            out.setdefault(key, kind)
    return out


def _check_table(value, where: str) -> None:
    if not isinstance(value, dict):
        raise InputError(f"{where} must be a table, got {type(value).__name__}")


def _check_keys(data: dict, allowed: tuple, where: str) -> None:
    for key in data:
        if key not in allowed:
            raise InputError(f"{where}: unknown key {key!r}{closest(key, allowed)}; allowed: {', '.join(allowed)}")


def _string(value, where: str) -> str:
    if not isinstance(value, str):
        raise InputError(f"{where} must be a string, got {value!r}")
    return value


def _boolean(value, where: str) -> bool:
    if not isinstance(value, bool):
        raise InputError(f"{where} must be true or false, got {value!r}")
    return value


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where} must be a finite number, got {value!r}")
    return float(value)


def _scalar(value, kind: str, where: str):
    if kind == "float":
        return _number(value, where)
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(f"{where} must be an integer, got {value!r}")
        return value
    if kind == "str":
        return _string(value, where)
    if kind == "bool":
        return _boolean(value, where)
    if kind == "point":
        if not isinstance(value, list) or len(value) not in (2, 3):
            raise InputError(f"{where} must be a pair of numbers [x, y] (three, [x, y, z], in 3D), got {value!r}")
        return tuple(_number(v, where) for v in value)
    return value


def _axis(value, kind: str, where: str) -> list:
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
        v = _scalar(item, kind, where)
        if v not in out:
            out.append(v)
    return out


def _range(data: dict, where: str) -> list[float]:
    allowed = ("from", "to", "step", "count", "spacing")
    _check_keys(data, allowed, where)
    for key in ("from", "to"):
        if key not in data:
            raise InputError(f"{where}: a range needs 'from' and 'to' (and 'step' or 'count')")
    start, stop = _number(data["from"], f"{where}.from"), _number(data["to"], f"{where}.to")
    spacing = _string(data.get("spacing", "linear"), f"{where}.spacing")
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


def _random_offsets(data, where: str, dim: int = 2) -> list[tuple[float, ...]]:
    _check_table(data, where)
    _check_keys(data, ("count", "seed"), where)
    count, seed = data.get("count"), data.get("seed", 0)
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 1000:
        raise InputError(f"{where}.count {count!r} is not allowed; it must be an integer from 1 to 1000")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"{where}.seed {seed!r} is not allowed; it must be an integer >= 0")
    draws = np.random.default_rng(seed).random((count, 3 if dim == 3 else 2))
    return [tuple(round(float(v), 6) % 1.0 for v in draw) for draw in draws]


def _orientations(value, where: str) -> list[tuple[float, float]]:
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


def _delta_law(data, where: str):
    """delta = coefficient * h^power, i.e. delta_rel = coefficient * h^(power - 1)."""
    _check_table(data, where)
    _check_keys(data, ("coefficient", "power"), where)
    if "coefficient" not in data:
        raise InputError(f"{where}: needs 'coefficient' (delta = coefficient * h^power)")
    coefficient = _number(data["coefficient"], f"{where}.coefficient")
    power = _number(data.get("power", 1.0), f"{where}.power")
    if coefficient <= 0:
        raise InputError(f"{where}.coefficient {coefficient:g} is not allowed; it must be > 0")
    if not 0 <= power <= 4:
        raise InputError(f"{where}.power {power:g} is not allowed; it must be in [0, 4]")
    return lambda h: float(f"{coefficient * h ** (power - 1.0):.12g}")


def _names(value, registry: dict, where: str, also: tuple[str, ...] = (), every: list | None = None) -> list[str]:
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


def _choices(value, allowed: dict, where: str) -> list[str]:
    if not isinstance(value, list):
        raise InputError(f"{where} must be a list of names, got {value!r}")
    for item in value:
        if not isinstance(item, str) or item not in allowed:
            hint = closest(item, allowed) if isinstance(item, str) else ""
            raise InputError(f"{where}: unknown {item!r}{hint}; allowed: {', '.join(allowed)}")
    return list(dict.fromkeys(value))
