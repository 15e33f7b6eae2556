"""The implicit boundary method in its delta -> 0 limit: a boundary-integral form, with its
declaration (IBM_LIMIT) and reactions.

Integrating the IBM's band terms across a band of width delta (int D' = 1, int D D' = 1/2,
int D'^2 = 4/(3 delta), int D'^2 phi = 1/3, D the seed's quadratic) and keeping every O(1)
term gives, with n the outward normal, t the tangent and K -= T(u, v) + T(v, u):

  roller: T = (n.u) [lam d_t v_t + (5/6) M d_n v_n],          penalty (4 M / (3 delta)) (n.u)(n.v)
  fixed:  T = 1/2 u.sigma(v) n + 1/3 [mu u.(grad v n) + (lam + mu)(n.u)(n.grad v n)],
                                      penalty (4 / (3 delta)) sym(v x n) : C : sym(u x n)
  load:   + int_Gamma (n.v)(n.sigma(u^a) n)   (rollers; v.sigma(u^a) n on fixed edges)
  corner: a point term where two essential edges meet (the D_a' D_b' part of the band energy
          in the corner cell delta x delta, less what the edge penalties already count).
  arc:    n = +-e_r and t turn along the piece (taken at each point); with the curvature kappa
          (1/R where the body lies inside the circle, -1/R outside it) K += kappa int S(u, v),
          roller: S = (lam - M/3)(n.u)(n.v),   fixed: S = -(penalty density) / 3.
          The -1/3: the band's area is (1 - kappa phi) ds dphi and int D'^2 phi = 1/3. The lam: a
          roller's turning normal adds -(1 - D) d_j(e_i e_a) u_a = -(1 - D)(t_i t_j e_a + e_i t_a t_j)
          u_a / rho to grad(D u), which meets the D' (n.u) n n^T term through int D'(1 - D) = 1/2
          on both sides.

The 1/2 is int D D' (the Nitsche-like term); the tangential part lam d_t v_t keeps full
weight because a roller's Dirichlet matrix is I - n n, not 0, on the boundary; the 1/3 terms
come from the penalty integrand varying across the band (int D'^2 phi). With these terms the
band-form stiffness converges to this one as O(delta) (tests/baselines/test_baselines.py; on arcs
tests/baselines/test_arcs.py). A shorter form (half of Nitsche's term on rollers, no
corner terms) misses O(1) parts.
Like the band form it is penalty-like: O(delta) errors, conditioning ~ 1/delta.
"""
from __future__ import annotations

from time import perf_counter

import numpy as np
import scipy.sparse as sp
from skfem import BilinearForm
from skfem.helpers import div, dot, grad, mul

from baselines.boundary import (bulk_system, consistency_load, edge_asm, edge_basis, grid_solution, solve_weak, stress,
                                symmetric)
from baselines.edge_reactions import edge_fields, needs, resultant, stress as plane_stress
from ibm.discretise.assembly import assemble_matrix, shape_vector
from ibm.boundary_method import BoundaryMethod, Supports
from ibm.geometry.outline import Body
from ibm.models.elastic import Elastic
from ibm.small.model import Model, Solution
from ibm.implicit_boundary import DEFAULT_DELTA_REL, DELTA_REL, SUPPORT
from ibm.quadrature.rules import QuadraturePoints, grid_crossings, segment_points


def consistency_term(kind: str, lam: float, mu: float) -> BilinearForm:
    """T(u, v) of the module doc, with the outward normal w.n and tangent w.t at each point."""
    M = lam + 2 * mu
    if kind == "roller":
        # lam d_t v_t: the tangential divergence div v - n.grad v n (in 2D t.grad v t; in 3D both tangents)
        return BilinearForm(lambda u, v, w: dot(u, w.n) * (lam * (div(v) - dot(w.n, mul(grad(v), w.n)))
                                                           + 5 / 6 * M * dot(w.n, mul(grad(v), w.n))))
    return BilinearForm(lambda u, v, w: 0.5 * dot(u, mul(stress(v, lam, mu), w.n))
                        + (mu * dot(u, mul(grad(v), w.n)) + (lam + mu) * dot(u, w.n) * dot(w.n, mul(grad(v), w.n))) / 3)


def penalty_density(kind: str, lam: float, mu: float) -> BilinearForm:
    """M (n.u)(n.v) (roller) or sym(v x n) : C : sym(u x n) = mu u.v + (lam + mu)(n.u)(n.v) (fixed)."""
    if kind == "roller":
        return BilinearForm(lambda u, v, w: (lam + 2 * mu) * dot(u, w.n) * dot(v, w.n))
    return BilinearForm(lambda u, v, w: mu * dot(u, v) + (lam + mu) * dot(u, w.n) * dot(v, w.n))


def curvature_term(kind: str, lam: float, mu: float) -> BilinearForm:
    """S(u, v) of the module doc: the arc's term per unit curvature."""
    M = lam + 2 * mu
    if kind == "roller":
        return BilinearForm(lambda u, v, w: (lam - M / 3) * dot(u, w.n) * dot(v, w.n))
    return BilinearForm(lambda u, v, w: -(mu * dot(u, v) + (lam + mu) * dot(u, w.n) * dot(v, w.n)) / 3)


def curvature(body: Body, k: int) -> float:
    """Signed curvature of piece k: 0 straight, 1/R on an arc bulging out, -1/R on a hole's arc."""
    arc = body.arcs[k] if body.arcs else None
    if arc is None:
        return 0.0
    return (-1.0 if arc.clockwise else 1.0) / body.arc_angles(k)[0]


def _energy(G1: np.ndarray, G2: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """sym(G1) : C : sym(G2) for gradients (..., d, d)."""
    e1, e2 = 0.5 * (G1 + np.swapaxes(G1, -1, -2)), 0.5 * (G2 + np.swapaxes(G2, -1, -2))
    return 2 * mu * np.einsum("...ij,...ij->...", e1, e2) + lam * np.trace(e1, axis1=-2, axis2=-1) * np.trace(e2, axis1=-2, axis2=-1)


def corner_matrix(kinds: tuple[str, str], normals: np.ndarray, material: Elastic) -> np.ndarray:
    """Q (d, d): the corner term is v . Q u at the vertex where edges a, b meet (2D), or its density
    per unit length along the ridge where faces a, b meet (3D).

    normals (2, d) inward at the vertex (an arc's normal there). In scaled band coordinates s_a, s_b
    in [0, 1] the corner region {phi_a < delta, phi_b < delta} carries the energy of the gradient part
    D_a' (E_a D_b u) x n_a + D_b' (D_a E_b u) x n_b (E = n n for a roller, I for a fixed edge);
    the edge penalties already count (4/3) P_k there. Area factor 1 / |sin| of the corner (the
    region's cross-section across a ridge in 3D; u varies along the ridge only at O(delta)).
    """
    lam, mu, M = material.lam, material.mu, material.M
    d = normals.shape[1]
    g, w = np.polynomial.legendre.leggauss(8)
    s, ws = (g + 1) / 2, w / 2
    sa, sb = np.meshgrid(s, s, indexing="ij")
    weight = np.outer(ws, ws)

    def factor(kind, n, s):   # D (.., d, d), delta D' (..,) and E (d, d) of one edge
        D, dD = 2 * s - s * s, 2 * (1 - s)
        E = np.outer(n, n) if kind == "roller" else np.eye(d)
        return np.eye(d) - (1 - D)[..., None, None] * E, dD, E

    Da, dDa, Ea = factor(kinds[0], normals[0], sa)
    Db, dDb, Eb = factor(kinds[1], normals[1], sb)
    Q = np.zeros((d, d))
    for i in range(d):
        for a in range(d):
            def gradient(e):
                ga = dDa[..., None, None] * np.einsum("ij,...jk,k,l->...il", Ea, Db, e, normals[0])
                gb = dDb[..., None, None] * np.einsum("...ij,jk,k,l->...il", Da, Eb, e, normals[1])
                return ga + gb
            e_i, e_a = np.eye(d)[i], np.eye(d)[a]
            Q[i, a] = np.sum(weight * _energy(gradient(e_i), gradient(e_a), lam, mu))
    for kind, n in zip(kinds, normals):
        P = M * np.outer(n, n) if kind == "roller" else mu * np.eye(d) + (lam + mu) * np.outer(n, n)
        Q -= 4 / 3 * P
    if d == 2:
        sine = abs(normals[0, 0] * normals[1, 1] - normals[0, 1] * normals[1, 0])
    else:
        sine = float(np.linalg.norm(np.cross(normals[0], normals[1])))
    return Q / sine


def essential_corners(model: Model):
    """Every vertex joining two essential edges a, b: (a, b, the vertex (1, 2), its cell (1,), Q (2, 2))."""
    body, grid = model.body, model.grid
    for a in range(body.n_edges):
        b = (a + 1) % body.n_edges
        if a not in body.essential_edges or b not in body.essential_edges:
            continue
        corner = body.ends[a][None]
        normals = -np.concatenate([body.outward(a, corner), body.outward(b, corner)])     # (2, 2) inward
        Q = corner_matrix((body.kinds[a], body.kinds[b]), normals, model.material)
        yield a, b, corner, grid.locate_towards(corner, normals[0] + normals[1]), Q


def essential_ridges(model: Model, order: int = 4):
    """Every ridge of a polyhedron joining two essential faces a, b: (a, b, its Gauss points split at
    grid planes (QuadraturePoints, exact for N_I N_J along it with order >= 4), Q (3, 3))."""
    body, grid = model.body, model.grid
    for a, b, start, end in body.ridges:
        if a not in body.essential_edges or b not in body.essential_edges:
            continue
        normals = body.normals[[a, b]]                                            # (2, 3) inward
        x, weight, _, _ = segment_points(start, end, grid_crossings(grid.h, start, end), order)
        cells = grid.locate_towards(x, normals[0] + normals[1])   # a ridge on a grid plane: the body's side
        Q = corner_matrix((body.kinds[a], body.kinds[b]), normals, model.material)
        yield a, b, QuadraturePoints(x, weight, cells), Q


def corner_terms(model: Model) -> sp.csr_matrix:
    """Point terms at every vertex joining two essential edges (2D), line terms along every ridge
    joining two essential faces (3D; where three faces meet the region is O(delta^3) and its term
    vanishes); (d n_nodes)^2."""
    grid, d = model.grid, model.dim
    K = sp.csr_matrix((d * grid.n_nodes, d * grid.n_nodes))
    if d == 3:
        for _, _, points, Q in essential_ridges(model):
            Nv = shape_vector(grid.shape_functions(points.x, points.cells)[0])       # (m, 3, 24)
            K = K + assemble_matrix(grid, points.cells,
                                    points.weight[:, None, None] * np.einsum("pia,ij,pjb->pab", Nv, Q, Nv))
        return K
    for _, _, corner, cell, Q in essential_corners(model):
        Nv = shape_vector(grid.shape_functions(corner, cell)[0])                  # (1, 2, 8)
        K = K + assemble_matrix(grid, cell, np.einsum("pia,ij,pjb->pab", Nv, Q, Nv))
    return K


def limit_stiffness(model: Model, bulk, delta: float) -> sp.csr_matrix:
    lam, mu = model.material.lam, model.material.mu
    K = bulk.K + corner_terms(model)
    for edge in bulk.edges:
        basis = edge_basis(model, edge)
        K = (K - symmetric(edge_asm(consistency_term(edge.kind, lam, mu), model, edge, basis))
             + 4 / (3 * delta) * edge_asm(penalty_density(edge.kind, lam, mu), model, edge, basis))
        kappa = curvature(model.body, edge.edge)
        if kappa != 0:
            K = K + kappa * edge_asm(curvature_term(edge.kind, lam, mu), model, edge, basis)
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


def limit_reactions(model: Model, solution: Solution) -> dict:
    """Roller F_e = int_e [lam eps_tt(u^h) + (5/6) M eps_nn(u^h) + n.sigma(u^a) n - (4 M / (3 delta)
    + kappa (lam - M / 3)) n.u^h] n ds; fixed F_e = int_e [sigma(u^h) n / 2 + (mu grad u^h n + (lam + mu)
    eps_nn(u^h) n) / 3 + sigma(u^a) n - (4 / (3 delta) - kappa / 3)(mu u^h + (lam + mu)(n.u^h) n)] ds; less
    half of each corner point term Q u^h at a vertex shared with another essential piece."""
    delta = needs(solution, "delta_abs", "ibm-limit")
    lam, mu, M = model.material.lam, model.material.mu, model.material.M
    result = {}
    for edge, u_h, grad_h, _, grad_a in edge_fields(model, solution, "ibm-limit"):
        n, kappa = edge.normal, curvature(model.body, edge.edge)
        t = np.stack([-n[:, 1], n[:, 0]], axis=1)
        normal_gap = np.sum(n * u_h, axis=1)                                       # (m,) n.u^h
        grad_n = np.einsum("paj,pj->pa", grad_h, n)                                # (m, 2) grad u^h n
        eps_nn = np.sum(n * grad_n, axis=1)
        sigma_a_n = np.einsum("pij,pj->pi", plane_stress(model, grad_a), n)        # (m, 2) sigma(u^a) n
        if edge.kind == "roller":
            eps_tt = np.einsum("pa,paj,pj->p", t, grad_h, t)
            flux = (lam * eps_tt + 5 / 6 * M * eps_nn + np.sum(n * sigma_a_n, axis=1)
                    - (4 * M / (3 * delta) + kappa * (lam - M / 3)) * normal_gap)
            integrand = flux[:, None] * n
        else:
            sigma_h_n = np.einsum("pij,pj->pi", plane_stress(model, grad_h), n)
            integrand = (sigma_h_n / 2 + (mu * grad_n + (lam + mu) * eps_nn[:, None] * n) / 3 + sigma_a_n
                         - (4 / (3 * delta) - kappa / 3) * (mu * u_h + (lam + mu) * normal_gap[:, None] * n))
        result[edge.edge] = resultant(edge, integrand)
    grid = model.grid
    for a, b, corner, cell, Q in essential_corners(model):                        # K += v.Q u^h at the vertex
        N, _ = grid.shape_functions(corner, cell)
        u_h = N[0] @ solution.nodal[grid.cell_dofs(cell)[0]].reshape(4, 2)
        for k in (a, b):
            result[k] = result[k] - Q @ u_h / 2
    return result


class ImplicitBoundaryLimit(BoundaryMethod):
    name = "ibm-limit"
    summary = "implicit boundary method, delta -> 0 boundary-integral form"
    parameters = (DELTA_REL, SUPPORT)
    supports = Supports({
        "load-steps": "its boundary terms and corner point terms are the delta -> 0 limit of the linear-elastic "
                      "band energy; at finite strain the band stress is not linear in the band coordinate, so the "
                      "limit form would not be the IBM's limit (use ibm)",
        "load-steps-3d": "its terms are the limit of the linear-elastic band energy (use ibm)"})

    def solve(self, model, delta_rel=DEFAULT_DELTA_REL, support_threshold=1e-4):
        return solve_limit(model, delta_rel, support_threshold)

    def reactions(self, model, solution):
        return limit_reactions(model, solution)


IBM_LIMIT = ImplicitBoundaryLimit()
