"""Weak-form pieces evaluated on a set of quadrature points.

Each takes an optional Dirichlet function `dirichlet(x) -> (D (n, 2, 2), grad D (n, 2, 2, 2))`;
without it the ordinary Q4 operators are used. The IBM integrates the ordinary forms at the
material points and adds band corrections form(D) - form(I) by exact band quadrature.

The ordinary stiffness goes through the cells' volume moments (ibm.discretise.assembly), so its cost
grows with the number of cells, not of points; every matrix is built straight into CSR.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.sparse as sp

from ibm.discretise.assembly import (GridMatrix, assemble_vector, point_stiffness,
                          shape_vector, stiffness_blocks, strain_matrix, tensor, voigt)
from ibm.small.model import Model
from ibm.quadrature.rules import QuadraturePoints

Dirichlet = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
CHUNK_3D = 1 << 14   # quadrature points per pass in 3D: bounds the (chunk, 24, 24) blocks (75 MB)


def parts(model: Model, qp: QuadraturePoints) -> list[QuadraturePoints]:
    """qp in pieces of at most CHUNK_3D points in 3D (millions of band points there), whole in 2D."""
    if model.dim == 2 or len(qp) <= CHUNK_3D:
        return [qp]
    return [qp.subset(slice(s, s + CHUNK_3D)) for s in range(0, len(qp), CHUNK_3D)]


def at(dirichlet: Dirichlet, qp: QuadraturePoints):
    """D (n, d, d) and grad D (n, d, d, d) at the points, in their band regions if they carry them."""
    return dirichlet(qp.x) if qp.region is None else dirichlet(qp.x, qp.region)


def operators(model: Model, qp: QuadraturePoints, dirichlet: Dirichlet | None = None):
    """Nv (n, d, k d) and B (n, r, k d) at the quadrature points."""
    N, dN = model.grid.shape_functions(qp.x, qp.cells)
    if dirichlet is None:
        return shape_vector(N), strain_matrix(N, dN)
    Dm, gradDm = at(dirichlet, qp)
    return shape_vector(N, Dm), strain_matrix(N, dN, Dm, gradDm)


def stiffness(model: Model, qp: QuadraturePoints, dirichlet: Dirichlet | None = None) -> sp.csr_matrix:
    """sum_q w B~^T C B~ (B without `dirichlet`), (d n_nodes)^2 CSR."""
    if dirichlet is None:
        return point_stiffness(model.grid, qp.x, qp.weight, qp.cells, model.C)
    matrix = GridMatrix(model.grid, qp.cells)
    for part in parts(model, qp):
        _, B = operators(model, part, dirichlet)
        matrix.add(part.cells, stiffness_blocks(B, model.C, part.weight))
    return matrix.tocsr()


def band_blocks(model: Model, band: QuadraturePoints, dirichlet: Dirichlet) -> np.ndarray:
    """(n, k d, k d) blocks w (B~^T C B~ - B^T C B) of the band correction at the band points."""
    N, dN = model.grid.shape_functions(band.x, band.cells)
    Dm, gradDm = at(dirichlet, band)
    C = model.C
    return (stiffness_blocks(strain_matrix(N, dN, Dm, gradDm), C, band.weight)
            - stiffness_blocks(strain_matrix(N, dN), C, band.weight))


def corrected_stiffness(model: Model, points: QuadraturePoints, band: QuadraturePoints,
                        dirichlet: Dirichlet, assemble: bool = True) -> sp.csr_matrix | GridMatrix:
    """stiffness(points) + stiffness(band, dirichlet) - stiffness(band), built as one CSR matrix.

    assemble=False returns the GridMatrix instead, from which the final unknowns can be
    taken directly (GridMatrix.tocsr(rows, columns)).
    """
    matrix = GridMatrix(model.grid, np.concatenate([points.cells, band.cells]))
    point_stiffness(model.grid, points.x, points.weight, points.cells, model.C, matrix)
    for part in parts(model, band) if len(band) else ():
        matrix.add(part.cells, band_blocks(model, part, dirichlet))
    return matrix.tocsr() if assemble else matrix


def _load(model: Model, qp: QuadraturePoints, values, dirichlet: Dirichlet | None) -> np.ndarray:
    """f_(I, a) = sum_q w N_I (D^T v)_a for vector values v (n, d), or a function v(x) giving them."""
    pieces = parts(model, qp)
    if len(pieces) > 1:
        if not callable(values):
            starts = np.cumsum([0] + [len(part) for part in pieces])
            return sum(_load(model, part, values[a:b], dirichlet) for part, a, b in zip(pieces, starts, starts[1:]))
        return sum(_load(model, part, values, dirichlet) for part in pieces)
    values = values(qp.x) if callable(values) else values
    N, _ = model.grid.shape_functions(qp.x, qp.cells)
    if dirichlet is not None:
        values = np.einsum("pia,pi->pa", at(dirichlet, qp)[0], values)
    blocks = N[:, :, None] * (values * qp.weight[:, None])[:, None, :]          # (n, k, d)
    return assemble_vector(model.grid, qp.cells, blocks.reshape(len(qp), -1))


def body_force(model: Model, qp: QuadraturePoints, dirichlet: Dirichlet | None = None) -> np.ndarray:
    """f_I = sum_q w N_I D^T b."""
    if model.loads.body_force is None or len(qp) == 0:
        return np.zeros(model.grid.dim * model.grid.n_nodes)
    return _load(model, qp, model.loads.body_force, dirichlet)


def lift_force(model: Model, qp: QuadraturePoints, dirichlet: Dirichlet | None = None) -> np.ndarray:
    """f = - sum_q w B~^T C eps(u^a): moves the essential data to the right-hand side."""
    if model.loads.lift is None or len(qp) == 0:
        return np.zeros(model.grid.dim * model.grid.n_nodes)
    pieces = parts(model, qp)
    if len(pieces) > 1:
        return sum(lift_force(model, part, dirichlet) for part in pieces)
    _, B = operators(model, qp, dirichlet)
    sigma_a = voigt(model.lift(qp.x)[1]) @ model.C.T
    return assemble_vector(model.grid, qp.cells, -np.einsum("pka,pk->pa", B, sigma_a) * qp.weight[:, None])


def traction_force(model: Model, edge_points: dict[int, QuadraturePoints],
                   dirichlet: Dirichlet | None = None) -> np.ndarray:
    """f_I = int_Gamma_t N_I D^T t, edge by edge."""
    f = np.zeros(model.grid.dim * model.grid.n_nodes)
    for k, traction in model.loads.tractions.items():
        qp = edge_points[k]
        if len(qp):
            f += _load(model, qp, traction, dirichlet)
    return f


class FieldEvaluator:
    """evaluate(x, cells) -> u (n, d), sigma (n, d, d), sigma_zz (n,) from nodal values U (d n_nodes,).

    u = D u^h + u^a and grad u = D grad u^h + (grad D) u^h + grad u^a, with u^h = sum_I N_I U_I:
    the same as Nv U and B U, without forming the (n, 3, 8) operators.
    """

    def __init__(self, model: Model, U: np.ndarray, dirichlet: Dirichlet | None = None):
        self.model, self.U, self.dirichlet = model, U, dirichlet

    def __call__(self, x: np.ndarray, cells: np.ndarray, region: np.ndarray | None = None):
        """region (n,): band-region masks of moment-fitted nodes (QuadraturePoints.region)."""
        model, dirichlet = self.model, self.dirichlet
        n, d = x.shape
        N, dN = model.grid.shape_functions(x, cells)
        ue = self.U[model.grid.cell_dofs(cells)].reshape(n, N.shape[1], d)     # (n, k, d) [p, I, a]
        u = np.matmul(N[:, None, :], ue)[:, 0]                                  # (n, d) u^h
        grad = np.matmul(ue.transpose(0, 2, 1), dN)                             # (n, d, d) [p, a, j] grad u^h
        if dirichlet is not None:
            Dm, gradDm = dirichlet(x) if region is None else dirichlet(x, region)
            # beyond the bands D = I with zero gradient: only points in a band change
            near = np.flatnonzero(np.any((Dm != np.eye(d)).reshape(n, -1), axis=1)
                                  | np.any(gradDm.reshape(n, -1) != 0, axis=1))
            Dn, uh = Dm[near], u[near]
            u = u.copy()
            u[near] = np.matmul(Dn, uh[:, :, None])[:, :, 0]
            grad[near] = np.matmul(Dn, grad[near]) + np.einsum("piaj,pa->pij", gradDm[near], uh)
        return self._fields(x, u, grad)

    def in_clear_cells(self, cells: np.ndarray, offsets: np.ndarray, x: np.ndarray):
        """The same fields, (c q, ...) cell by cell, at the points x = grid.points_in_cells(cells, offsets)
        (the caller has them) of cells (c,) that lie clear of every band (D = I there, as the error norms'
        whole cells): the shape functions once for all cells, the fields by two matrix products."""
        model = self.model
        grid, d = model.grid, model.dim
        N, dN = grid.shape_functions(grid.origin + offsets, np.zeros(len(offsets), int))    # (q, k), (q, k, d)
        ue = self.U[grid.cell_dofs(cells)].reshape(len(cells), N.shape[1], d)              # (c, k, d)
        u = np.tensordot(ue, N, axes=([1], [1])).transpose(0, 2, 1).reshape(-1, d)        # (c q, d)
        grad = np.tensordot(ue, dN, axes=([1], [1])).transpose(0, 2, 1, 3).reshape(-1, d, d)   # [cq, a, j]
        return self._fields(x, u, grad)

    def _fields(self, x, u, grad):
        u_a, grad_a = self.model.lift(x)
        sigma = voigt(grad + grad_a) @ self.model.C.T
        return u + u_a, tensor(sigma), self.model.material.sigma_zz(sigma)


def field_evaluator(model: Model, U: np.ndarray, dirichlet: Dirichlet | None = None) -> FieldEvaluator:
    """The fields of nodal values U (FieldEvaluator)."""
    return FieldEvaluator(model, U, dirichlet)
