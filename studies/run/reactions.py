"""Reaction forces: the resultant of the support's traction on each essential piece of a solved
small-strain linear elastic case, by each method's own definition; beside them a domain integral
that serves every method, and the exact resultant.

    F_e = int_e sigma n ds          (n the outward normal: the force the support puts on the body)

Each method's F_e comes from its own discrete equations (its module's reactions): they read
a(u, v) - l(v) = (its boundary terms)(v) for every test field v they admit, and the constant fields
c are among those, so tested by c a piece's boundary terms give F_e . c and the reactions of all
pieces balance the applied loads as exactly as the method's equations are solved.

The domain reaction (studies.problems.footing's kind) serves every method: on a straight piece e, for c its
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

from baselines.registry import METHODS
from ibm.exceptions import InputError
from ibm.quadrature.bands import edge_quadrature
from ibm.small.model import Model, Solution

EXACT_ORDER = 10           # Gauss points per straight piece (split at grid lines) for the exact resultant
PARALLEL = 1e-9            # |n_1 x n_2| below this: two lines are parallel


def reactions(model: Model, solution: Solution, method: str) -> dict[int, np.ndarray]:
    """F_e (2,) on every essential piece e of `model`, by `method`'s own definition (its reactions)."""
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; allowed: {', '.join(METHODS)}")
    return METHODS[method].reactions(model, solution)


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
