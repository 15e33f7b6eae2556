"""The 3D boxes (studies.problems.box_fields) as problems of a study: a CaseSpec with dim = 3.

A 3D case takes from CaseSpec: problem, method (one supporting "3d"; at large kinematics
"load-steps-3d"), angle, tilt, offset (three components), cell, ppc, E, nu, load, width (also the
depth) and height, solver, and the method's parameters; at large kinematics (the boxes with an
exact finite-strain solution) also steps, basis, band and locking. The rest keeps its default.
Small kinematics solves the placed box once (studies.run.solid.solve_box_case), large kinematics
runs the load steps (studies.run.solid.run_box_large). Fields (keep_fields) are
studies.run.solid.point_fields, the arrays its VTK files hold.
"""
from __future__ import annotations

from baselines.registry import METHODS, in_3d, in_load_steps, require
from ibm.exceptions import InputError
from studies.problems.box_fields import BOXES, FINITE_STRAIN
from studies.problems.library import closest
from studies.problems.problem import Problem
from studies.run.solid import run_box_large, solve_box_case

# settings a 3D case cannot change (yet): name -> (its only value, why); at large kinematics the
# load steps' own (steps, locking) are free
FIXED = {"kinematics": ("small", "3D cases are one linear step"),
         "material": ("elastic", "3D cases are linear elastic"),
         "load_type": ("pressure", "the 3D boxes are loaded by their own tractions and body forces"),
         "problem_file": ("", "problem files are 2D outlines"),
         "locking": ("none", "3D cases are elastic"),
         "steps": (1, "3D cases are one linear step")}
FREE_AT_LARGE = ("kinematics", "locking", "steps")


class BoxProblem(Problem):
    """A box of studies.problems.box_fields.BOXES in 3D."""

    dims = (3,)

    def __init__(self, name: str):
        self.name = name
        self.summary = BOXES[name][2]
        self.large = name in FINITE_STRAIN

    def area(self, spec) -> float:
        return spec.width * spec.height * spec.width       # a volume: the points' estimate is per cell

    def steps_allowed(self, spec) -> bool:
        return spec.kinematics == "large"

    def checkpoint_refusal(self, spec) -> str:
        if spec.kinematics != "large":
            return "--checkpoint is for load steps (--kinematics large); a 3D small-strain case is one linear solve"
        return super().checkpoint_refusal(spec)

    def locking_applies(self, spec) -> bool:
        return spec.kinematics == "large"        # F-bar in the load steps (the 3D column's volumetric locking)

    def fields_refusal(self, spec) -> str:
        return "--vtk is not available with --dim 3 --kinematics large yet" if spec.kinematics == "large" else ""

    def validate(self, spec) -> None:
        large = spec.kinematics == "large"
        if spec.kinematics not in ("small", "large"):
            raise InputError(f"kinematics {spec.kinematics!r} is not allowed; allowed: small, large")
        if large and not self.large:
            allowed = ", ".join(FINITE_STRAIN)
            raise InputError(f"problem {self.name!r} has no exact finite-strain solution in 3D (dim = 3): kinematics "
                             f"'large' is not available for it; allowed: 'small' ('large' for {allowed})")
        for name, (value, why) in FIXED.items():
            if getattr(spec, name) != value and not (large and name in FREE_AT_LARGE):
                allowed = f"; allowed: {value!r}" if value != "" else ""
                raise InputError(f"{name.replace('_', ' ')} {getattr(spec, name)!r} is not available with dim = 3 "
                                 f"({why}){allowed}")
        if spec.method not in METHODS:
            raise InputError(f"unknown method {spec.method!r}{closest(spec.method, METHODS)}; allowed with dim = 3: "
                             f"{', '.join(in_load_steps(3) if large else in_3d())}")
        require(spec.method, "load-steps-3d" if large else "3d")
        if large and not spec.load > 0:
            raise InputError(f"load {spec.load} is not allowed for large kinematics; it must be > 0 (compressive)")

    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        method = METHODS[spec.method]
        size = (spec.width, spec.height, spec.width)
        parameters = {k: v for k, v in spec.method_parameters.items() if k in method.names}
        if spec.kinematics == "large":
            return run_box_large(spec.problem, spec.method, spec.angle, spec.tilt, spec.offset, spec.cell, spec.ppc,
                                 spec.steps, spec.E, spec.nu, spec.load, size, solver=solver, band=spec.band,
                                 basis=spec.basis, locking=spec.locking, checkpoint=checkpoint, **parameters)
        record = solve_box_case(spec.problem, spec.method, spec.angle, spec.tilt, spec.offset, spec.cell, spec.ppc,
                                spec.E, spec.nu, spec.load, size, solver=solver, keep_fields=keep_fields,
                                **parameters)
        fields = record.pop("fields", None)
        used = method.used(spec.method_parameters)
        record["npoints"] = record.pop("n_points")          # the 2D records' name, one column in the store
        record.pop("offset")
        record.update({"E": spec.E, "nu": spec.nu, "load": spec.load, "load_type": spec.load_type,
                       "width": spec.width, "height": spec.height, "kinematics": spec.kinematics,
                       "delta_rel": used.get("delta_rel"), **used, "reference": "exact"})
        if fields is not None:
            record["fields"] = fields
        return record


PROBLEMS = tuple(BoxProblem(name) for name in BOXES)
