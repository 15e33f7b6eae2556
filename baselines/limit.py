"""The implicit boundary method in its delta -> 0 limit: a boundary-integral form.

Integrating the IBM's band terms across a band of width delta (int D' = 1, int D D' = 1/2,
int D'^2 = 4/(3 delta), int D'^2 phi = 1/3, D the seed's quadratic) and keeping every O(1)
term gives, with n the outward normal, t the tangent and K -= T(u, v) + T(v, u):

  roller: T = (n.u) [lam d_t v_t + (5/6) M d_n v_n],          penalty (4 M / (3 delta)) (n.u)(n.v)
  fixed:  T = 1/2 u.sigma(v) n + 1/3 [mu u.(grad v n) + (lam + mu)(n.u)(n.grad v n)],
                                      penalty (4 / (3 delta)) sym(v x n) : C : sym(u x n)
  load:   + int_Gamma (n.v)(n.sigma(u^a) n)   (rollers; v.sigma(u^a) n on fixed edges)
  corner: a point term where two essential edges meet (the D_a' D_b' part of the band energy
          in the corner cell delta x delta, less what the edge penalties already count).

The 1/2 is int D D' (the Nitsche-like term); the tangential part lam d_t v_t keeps full
weight because a roller's Dirichlet matrix is I - n n, not 0, on the boundary; the 1/3 terms
come from the penalty integrand varying across the band (int D'^2 phi). With these terms the
band-form stiffness converges to this one as O(delta) (tests/test_baselines.py). The method
notes' shorter form (half of Nitsche's term on rollers, no corner terms) misses O(1) parts.
Like the band form it is penalty-like: O(delta) errors, conditioning ~ 1/delta.
"""
from __future__ import annotations

from time import perf_counter

import numpy as np
import scipy.sparse as sp
from skfem import BilinearForm, asm
from skfem.helpers import dot, grad, mul

from baselines.boundary import bulk_system, consistency_load, edge_basis, grid_solution, solve_weak, stress, symmetric
from ibm.assembly import assemble_matrix, shape_vector
from ibm.material import Elastic
from ibm.model import Model, Solution

DEFAULT_DELTA_REL = 1e-5   # the band form's default


def _column(n: np.ndarray) -> np.ndarray:
    return np.asarray(n, float)[:, None, None]


def consistency_term(kind: str, normal: np.ndarray, lam: float, mu: float) -> BilinearForm:
    """T(u, v) of the module doc for a straight edge with outward normal `normal`."""
    M = lam + 2 * mu
    n, t = _column(normal), _column([-normal[1], normal[0]])
    if kind == "roller":
        return BilinearForm(lambda u, v, w: dot(u, n) * (lam * dot(t, mul(grad(v), t))
                                                         + 5 / 6 * M * dot(n, mul(grad(v), n))))
    return BilinearForm(lambda u, v, w: 0.5 * dot(u, mul(stress(v, lam, mu), n))
                        + (mu * dot(u, mul(grad(v), n)) + (lam + mu) * dot(u, n) * dot(n, mul(grad(v), n))) / 3)


def penalty_density(kind: str, normal: np.ndarray, lam: float, mu: float) -> BilinearForm:
    """M (n.u)(n.v) (roller) or sym(v x n) : C : sym(u x n) = mu u.v + (lam + mu)(n.u)(n.v) (fixed)."""
    n = _column(normal)
    if kind == "roller":
        return BilinearForm(lambda u, v, w: (lam + 2 * mu) * dot(u, n) * dot(v, n))
    return BilinearForm(lambda u, v, w: mu * dot(u, v) + (lam + mu) * dot(u, n) * dot(v, n))


def _energy(G1: np.ndarray, G2: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """sym(G1) : C : sym(G2) for gradients (..., 2, 2)."""
    e1, e2 = 0.5 * (G1 + np.swapaxes(G1, -1, -2)), 0.5 * (G2 + np.swapaxes(G2, -1, -2))
    return 2 * mu * np.einsum("...ij,...ij->...", e1, e2) + lam * np.trace(e1, axis1=-2, axis2=-1) * np.trace(e2, axis1=-2, axis2=-1)


def corner_matrix(kinds: tuple[str, str], normals: np.ndarray, material: Elastic) -> np.ndarray:
    """Q (2, 2): the corner point term is v . Q u at the vertex where edges a, b meet.

    normals (2, 2) inward. In scaled band coordinates s_a, s_b in [0, 1] the corner region
    {phi_a < delta, phi_b < delta} carries the energy of the gradient part
    D_a' (E_a D_b u) x n_a + D_b' (D_a E_b u) x n_b (E = n n for a roller, I for a fixed edge);
    the edge penalties already count (4/3) P_k there. Area factor 1 / |sin| of the corner.
    """
    lam, mu, M = material.lam, material.mu, material.M
    g, w = np.polynomial.legendre.leggauss(8)
    s, ws = (g + 1) / 2, w / 2
    sa, sb = np.meshgrid(s, s, indexing="ij")
    weight = np.outer(ws, ws)

    def factor(kind, n, s):   # D (.., 2, 2), delta D' (..,) and E (2, 2) of one edge
        D, dD = 2 * s - s * s, 2 * (1 - s)
        E = np.outer(n, n) if kind == "roller" else np.eye(2)
        return np.eye(2) - (1 - D)[..., None, None] * E, dD, E

    Da, dDa, Ea = factor(kinds[0], normals[0], sa)
    Db, dDb, Eb = factor(kinds[1], normals[1], sb)
    Q = np.zeros((2, 2))
    for i in range(2):
        for a in range(2):
            def gradient(e):
                ga = dDa[..., None, None] * np.einsum("ij,...jk,k,l->...il", Ea, Db, e, normals[0])
                gb = dDb[..., None, None] * np.einsum("...ij,jk,k,l->...il", Da, Eb, e, normals[1])
                return ga + gb
            e_i, e_a = np.eye(2)[i], np.eye(2)[a]
            Q[i, a] = np.sum(weight * _energy(gradient(e_i), gradient(e_a), lam, mu))
    for kind, n in zip(kinds, normals):
        P = M * np.outer(n, n) if kind == "roller" else mu * np.eye(2) + (lam + mu) * np.outer(n, n)
        Q -= 4 / 3 * P
    sine = abs(normals[0, 0] * normals[1, 1] - normals[0, 1] * normals[1, 0])
    return Q / sine


def corner_terms(model: Model) -> sp.csr_matrix:
    """Point terms at every vertex joining two essential edges, (2 n_nodes)^2."""
    body, grid = model.body, model.grid
    K = sp.csr_matrix((2 * grid.n_nodes, 2 * grid.n_nodes))
    for a in range(body.n_edges):
        b = (a + 1) % body.n_edges
        if a not in body.essential_edges or b not in body.essential_edges:
            continue
        Q = corner_matrix((body.kinds[a], body.kinds[b]), body.normals[[a, b]], model.material)
        corner = body.ends[a][None]
        cell = grid.locate_towards(corner, body.normals[a] + body.normals[b])
        Nv = shape_vector(grid.shape_functions(corner, cell)[0])                  # (1, 2, 8)
        K = K + assemble_matrix(grid, cell, np.einsum("pia,ij,pjb->pab", Nv, Q, Nv))
    return K


def limit_stiffness(model: Model, bulk, delta: float) -> sp.csr_matrix:
    lam, mu = model.material.lam, model.material.mu
    K = bulk.K + corner_terms(model)
    for edge in bulk.edges:
        basis = edge_basis(model, edge)
        K = (K - symmetric(asm(consistency_term(edge.kind, edge.normal, lam, mu), basis))
             + 4 / (3 * delta) * asm(penalty_density(edge.kind, edge.normal, lam, mu), basis))
    return K


def solve_limit(model: Model, delta_rel: float = DEFAULT_DELTA_REL, support_threshold: float = 1e-4,
                  estimate_condition: bool = True) -> Solution:
    """IBM limit form with delta = delta_rel * h."""
    start = perf_counter()
    bulk = bulk_system(model)
    delta = delta_rel * model.grid.h
    K = limit_stiffness(model, bulk, delta)
    f = bulk.f + sum(consistency_load(model, edge) for edge in bulk.edges)
    U, info = solve_weak(model, bulk, K, f, start, support_threshold, estimate_condition)
    info.update(delta_abs=delta)   # not `delta`: this form has no band for the error quadrature to resolve
    return grid_solution(model, U, info, start)
