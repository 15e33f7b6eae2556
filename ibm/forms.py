"""Weak-form pieces evaluated on a set of quadrature points.

Each takes an optional Dirichlet function `dirichlet(x) -> (D (n, 2, 2), grad D (n, 2, 2, 2))`;
without it the ordinary Q4 operators are used. The IBM integrates the ordinary forms at the
material points and adds band corrections form(D) - form(I) by exact band quadrature.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.sparse as sp

from ibm.assembly import (assemble_matrix, assemble_vector, shape_vector, stiffness_blocks,
                          strain_matrix, voigt)
from ibm.model import Model
from ibm.quadrature import QuadraturePoints

Dirichlet = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def operators(model: Model, qp: QuadraturePoints, dirichlet: Dirichlet | None = None):
    """Nv (n, 2, 8) and B (n, 3, 8) at the quadrature points."""
    N, dN = model.grid.shape_functions(qp.x, qp.cells)
    if dirichlet is None:
        return shape_vector(N), strain_matrix(N, dN)
    Dm, gradDm = dirichlet(qp.x)
    return shape_vector(N, Dm), strain_matrix(N, dN, Dm, gradDm)


def stiffness(model: Model, qp: QuadraturePoints, dirichlet: Dirichlet | None = None) -> sp.csr_matrix:
    _, B = operators(model, qp, dirichlet)
    return assemble_matrix(model.grid, qp.cells, stiffness_blocks(B, model.material.C, qp.weight))


def body_force(model: Model, qp: QuadraturePoints, dirichlet: Dirichlet | None = None) -> np.ndarray:
    """f_I = sum_q w N_I D^T b."""
    if model.loads.body_force is None or len(qp) == 0:
        return np.zeros(2 * model.grid.n_nodes)
    Nv, _ = operators(model, qp, dirichlet)
    b = model.loads.body_force(qp.x)
    return assemble_vector(model.grid, qp.cells, np.einsum("pia,pi->pa", Nv, b) * qp.weight[:, None])


def lift_force(model: Model, qp: QuadraturePoints, dirichlet: Dirichlet | None = None) -> np.ndarray:
    """f = - sum_q w B~^T C eps(u^a): moves the essential data to the right-hand side."""
    if model.loads.lift is None or len(qp) == 0:
        return np.zeros(2 * model.grid.n_nodes)
    _, B = operators(model, qp, dirichlet)
    sigma_a = voigt(model.lift(qp.x)[1]) @ model.material.C.T
    return assemble_vector(model.grid, qp.cells, -np.einsum("pka,pk->pa", B, sigma_a) * qp.weight[:, None])


def traction_force(model: Model, edge_points: dict[int, QuadraturePoints],
                   dirichlet: Dirichlet | None = None) -> np.ndarray:
    """f_I = int_Gamma_t N_I D^T t, edge by edge."""
    f = np.zeros(2 * model.grid.n_nodes)
    for k, traction in model.loads.tractions.items():
        qp = edge_points[k]
        Nv, _ = operators(model, qp, dirichlet)
        f += assemble_vector(model.grid, qp.cells,
                             np.einsum("pia,pi->pa", Nv, traction(qp.x)) * qp.weight[:, None])
    return f


def field_evaluator(model: Model, U: np.ndarray, dirichlet: Dirichlet | None = None):
    """evaluate(x, cells) -> u (n, 2), sigma (n, 2, 2), sigma_zz (n,) from nodal values U (2 n_nodes,)."""
    from ibm.assembly import tensor

    def evaluate(x: np.ndarray, cells: np.ndarray):
        qp = QuadraturePoints(x, np.ones(len(x)), cells)
        Nv, B = operators(model, qp, dirichlet)
        ue = U[model.grid.cell_dofs(cells)]                      # (n, 8)
        u_a, grad_a = model.lift(x)
        u = np.einsum("pia,pa->pi", Nv, ue) + u_a
        sigma = (np.einsum("pka,pa->pk", B, ue) + voigt(grad_a)) @ model.material.C.T
        return u, tensor(sigma), model.material.sigma_zz(sigma)

    return evaluate
