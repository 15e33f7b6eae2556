"""A 3D case of a study: a CaseSpec with dim = 3, checked, solved by studies.run.solid.solve_box_case,
returned as a flat record like a 2D case's and, on request, with its per-point fields.

What a 3D case takes from CaseSpec: problem (studies.problems.boxes.BOXES), method (a method supporting "3d"),
angle, tilt, offset (three components), cell, ppc, E, nu, load, width (also the depth) and height,
solver, and the method's parameters. The rest must keep its default (small kinematics, elastic,
pressure on top, no problem file, no locking).

Fields (keep_fields) are studies.run.solid.point_fields, the arrays its VTK files hold.
"""
from __future__ import annotations

from ibm.exceptions import InputError

# settings a 3D case cannot change yet: name -> (its only value, why)
FIXED = {"kinematics": ("small", "3D cases are one linear step"),
         "material": ("elastic", "3D cases are linear elastic"),
         "load_type": ("pressure", "the 3D boxes are loaded by their own tractions and body forces"),
         "problem_file": ("", "problem files are 2D outlines"),
         "locking": ("none", "3D cases are elastic"),
         "steps": (1, "3D cases are one linear step")}


def validate(spec) -> None:
    """Raise InputError naming the first setting of a 3D case (spec.dim == 3) that 3D does not take."""
    from baselines.registry import METHODS, in_3d, require
    from studies.problems.boxes import BOXES
    from studies.problems.library import closest

    for name, (value, why) in FIXED.items():
        if getattr(spec, name) != value:
            allowed = f"; allowed: {value!r}" if value != "" else ""
            raise InputError(f"{name.replace('_', ' ')} {getattr(spec, name)!r} is not available with dim = 3 "
                             f"({why}){allowed}")
    if spec.problem not in BOXES:
        raise InputError(f"problem {spec.problem!r} is not available with dim = 3{closest(spec.problem, BOXES)}; "
                         f"allowed: {', '.join(BOXES)}")
    if spec.method not in METHODS:
        raise InputError(f"unknown method {spec.method!r}{closest(spec.method, METHODS)}; allowed with dim = 3: "
                         f"{', '.join(in_3d())}")
    require(spec.method, "3d")


def run_box_case(spec, keep_fields: bool = False, solver: str = "auto") -> dict:
    """Solve the 3D case `spec`; its record (settings, sizes, errors, times), with its per-point arrays
    under "fields" when keep_fields. solver: the backend when the spec leaves it at "auto"."""
    from baselines.registry import METHODS
    from studies.run.solid import solve_box_case

    method = METHODS[spec.method]
    parameters = {k: v for k, v in spec.method_parameters.items() if k in method.names}
    record = solve_box_case(spec.problem, spec.method, spec.angle, spec.tilt, spec.offset, spec.cell, spec.ppc,
                            spec.E, spec.nu, spec.load, (spec.width, spec.height, spec.width),
                            solver=spec.solver if spec.solver != "auto" else solver, keep_fields=keep_fields,
                            **parameters)
    fields = record.pop("fields", None)
    used = method.used(spec.method_parameters)
    record["npoints"] = record.pop("n_points")          # the 2D records' name, one column in the store
    record.pop("offset")
    record.update({"E": spec.E, "nu": spec.nu, "load": spec.load, "load_type": spec.load_type, "width": spec.width,
                   "height": spec.height, "kinematics": spec.kinematics, "delta_rel": used.get("delta_rel"), **used,
                   "reference": "exact"})
    if fields is not None:
        record["fields"] = fields
    return record
