"""What the weak methods' reaction definitions share: the fields on the essential pieces' Gauss
points (baselines.boundary.essential_edge_points) and their resultants.
u^h = u - u^a is what a method solved for, so n.u^h is a roller's violation and u^h a fixed piece's.
"""
from __future__ import annotations

import numpy as np

from baselines.boundary import essential_edge_points
from ibm.discretise.assembly import tensor, voigt
from ibm.exceptions import InputError


def needs(solution, what: str, method: str):
    """solution.info[what], or one line naming what is missing."""
    if what not in solution.info:
        raise InputError(f"the solution carries no {what!r}: reactions by {method!r} need a solution of {method!r}")
    return solution.info[what]


def stress(model, grad: np.ndarray) -> np.ndarray:
    """Plane-strain stress (m, 2, 2) of displacement gradients (m, 2, 2)."""
    return tensor(voigt(grad) @ model.material.C.T)


def edge_fields(model, solution, method: str):
    """Per essential edge: (EdgePoints, u^h (m, 2), grad u^h (m, 2, 2), u^a, grad u^a) at the points the
    weak methods integrate their boundary terms with."""
    if solution.nodal is None:
        raise InputError(f"the solution carries no nodal values: reactions by {method!r} need a grid method's solution")
    grid = model.grid
    for edge in essential_edge_points(model):
        x, cells = edge.points.x, edge.points.cells
        N, dN = grid.shape_functions(x, cells)                                   # (m, 4), (m, 4, 2)
        Ue = solution.nodal[grid.cell_dofs(cells)].reshape(len(x), 4, 2)          # (m, 4, 2) [p, I, a]
        u_h = np.einsum("pI,pIa->pa", N, Ue)
        grad_h = np.einsum("pIa,pIj->paj", Ue, dN)                                # (m, 2, 2) [p, a, j]
        yield (edge, u_h, grad_h, *model.lift(x))


def resultant(edge, integrand: np.ndarray) -> np.ndarray:
    """sum_q w_q integrand_q (2,) over the edge's points."""
    return edge.points.weight @ integrand


def violation(edge, u_h: np.ndarray) -> np.ndarray:
    """(n.u^h) n (m, 2) on a roller, u^h on a fixed piece."""
    return np.sum(edge.normal * u_h, axis=1)[:, None] * edge.normal if edge.kind == "roller" else u_h


def multiplier_reactions(model, solution, method: str) -> dict[int, np.ndarray]:
    """sum_q w_q (sigma n)_q over each piece's points of the recovered traction: -int lam n."""
    tractions = solution.tractions
    if tractions is None:
        raise InputError(f"the solution carries no multipliers: reactions by {method!r} need a solution of {method!r}")
    forces = tractions.weight[:, None] * tractions.value                              # (m, 2)
    return {k: forces[tractions.edge == k].sum(axis=0) for k in model.body.essential_edges}


def residual_reactions(solution) -> dict[int, np.ndarray]:
    """The residual K U - f at each piece's constrained DOFs (Solution.reactions)."""
    if solution.reactions is None:
        raise InputError("the solution carries no constrained-DOF reactions: reactions by 'nodal' or 'fem' need "
                         "a solution of theirs")
    return {k: np.asarray(F, float) for k, F in solution.reactions.items()}
