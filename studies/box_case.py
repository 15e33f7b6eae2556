"""A 3D case of a study: a CaseSpec with dim = 3, checked, solved by studies.solid.solve_box_case,
returned as a flat record like a 2D case's and, on request, with its per-point fields.

What a 3D case takes from CaseSpec: problem (studies.boxes.BOXES), method (studies.solid.METHODS_3D),
angle, tilt, offset (three components), cell, ppc, E, nu, load, width (also the depth) and height,
solver, and the method parameters solve_box_case forwards (PARAMETERS). The rest must keep its
default (small kinematics, elastic, pressure on top, no problem file, no locking).

Fields (keep_fields) are the arrays of the case's VTK files, which solve_box_case writes and this
module reads back (so the study's fields are what ParaView shows):
    x (n, 3), volume (n,), u_h, u (n, 3), sigma_h, sigma (n, 3, 3),
    err_u, err_sigma (n,)     |u_h - u| / max|u| and |s_h - s| / max|s| of the loaded-direction stress
    faces (6, 4, 3), kinds (6,)   the box's faces (corners in order) and their boundary kinds
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from ibm.geometry import InputError

# method parameter -> the keyword of solve_box_case that carries it
PARAMETERS = {"delta_rel": "delta_rel", "support_threshold": "support_threshold", "beta0": "beta0",
              "gamma": "gamma"}
# settings a 3D case cannot change yet: name -> (its only value, why)
FIXED = {"kinematics": ("small", "3D cases are one linear step"),
         "material": ("elastic", "3D cases are linear elastic"),
         "load_type": ("pressure", "the 3D boxes are loaded by their own tractions and body forces"),
         "problem_file": ("", "problem files are 2D outlines"),
         "locking": ("none", "3D cases are elastic"),
         "steps": (1, "3D cases are one linear step")}


def validate(spec) -> None:
    """Raise InputError naming the first setting of a 3D case (spec.dim == 3) that 3D does not take."""
    from baselines.registry import METHODS
    from studies.boxes import BOXES
    from studies.problems import closest
    from studies.solid import METHODS_3D

    for name, (value, why) in FIXED.items():
        if getattr(spec, name) != value:
            allowed = f"; allowed: {value!r}" if value != "" else ""
            raise InputError(f"{name.replace('_', ' ')} {getattr(spec, name)!r} is not available with dim = 3 "
                             f"({why}){allowed}")
    if spec.problem not in BOXES:
        raise InputError(f"problem {spec.problem!r} is not available with dim = 3{closest(spec.problem, BOXES)}; "
                         f"allowed: {', '.join(BOXES)}")
    if spec.method not in METHODS_3D:
        raise InputError(f"method {spec.method!r} is not available with dim = 3 yet{closest(spec.method, METHODS_3D)}; "
                         f"allowed: {', '.join(METHODS_3D)}")
    defaults = METHODS[spec.method].parameters
    for key, value in spec.method_parameters.items():
        if key not in PARAMETERS and key in defaults and value not in (None, defaults[key]):
            raise InputError(f"{key.replace('_', '-')} {value} is not available with dim = 3 yet (method "
                             f"{spec.method!r} uses {defaults[key]:g}); 3D takes "
                             f"{', '.join(k.replace('_', '-') for k in PARAMETERS)}")


def run_box_case(spec, keep_fields: bool = False, solver: str = "auto") -> dict:
    """Solve the 3D case `spec`; its record (settings, sizes, errors, times), with its per-point arrays
    under "fields" when keep_fields. solver: the backend when the spec leaves it at "auto"."""
    from baselines.registry import METHODS
    from studies.solid import solve_box_case

    parameters = {PARAMETERS[k]: v for k, v in spec.method_parameters.items() if k in PARAMETERS}
    with tempfile.TemporaryDirectory(prefix="ibm-box-") as folder:
        record = solve_box_case(spec.problem, spec.method, spec.angle, spec.tilt, spec.offset, spec.cell, spec.ppc,
                                spec.E, spec.nu, spec.load, (spec.width, spec.height, spec.width),
                                vtk=folder if keep_fields else None,
                                solver=spec.solver if spec.solver != "auto" else solver, **parameters)
        fields = read_fields(record.pop("vtk")) if keep_fields else None
    used = {k: spec.method_parameters.get(k) or v for k, v in METHODS[spec.method].parameters.items()}
    record["npoints"] = record.pop("n_points")          # the 2D records' name, one column in the store
    record.pop("offset")
    record.update({"E": spec.E, "nu": spec.nu, "load": spec.load, "load_type": spec.load_type, "width": spec.width,
                   "height": spec.height, "kinematics": spec.kinematics, "delta_rel": used.get("delta_rel"), **used,
                   "reference": "exact"})
    if fields is not None:
        record["fields"] = fields
    return record


def read_fields(paths: list[str]) -> dict[str, np.ndarray]:
    """The per-point arrays and the faces of a 3D case from the VTK files of studies.solid.write_vtk."""
    import meshio

    from studies.vtk import EDGE_KIND_CODES

    files = {Path(p).stem.rsplit("_", 1)[1]: p for p in paths}          # STEM_points.vtu -> "points"
    points, body = meshio.read(files["points"]), meshio.read(files["body"])
    data = points.point_data
    n = len(points.points)
    names = {code: kind for kind, code in EDGE_KIND_CODES.items()}
    quads = body.cells_dict["quad"]
    return {"x": points.points, "volume": data["volume"], "u_h": data["displacement"],
            "u": data["displacement_exact"], "sigma_h": data["stress"].reshape(n, 3, 3),
            "sigma": data["stress_exact"].reshape(n, 3, 3), "err_u": data["err_u"], "err_sigma": data["err_sigma"],
            "faces": body.points[quads], "kinds": np.array([names[int(c)] for c in body.cell_data["face_kind"][0]])}
