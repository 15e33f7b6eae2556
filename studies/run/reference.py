"""A reference solution where no exact one is known: body-fitted fem, refined until it is good enough.

The reference is `fem` (P2 triangles on a gmsh mesh of the outline, baselines.fem.mesh) at
h/2, h/4, ... Its own error is estimated by Richardson extrapolation from the last two
levels: with rates p = 3 (L2) and 2 (energy) for P2, the finer level's error is about
||u_fine - u_coarse|| / (2^p - 1). Refinement stops when both estimates are 10x below the
errors they are compared with (the method's errors against the reference), or at the size
limit; the record says which (`reference_converged`) and states the estimates.
"""
from __future__ import annotations

from dataclasses import dataclass

from baselines.fem.method import solve_fem
from ibm.norms import norm_errors
from ibm.small.model import build_model

RATES = {"err_l2": 3.0, "err_energy": 2.0}
MARGIN = 10.0
MAX_LEVELS = 5            # h / 2 .. h / 32
MAX_ELEMENTS = 2_000_000  # about the area / (h_ref^2 / 2): the largest reference attempted


@dataclass(frozen=True, eq=False)
class Reference:
    evaluate: object          # x (n, 2), cells -> u, sigma, sigma_zz
    cell: float               # the reference's element size
    estimate: dict            # err_l2, err_energy: its own estimated relative errors
    converged: bool           # both estimates MARGIN below the errors compared with them

    def summary(self) -> dict:
        return {"reference": "fem", "reference_cell": self.cell, "reference_converged": self.converged,
                **{f"reference_{k}": v for k, v in self.estimate.items()}}


def fem_reference(body, material, loads, cell: float, errors_of) -> Reference:
    """Refine fem from cell / 2 until its estimated errors are MARGIN below errors_of(reference_evaluate).

    errors_of(evaluate) -> {"err_l2", "err_energy"}: the compared method's errors against a candidate.
    """
    previous, reference = None, None
    h = cell
    area = abs(body.area)
    for _ in range(MAX_LEVELS):
        h /= 2
        if reference is not None and area / (h * h / 2) > MAX_ELEMENTS:
            break
        model = build_model(body, material, loads, h, 1)
        solution = solve_fem(model, estimate_condition=False)
        if previous is not None:
            difference = norm_errors(body, model.grid, material, previous.evaluate, solution.evaluate)
            estimate = {k: difference[k] / (2 ** RATES[k] - 1) for k in RATES}
            target = errors_of(solution.evaluate)
            converged = all(estimate[k] * MARGIN <= target[k] for k in RATES)
            reference = Reference(solution.evaluate, h, estimate, converged)
            if converged:
                return reference
        previous = solution
    return reference
