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
(the values by studies.run.spec_values, each expanded case by studies.run.case.validate): a bad
one raises InputError with one line naming the key and what is allowed. Case ids:
studies.run.identity.

The collapse problems (Problem.collapse: studies.problems.collapse, studies.problems.footing) have no
exact field and no err_* columns: a sweep of them takes only them, the table "collapse" and the
figures of COLLAPSE_FIGURES that each declares, and is never part of problems = "all". Their locking axis applies to the grid
methods; fem's cases take locking = "none" (its P2 triangles do not lock).
"""
from __future__ import annotations

import dataclasses
import importlib
import pkgutil
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import baselines
from baselines.registry import METHODS, in_3d
from ibm.exceptions import InputError
from studies.problems.problem_file import load_problem_file
from studies.problems.registry import PROBLEMS, collapse_names, get as get_problem, names as problem_names
from studies.report.criteria import BY_NAME as CRITERIA
from studies.run.case import CaseSpec, closest, validate
from studies.run.identity import case_id
from studies.run.seed import PAPER, SEED_METHOD
from studies.run.spec_values import (MAX_CASES, axis_values, boolean, case_fields, check_keys, check_table, choices,
                                     delta_law, given_names, method_parameter_kinds, orientations, random_offsets,
                                     scalar, string)

TOP_KEYS = ("title", "description", "base", "output", "sweep", "verdict")
VERDICT_KEYS = ("sweeps", "problems", "only")
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
    "contact": "every case's contact measures (wall forces, slip, half-width) against their exact values, with "
               "penetration, Newton iterations, step cuts and time (contact problems)",
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
    # contact problems
    "contact-curves": None,
}
FIELD_FIGURES = ("error-maps", "stress-profile", "snapshots", "plastic-zones",   # need the sweep's fields = true
                 "error-view-3d")
SOLID_KINDS = ("method-orientation", "error-vs-orientation", "error-view-3d")     # tables and figures of 3D sweeps
LARGE_FIGURES = ("error-vs-step", "newton-iterations", "error-vs-h-peer", "stress-profile", "snapshots")
COLLAPSE_TABLES = ("collapse",)
CONTACT_TABLES, CONTACT_FIGURES = ("contact",), ("contact-curves",)
COLLAPSE_FIGURES = ("load-settlement", "pressure-expansion", "plastic-zones", "locking")   # a problem's `figures`
AXIS_ORDER_FIRST = ("problem", "method")
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
    verdict: tuple = ()                # Selection per scorecard criterion, in the spec's order

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


def load(path: str | Path) -> Study:
    """The study of the spec file at `path` (TOML); InputError naming the file, the key and the value."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"spec file {str(path)!r} does not exist")
    text = path.read_text()
    return parse(text, source=str(path))


def parse(text: str, source: str = "<spec>") -> Study:
    """The study of a spec's TOML `text` (`source` names it in messages): sweeps expanded into cases."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InputError(f"{source}: not valid TOML ({error})") from None
    methods, problems = load_registries()
    check_keys(data, TOP_KEYS, "top level")
    title = string(data.get("title", Path(source).stem), "title")
    description = string(data.get("description", ""), "description")
    output = data.get("output", {})
    check_table(output, "output")
    check_keys(output, tuple(OUTPUT_KEYS), "[output]")
    vtk = boolean(output.get("vtk", False), "output.vtk")

    base_data = data.get("base", {})
    check_table(base_data, "base")
    fields = case_fields()
    parameters = method_parameter_kinds(methods)
    check_keys(base_data, tuple(fields) + tuple(parameters), "[base]")
    base_values = {}
    for key, value in base_data.items():
        kind = fields.get(key) or parameters[key]
        base_values[key] = scalar(value, kind, f"base.{key}")
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
    verdict = _verdict(data.get("verdict", {}), sweeps)
    return Study(title, description, base, tuple(sweeps), vtk, text, source, verdict)


@dataclass(frozen=True)
class Selection:
    """The sweeps (and, if given, only these problems of them, and only their cases whose settings take the
    values of `only`) that a scorecard criterion reads."""
    criterion: str
    sweeps: tuple[str, ...]
    problems: tuple[str, ...] = ()
    only: tuple = ()                  # (CaseSpec field, allowed values) pairs

    def keeps(self, case: CaseSpec) -> bool:
        return ((not self.problems or case.problem in self.problems)
                and all(getattr(case, name) in values for name, values in self.only))


def _verdict(data, sweeps: list[Sweep]) -> tuple[Selection, ...]:
    """[verdict]: criterion = ["sweep", ...] | "all" | {sweeps = [...] | "all", problems = [...],
    only = {field = value or [values], ...}}."""
    check_table(data, "verdict")
    names, fields = [s.name for s in sweeps], tuple(case_fields())
    out = []
    for criterion, value in data.items():
        where = f"verdict.{criterion}"
        if criterion not in CRITERIA:
            raise InputError(f"verdict: unknown criterion {criterion!r}{closest(criterion, tuple(CRITERIA))}; "
                             f"allowed: {', '.join(CRITERIA)}")
        table = value if isinstance(value, dict) else {"sweeps": value}
        check_keys(table, VERDICT_KEYS, where)
        chosen = table.get("sweeps", "all")
        chosen = names if chosen == "all" else chosen
        if not isinstance(chosen, list) or not chosen or not all(isinstance(n, str) for n in chosen):
            raise InputError(f"{where}: sweeps must be \"all\" or a non-empty list of sweep names, got {chosen!r}")
        for name in chosen:
            if name not in names:
                raise InputError(f"{where}: no sweep is named {name!r}{closest(name, tuple(names))}")
        problems = table.get("problems", [])
        if not isinstance(problems, list) or not all(isinstance(p, str) for p in problems):
            raise InputError(f"{where}: problems must be a list of problem names, got {problems!r}")
        given = {c.problem for s in sweeps if s.name in chosen for c in s.cases}
        for problem in problems:
            if problem not in given:
                raise InputError(f"{where}: no sweep it names runs the problem {problem!r}; they run "
                                 f"{', '.join(sorted(given))}")
        only = table.get("only", {})
        check_table(only, f"{where}.only")
        check_keys(only, fields, f"{where}.only")
        kept = tuple((name, tuple(v if isinstance(v, list) else [v])) for name, v in only.items())
        selection = Selection(criterion, tuple(chosen), tuple(problems), kept)
        if not any(selection.keeps(c) for s in sweeps if s.name in chosen for c in s.cases):
            raise InputError(f"{where}: no case of the sweeps it names is left by its problems and only")
        out.append(selection)
    return tuple(out)


def _beside(folder: Path, path: str) -> str:
    """A problem file named relative to the spec's folder, as an absolute path."""
    return str(Path(path) if Path(path).is_absolute() else folder / path)


def _sweep(data, index, base, base_parameters, fields, parameters, methods, problems, folder: Path,
           load_type_given: bool = False) -> Sweep:
    where = f"sweep[{index}]"
    check_table(data, where)
    axes_allowed = tuple(k for k in fields if k not in ("problem", "method")) + tuple(parameters)
    check_keys(data, SWEEP_KEYS + axes_allowed, where)
    name = string(data.get("name", ""), f"{where}.name")
    if not NAME.match(name):
        raise InputError(f"{where}.name {name!r} is not allowed; use lower-case letters, digits and '-'")
    where = f"sweep {name!r}"
    summary = string(data.get("summary", ""), f"{where}: summary")
    dims = axis_values(data["dim"], "int", f"{where}: dim") if "dim" in data else [base.dim]
    solid = set(dims) == {3}                        # "all" means what 3D has
    # "all": the problems with an exact field that every method runs (a contact problem is named, as it
    # needs a method with contact)
    every = problem_names(3) if solid else [n for n, p in problems.items() if not p.contact]
    chosen_problems = given_names(data.get("problems", [base.problem]), problems, f"{where}: problems",
                                  also=tuple(collapse_names()), every=every)
    mixed = [p for p in chosen_problems if p in collapse_names()]
    if mixed and len(mixed) < len(chosen_problems):
        raise InputError(f"{where}: the collapse problems ({', '.join(mixed)}) have no exact field; give them a sweep "
                         f"of their own, without {', '.join(p for p in chosen_problems if p not in mixed)}")
    chosen_methods = given_names(data.get("methods", [base.method]), methods, f"{where}: methods",
                                 every=in_3d() if solid else None)

    axes: dict[str, list] = {}
    for key in axes_allowed:
        if key in data:
            axes[key] = axis_values(data[key], fields.get(key) or parameters[key], f"{where}: {key}")
    if "problem_file" in axes:
        axes["problem_file"] = [_beside(folder, path) if path else path for path in axes["problem_file"]]
    if "random_offsets" in data:
        if "offset" in data:
            raise InputError(f"{where}: give either offset or random_offsets, not both")
        if len(set(dims)) > 1:
            raise InputError(f"{where}: random_offsets needs one dim per sweep (2 or 3 components), got dim {dims}")
        axes["offset"] = random_offsets(data["random_offsets"], f"{where}: random_offsets", dims[0])
    if "orientation" in data:
        if "angle" in data or "tilt" in data:
            raise InputError(f"{where}: give either orientation or angle and tilt, not both")
        axes["orientation"] = orientations(data["orientation"], f"{where}: orientation")
    law = None
    if "delta_law" in data:
        if "delta_rel" in data:
            raise InputError(f"{where}: give either delta_rel or delta_law, not both")
        law = delta_law(data["delta_law"], f"{where}: delta_law")

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
                # large kinematics and contact (load steps at any kinematics): the load steps' own defaults
                contact = getattr(PROBLEMS.get((problem, settings.get("dim", base.dim))), "contact", False)
                defaults = methods[method].defaults(settings.get("kinematics", base.kinematics) == "large" or contact)
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

    tables = tuple(choices(data.get("tables", []), TABLES, f"{where}: tables"))
    figures = tuple(choices(data.get("figures", []), FIGURES, f"{where}: figures"))
    fields_wanted = boolean(data.get("fields", False), f"{where}: fields")
    vtk = boolean(data.get("vtk", False), f"{where}: vtk")
    _check_collapse(chosen_problems, cases, tables, figures, where)
    _check_contact(chosen_problems, tables, figures, where)
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


def _check_contact(problems: list[str], tables: tuple, figures: tuple, where: str) -> None:
    """The contact table and figure are for sweeps of contact problems only."""
    others = [p for p in problems if not get_problem(p).contact]
    asked = [f"table {kind}" for kind in tables if kind in CONTACT_TABLES] + \
        [f"figure {kind}" for kind in figures if kind in CONTACT_FIGURES]
    if asked and others:
        takers = [name for name in problem_names(2) if get_problem(name).contact]
        raise InputError(f"{where}: {asked[0]} is for the contact problems ({', '.join(takers)}); this sweep has "
                         f"{', '.join(others)}")


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
