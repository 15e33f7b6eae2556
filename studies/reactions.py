"""Reaction forces: the resultant of the support's traction on each essential piece of a solved
small-strain linear elastic case, by each method's own definition; beside them a domain integral
that serves every method, and the exact resultant.

    F_e = int_e sigma n ds          (n the outward normal: the force the support puts on the body)

Each method's F_e comes from its own discrete equations. They read a(u, v) - l(v) = (its boundary
terms)(v) for every test field v they admit, and the constant fields c are among those (the
extension of tiny-support nodes and the active nodes keep constants). Tested by c, a piece's
boundary terms give F_e . c, so the reactions of all pieces balance the applied loads as exactly
as the method's equations are solved. Below, u^h = u - u^a is what the method solved for (the lift
u^a carries the essential data, so n.u^h is a roller's violation and u^h a fixed piece's),
M = lam + 2 mu, h the cell size, eps_tt = t.grad u t, eps_nn = n.grad u n:

- penalty:   F_e = -beta int_e (n.u^h) n ds (roller), -beta int_e u^h ds (fixed), beta = beta0 M / h.
- nitsche:   F_e = int_e [n.sigma(u) n - (gamma M / h) n.u^h] n ds (roller),
             int_e [sigma(u) n - (gamma M / h) u^h] ds (fixed); its symmetric term tests grad c = 0.
- lagrange:  F_e = -int_e [lam + a (M / h) n.u^h] n ds (roller), -int_e [lam + a (M / h) u^h] ds (fixed):
             the multipliers and the augmentation a (its default 1), which vanishes where the
             constraint holds pointwise. lagrange-nodal: F_e = -sum_c lam_c n_c, its point multipliers.
- ibm-limit: roller F_e = int_e [lam eps_tt(u^h) + (5/6) M eps_nn(u^h) + n.sigma(u^a) n
             - (4 M / (3 delta) + kappa (lam - M / 3)) n.u^h] n ds; fixed F_e = int_e [sigma(u^h) n / 2
             + (mu grad u^h n + (lam + mu) eps_nn(u^h) n) / 3 + sigma(u^a) n
             - (4 / (3 delta) - kappa / 3)(mu u^h + (lam + mu)(n.u^h) n)] ds; less half of each corner
             point term Q u^h at a vertex shared with another essential piece (baselines.limit).
- ibm:       F_e . c = a(u, w) - l(w) with w = (D_(-e) - D) c, D_(-e) the product of the walls'
             Dirichlet functions without wall e's. D_(-e) c is free on wall e and meets the other
             walls' constraints; D c is a test field of the method, whose residual vanishes, so w
             may replace D_(-e) c. w is zero outside wall e's band and its material-point part
             c - c is zero, so only the exact band quadrature sees it:
                 F_e . c = int_band [sigma(u) : grad w - b.w] dOmega - int_Gamma_t t.w ds.
             Away from other bands w = (1 - D(phi)) n (n.c) on a roller ((1 - D(phi)) c on a fixed
             wall), so F_e . c = int_band D'(phi) n.sigma n (n.c) dOmega (int D' dphi = 1 across the
             band): the band's D'-weighted mean of the normal stress, not the stress at the wall.
             Where a fixed wall's band overlaps another's, (I - D_a)(I - D_b) c counts to neither
             (an O(delta) gap in the balance; zero where rollers meet at right angles). On a wall
             of several pieces, each band point counts to the piece its foot on the wall lies on.
- nodal, fem: the residual K U - f at the piece's constrained DOFs (Solution.reactions, split at
             corners by baselines.boundary.piece_reactions).

The domain reaction (studies.footing's kind) serves every method: on a straight piece e, for c its
normal (and its tangent on a fixed piece), v = psi c with psi linear, one on e and zero on every
other essential piece that v would cross (a fixed piece, or a roller whose normal is not
orthogonal to c), gives
    F_e . c = sum_p V_p c.sigma_p grad psi - sum_p V_p psi b.c - int_Gamma_t psi t.c ds.
It exists where those pieces lie on one straight line parallel to e (or there are none: psi = 1).
It is penalty's, lagrange's and nodal's own reaction again (v lies in their test space and their
other pieces' terms vanish on it); Nitsche's and ibm-limit's symmetric terms add parts that vanish
with the constraint's violation; for the IBM (its points' stresses, not its band) and fem (not its
mesh) it is a check from outside.
"""
from __future__ import annotations

import numpy as np

from baselines.boundary import essential_edge_points
from ibm import dirichlet
from ibm.assembly import tensor, voigt
from ibm.bands import band_quadrature, edge_quadrature
from ibm.exceptions import InputError
from ibm.model import Model, Solution

EXACT_ORDER = 10           # Gauss points per straight piece (split at grid lines) for the exact resultant
PARALLEL = 1e-9            # |n_1 x n_2| below this: two lines are parallel


def reactions(model: Model, solution: Solution, method: str) -> dict[int, np.ndarray]:
    """F_e (2,) on every essential piece e of `model`, by `method`'s definition (module doc)."""
    if method not in DEFINITIONS:
        raise InputError(f"method {method!r} has no reaction definition; methods with one: {', '.join(DEFINITIONS)}")
    return DEFINITIONS[method](model, solution)


def _stress(model: Model, grad: np.ndarray) -> np.ndarray:
    """Plane-strain stress (m, 2, 2) of displacement gradients (m, 2, 2)."""
    return tensor(voigt(grad) @ model.material.C.T)


def _needs(solution: Solution, what: str, method: str):
    """solution.info[what], or one line naming what is missing."""
    if what not in solution.info:
        raise InputError(f"the solution carries no {what!r}: reactions by {method!r} need a solution of {method!r}")
    return solution.info[what]


def _edge_fields(model: Model, solution: Solution, method: str):
    """Per essential edge: (EdgePoints, u^h (m, 2), grad u^h (m, 2, 2), u^a, grad u^a) at the points the
    weak methods integrate their boundary terms with (baselines.boundary.essential_edge_points)."""
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


def _resultant(edge, integrand: np.ndarray) -> np.ndarray:
    """sum_q w_q integrand_q (2,) over the edge's points."""
    return edge.points.weight @ integrand


def _violation(edge, u_h: np.ndarray) -> np.ndarray:
    """(n.u^h) n (m, 2) on a roller, u^h on a fixed piece."""
    return np.sum(edge.normal * u_h, axis=1)[:, None] * edge.normal if edge.kind == "roller" else u_h


def _penalty(model: Model, solution: Solution) -> dict[int, np.ndarray]:
    beta = _needs(solution, "beta", "penalty")
    result = {}
    for edge, u_h, _, _, _ in _edge_fields(model, solution, "penalty"):
        result[edge.edge] = -beta * _resultant(edge, _violation(edge, u_h))
    return result


def _nitsche(model: Model, solution: Solution) -> dict[int, np.ndarray]:
    gamma = _needs(solution, "gamma", "nitsche")
    stiffness = gamma * model.material.M / model.grid.h
    result = {}
    for edge, u_h, grad_h, _, grad_a in _edge_fields(model, solution, "nitsche"):
        n = edge.normal
        t = np.einsum("pij,pj->pi", _stress(model, grad_h + grad_a), n) - stiffness * u_h     # sigma(u) n - s u^h
        if edge.kind == "roller":
            t = np.sum(t * n, axis=1)[:, None] * n
        result[edge.edge] = _resultant(edge, t)
    return result


def _lagrange(model: Model, solution: Solution) -> dict[int, np.ndarray]:
    result = _multipliers(model, solution, "lagrange")
    stiffness = solution.info.get("augment", 0.0) * model.material.M / model.grid.h
    if stiffness > 0:
        for edge, u_h, _, _, _ in _edge_fields(model, solution, "lagrange"):
            result[edge.edge] = result[edge.edge] - stiffness * _resultant(edge, _violation(edge, u_h))
    return result


def _multipliers(model: Model, solution: Solution, method: str = "lagrange-nodal") -> dict[int, np.ndarray]:
    """sum_q w_q (sigma n)_q over each piece's points of the recovered traction: -int lam n."""
    tractions = solution.tractions
    if tractions is None:
        raise InputError(f"the solution carries no multipliers: reactions by {method!r} need a solution of {method!r}")
    forces = tractions.weight[:, None] * tractions.value                              # (m, 2)
    return {k: forces[tractions.edge == k].sum(axis=0) for k in model.body.essential_edges}


def _limit(model: Model, solution: Solution) -> dict[int, np.ndarray]:
    from baselines.limit import curvature, essential_corners
    delta = _needs(solution, "delta_abs", "ibm-limit")
    lam, mu, M = model.material.lam, model.material.mu, model.material.M
    result = {}
    for edge, u_h, grad_h, _, grad_a in _edge_fields(model, solution, "ibm-limit"):
        n, kappa = edge.normal, curvature(model.body, edge.edge)
        t = np.stack([-n[:, 1], n[:, 0]], axis=1)
        normal_gap = np.sum(n * u_h, axis=1)                                       # (m,) n.u^h
        grad_n = np.einsum("paj,pj->pa", grad_h, n)                                # (m, 2) grad u^h n
        eps_nn = np.sum(n * grad_n, axis=1)
        sigma_a_n = np.einsum("pij,pj->pi", _stress(model, grad_a), n)             # (m, 2) sigma(u^a) n
        if edge.kind == "roller":
            eps_tt = np.einsum("pa,paj,pj->p", t, grad_h, t)
            flux = (lam * eps_tt + 5 / 6 * M * eps_nn + np.sum(n * sigma_a_n, axis=1)
                    - (4 * M / (3 * delta) + kappa * (lam - M / 3)) * normal_gap)
            integrand = flux[:, None] * n
        else:
            sigma_h_n = np.einsum("pij,pj->pi", _stress(model, grad_h), n)
            integrand = (sigma_h_n / 2 + (mu * grad_n + (lam + mu) * eps_nn[:, None] * n) / 3 + sigma_a_n
                         - (4 / (3 * delta) - kappa / 3) * (mu * u_h + (lam + mu) * normal_gap[:, None] * n))
        result[edge.edge] = _resultant(edge, integrand)
    grid = model.grid
    for a, b, corner, cell, Q in essential_corners(model):                        # K += v.Q u^h at the vertex
        N, _ = grid.shape_functions(corner, cell)
        u_h = N[0] @ solution.nodal[grid.cell_dofs(cell)[0]].reshape(4, 2)
        for k in (a, b):
            result[k] = result[k] - Q @ u_h / 2
    return result


def _band(model: Model, solution: Solution) -> dict[int, np.ndarray]:
    body, grid = model.body, model.grid
    delta = _needs(solution, "delta", "ibm")
    band = band_quadrature(body, grid, delta)
    _, sigma, _ = solution.evaluate(band.x, band.cells)                           # sigma(D u^h + u^a)
    D, grad_D = dirichlet.matrix(body, band.x, delta)                              # (n, 2, 2), (n, 2, 2, 2)
    force = np.zeros((len(band), 2)) if model.loads.body_force is None else model.loads.body_force(band.x)
    loaded = [edge_quadrature(body, grid, k, delta) for k in model.loads.tractions]
    tractions = [(qp, model.loads.tractions[k](qp.x), dirichlet.matrix(body, qp.x, delta)[0])
                 for k, qp in zip(model.loads.tractions, loaded)]
    result = {}
    for w, wall in enumerate(body.walls):
        D_w, grad_w = dirichlet.matrix(body, band.x, delta, leave_out=w)
        # w_a = (D_w - D) e_a: grad w_a [p, i, j] = (grad_w - grad_D)[p, i, a, j]
        density = (np.einsum("pij,piaj->pa", sigma, grad_w - grad_D)
                   - np.einsum("pi,pia->pa", force, D_w - D)) * band.weight[:, None]       # (n, 2)
        share = [(band.x, density)]
        for qp, t, D_t in tractions:
            D_tw = dirichlet.matrix(body, qp.x, delta, leave_out=w)[0]
            share.append((qp.x, -np.einsum("pi,pia->pa", t, D_tw - D_t) * qp.weight[:, None]))
        for x, values in share:
            piece = _piece_of(body, wall, x)
            for k in wall.pieces:
                result[k] = result.get(k, np.zeros(2)) + values[piece == k].sum(axis=0)
    return result


def _piece_of(body, wall, x: np.ndarray) -> np.ndarray:
    """The piece (n,) of `wall` whose stretch of the wall the foot of each point x (n, 2) lies on."""
    if len(wall.pieces) == 1:
        return np.full(len(x), wall.pieces[0])
    _, t = wall.local(x)
    ends = np.cumsum([body.lengths[k] for k in wall.pieces])[:-1]
    return np.asarray(wall.pieces)[np.searchsorted(ends, t)]


def _residual(model: Model, solution: Solution) -> dict[int, np.ndarray]:
    if solution.reactions is None:
        raise InputError("the solution carries no constrained-DOF reactions: reactions by 'nodal' or 'fem' need "
                         "a solution of theirs")
    return {k: np.asarray(F, float) for k, F in solution.reactions.items()}


DEFINITIONS = {"ibm": _band, "ibm-limit": _limit, "penalty": _penalty, "nitsche": _nitsche, "lagrange": _lagrange,
               "lagrange-nodal": _multipliers, "nodal": _residual, "fem": _residual}


# --- the domain reaction and the exact resultant ------------------------------------------------

def _linear_test(body, e: int, c: np.ndarray) -> tuple[np.ndarray, float] | None:
    """psi(x) = g.x + s (g (2,), s) of the domain reaction for piece e along c (module doc), or None."""
    arcs = body.arcs or (None,) * body.n_edges
    if arcs[e] is not None:
        return None
    crossed = []
    for j in body.essential_edges:
        if j == e:
            continue
        if arcs[j] is not None:
            return None
        if body.kinds[j] == "fixed" or abs(body.normals[j] @ c) > PARALLEL:
            crossed.append(j)
    if not crossed:
        return np.zeros(2), 1.0
    n = body.normals[crossed[0]]
    level = n @ body.starts[crossed[0]]
    for j in crossed:                 # one line: parallel normals, both ends on it
        if abs(n[0] * body.normals[j][1] - n[1] * body.normals[j][0]) > PARALLEL or \
                max(abs(n @ body.starts[j] - level), abs(n @ body.ends[j] - level)) > PARALLEL * body.lengths.max():
            return None
    height = n @ body.starts[e] - level
    skew = abs(n[0] * body.normals[e][1] - n[1] * body.normals[e][0])
    if skew > PARALLEL or abs(height) <= PARALLEL * body.lengths.max():
        return None
    return n / height, -level / height


def domain_reactions(model: Model, solution: Solution) -> dict[int, np.ndarray]:
    """F_e (2,) by the domain integral (module doc) on every essential piece where it exists."""
    body, grid, points = model.body, model.grid, model.points
    x, V = points.x, points.volume
    force = None if model.loads.body_force is None else model.loads.body_force(x)
    loaded = {k: edge_quadrature(body, grid, k, None) for k in model.loads.tractions}
    result = {}
    for e in body.essential_edges:
        n = -body.normals[e]                                                         # outward
        directions = [n] if body.kinds[e] == "roller" else [n, np.array([-n[1], n[0]])]
        total = np.zeros(2)
        for c in directions:
            found = _linear_test(body, e, c)
            if found is None:
                break
            g, s = found
            psi = x @ g + s                                                          # (n,)
            value = np.sum(V * np.einsum("i,pij,j->p", c, solution.sigma, g))
            if force is not None:
                value -= np.sum(V * psi * (force @ c))
            for k, qp in loaded.items():
                value -= np.sum(qp.weight * (qp.x @ g + s) * (model.loads.tractions[k](qp.x) @ c))
            total += value * c
        else:
            result[e] = total
    return result


def exact_reactions(model: Model, exact) -> dict[int, np.ndarray]:
    """int_e sigma n ds (2,) of an exact field (exact(x) -> u, sigma, sigma_zz) on every essential piece e:
    Gauss along the piece split at grid lines (EXACT_ORDER points a part; on arcs the sub-arcs' rule)."""
    body, grid = model.body, model.grid
    result = {}
    for e in body.essential_edges:
        qp = edge_quadrature(body, grid, e, None, order=EXACT_ORDER)
        _, sigma, _ = exact(qp.x)
        result[e] = qp.weight @ np.einsum("pij,pj->pi", sigma, body.outward(e, qp.x))
    return result


def reaction_records(model: Model, solution: Solution, method: str, exact=None) -> list[dict]:
    """The reaction on every essential piece as JSON-able records (`ibm-study solve --json`): edge
    index, kind, force (2,) and, given an exact field, its exact resultant."""
    forces = reactions(model, solution, method)
    known = exact_reactions(model, exact) if exact is not None else {}
    return [{"edge": k, "kind": model.body.kinds[k], "force": forces[k].tolist(),
             **({"exact": known[k].tolist()} if k in known else {})} for k in model.body.essential_edges]


def reaction_error(records: list[dict]) -> float:
    """max_e |F_e - F_e exact| / max_e |F_e exact| over reaction_records with exact resultants."""
    error = max(np.linalg.norm(np.subtract(r["force"], r["exact"])) for r in records)
    return float(error / max(max(np.linalg.norm(r["exact"]) for r in records), np.finfo(float).tiny))
