"""One small-strain case: a placed problem -> model -> method -> error norms vs exact, as one flat record.

The exact field is the problem's; a problem file without one is measured against a refined
body-fitted reference (studies.run.reference). Error norms at the points (ibm.norms.point_errors) and
by quadrature over the body (ibm.norms.norm_errors); a multiplier method's recovered tractions and
every method's reactions beside the exact ones (studies.run.reactions).
"""
from __future__ import annotations

from time import perf_counter

import numpy as np

from baselines.registry import METHODS
from ibm.norms import norm_errors, point_errors
from ibm.small.model import build_model
from ibm.solvers import backends as solvers
from studies.run.reactions import reaction_error, reaction_records
from studies.run.reference import fem_reference


def run_small_case(spec, instance, keep_fields: bool = False, solver: str = "auto") -> dict:
    """Solve the placed `instance` of `spec` (studies.problems.library.Placed) by the spec's method with the
    linear solver `solver`; the record (settings, sizes, error norms, diagnostics, time_s), with its
    arrays under "fields" when keep_fields."""
    start = perf_counter()
    model = build_model(instance.body, instance.parameters.material, instance.loads, spec.cell, spec.ppc)
    method = METHODS[spec.method]
    with solvers.choice(solver):
        solution = method(model, **spec.method_parameters)
    exact, reference = instance.exact, {"reference": "exact"}
    if exact is None:   # a problem file without an exact field: a refined fem reference
        found = fem_reference(model.body, model.material, model.loads, spec.cell, lambda candidate: norm_errors(
            model.body, model.grid, model.material, solution.evaluate, candidate, delta=solution.info.get("delta")))
        exact, reference = found.evaluate, found.summary()
    u, sigma, zz = exact(model.points.x)
    errors = point_errors(model.points.volume, solution.u, u, solution.sigma, sigma,
                          solution.sigma_zz, zz, instance.direction)
    errors.update(norm_errors(model.body, model.grid, model.material, solution.evaluate, exact,
                              delta=solution.info.get("delta")))
    if solution.tractions is not None:
        errors["err_traction"] = traction_error(solution.tractions, instance.body, exact)
    forces = reaction_records(model, solution, spec.method, exact if reference["reference"] == "exact" else None)
    if forces and "exact" in forces[0]:
        errors["err_reaction"] = reaction_error(forces)
    used = method.used(spec.method_parameters)
    material = instance.parameters.material
    record = {
        "problem": instance.problem.name if spec.problem_file else spec.problem,
        **({"problem_file": spec.problem_file} if spec.problem_file else {}),
        "method": spec.method, "angle": spec.angle, "cell": spec.cell,
        "ppc": spec.ppc, "offset": list(spec.offset), "E": material.E, "nu": material.nu, "load": spec.load,
        "load_type": spec.load_type, "width": spec.width, "height": spec.height, "kinematics": spec.kinematics,
        "delta_rel": used.get("delta_rel"), **used,
        "ndof": int(solution.info["ndof"]), "npoints": len(model.points),
        **errors, **reference,
        **{k: v for k, v in solution.info.items() if k != "ndof" and np.isscalar(v)},
        "reactions": forces,
        "time_s": perf_counter() - start,
    }
    if keep_fields:
        record["fields"] = {"model": model, "instance": instance, "solution": solution,
                            "exact": (u, sigma, zz)}
    return record


def traction_error(tractions, body, exact) -> float:
    """Relative error of a method's recovered boundary traction sigma n against the exact one
    (exact(x) -> u, sigma, ...), sqrt(sum w |t_h - t|^2 / sum w |t|^2) over its points (multiplier methods)."""
    _, sigma, _ = exact(tractions.x)
    outward = np.zeros_like(tractions.x)                 # per point: an arc's normal turns
    for k in np.unique(tractions.edge):
        mine = tractions.edge == k
        outward[mine] = body.outward(int(k), tractions.x[mine])
    exact = np.einsum("pij,pj->pi", sigma, outward)
    error = np.sum(tractions.weight * np.sum((tractions.value - exact) ** 2, axis=1))
    return float(np.sqrt(error / np.sum(tractions.weight * np.sum(exact ** 2, axis=1))))
