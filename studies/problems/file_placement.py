"""A problem file (studies.problems.problem_file) placed in the grid, and the problem of a study that
a case's problem_file names (PROBLEM_FILE).

On an arc the roller's normal is the radial direction, and d_k below is the distance to the arc.

Placement: the outline's `start` point goes to grid node + offset h and the body turns by
the case's angle about it (angle 90 keeps the file's axes, as for the built-in problems).

With [exact], loads left out are derived from it: b = -div sigma, the tractions sigma n on
traction pieces, the essential data u (n.u on rollers). The lift that carries those data is, by
default (lift = "bubble"), u^a = (1 - beta) u with beta = prod_k (1 - exp(-d_k^2 / l^2)) over the
essential pieces (d_k the distance to piece k, l a quarter of the body's diameter): u^a = u on
every essential piece, and u - u^a = beta u is a smooth field every method must still find.
With lift = "exact" the field itself is the lift, so u^h = 0 is the discrete solution of every
consistent method: a linear field is then a patch test (the bubble's beta u is not linear, so no
method reproduces it exactly). Essential data that vanish need no lift.
Without [exact], data given on several pieces are blended by u^a = sum_k w_k g_k,
w_k = prod_(j != k) d_j^2 / sum_i prod_(j != i) d_j^2 (w_k = 1 on piece k): where two pieces
meet, their data must agree (a roller's tangential part is zero), or the lift's energy is
unbounded there. The errors are then measured against a body-fitted fem reference
(studies.run.reference).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.exceptions import InputError
from ibm.geometry.outline import Body
from ibm.models.elastic import Elastic
from ibm.small.model import Loads
from studies.problems.file_fields import compiled, evaluate, expression, fail, vector_field
from studies.problems.library import LOAD_TYPES, Parameters, Placed, local_stress, plastic, rotated
from studies.problems.problem import Problem
from studies.problems.problem_file import UserProblem, load_problem_file
from studies.run.small import run_small_case


@dataclass(frozen=True, eq=False)
class FileInstance(Placed):
    """A problem file placed in the grid: what a case needs (as studies.problems.library.Instance)."""

    problem: UserProblem
    parameters: object               # studies.problems.library.Parameters (material)
    body: Body
    loads: Loads
    corner: np.ndarray
    exact: object                    # x (n, 2) -> u, sigma, sigma_zz (global); None without [exact]


def _vanishes(problem: UserProblem, texts: tuple[str, str], k: int, normal_only: bool) -> bool:
    """The field's data on piece k (its normal part on a roller) vanish identically (sympy): on a straight
    piece at a + s (b - a), on an arc at c + R (cos s, sin s) with the radial normal (cos s, sin s)."""
    import sympy as sp
    x, y, s = sp.symbols("x y s", real=True)
    arc = problem.arcs[k] if problem.arcs else None
    if arc is None:
        a, b = (sp.Matrix([sp.nsimplify(v) for v in problem.vertices[j % len(problem.vertices)]]) for j in (k, k + 1))
        on, normal = a + s * (b - a), sp.Matrix([a[1] - b[1], b[0] - a[0]])
    else:   # the circle about the centre through the piece's start (nsimplify: a radius 40.00000000000001 is 40)
        radius = sp.nsimplify(float(np.hypot(*(problem.vertices[k] - arc.center))))
        normal = sp.Matrix([sp.cos(s), sp.sin(s)])
        on = sp.Matrix([sp.nsimplify(v) for v in arc.center]) + radius * normal
    u = sp.Matrix([expression(problem.path, "exact.u", t) for t in texts]).subs({x: on[0], y: on[1]})
    if normal_only:
        u = sp.Matrix([u.dot(normal)])
    return all(sp.simplify(c) == 0 for c in u)


def _on_piece(body: Body, k: int, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (m, 2) of piece k at fractions s (m,) of its length (of its sweep on an arc), and the
    outward unit normals (m, 2) there."""
    if body.arcs and body.arcs[k] is not None:
        radius, start, sweep = body.arc_angles(k)
        theta = start + s * sweep
        x = np.asarray(body.arcs[k].center, float) + radius * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    else:
        x = body.starts[k] + s[:, None] * body.tangents[k]
    return x, body.outward(k, x)


def _roller_shear(problem: UserProblem, material: Elastic) -> None:
    """InputError when the exact field has a tangential traction on a roller piece (no load carries it)."""
    _, grad, _ = compiled(problem.exact, material.lam, material.mu)
    body = problem.body(90.0, problem.start)                                   # the file's frame
    for k, kind in enumerate(problem.kinds):
        if kind != "roller":
            continue
        X, n = _on_piece(body, k, np.linspace(0.05, 0.95, 7))                 # (7, 2), outward (7, 2)
        sigma, _ = local_stress(evaluate(grad, X), material)
        t = np.stack([-n[:, 1], n[:, 0]], axis=1)
        shear = np.abs(np.einsum("pi,pij,pj->p", t, sigma, n)).max()
        scale = np.abs(sigma).max() or 1.0
        if shear > 1e-9 * scale:
            fail(problem.path, "exact.u", f"piece {k} is a roller, but the field's tangential traction there is "
                 f"{shear:.3g}, not zero (a roller carries none); make the piece fixed or change the field")


def _distances(body: Body, pieces: list[int], x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Squared distances (m, n) of points x (n, 2) to the pieces, and their gradients (m, n, 2).

    To an arc: |rho - R| where the point's angle about the centre lies in the arc's sweep, else the
    distance to the nearer end. Not differentiable at the centre (gradient 0 taken there) nor on the
    ray from it opposite the arc's middle, where the nearer end changes.
    """
    z, dz = [], []
    for k in pieces:
        arc = body.arcs[k] if body.arcs else None
        if arc is None:
            a, d = body.starts[k], body.tangents[k]
            t = np.clip((x - a) @ d / (d @ d), 0.0, 1.0)
            r = x - (a + t[:, None] * d)
            z.append(np.sum(r * r, axis=1))
            dz.append(2 * r)
            continue
        radius, start, sweep = body.arc_angles(k)
        radial = x - np.asarray(arc.center, float)                              # (n, 2)
        rho = np.hypot(radial[:, 0], radial[:, 1])
        inside = np.mod(np.arctan2(radial[:, 1], radial[:, 0]) - start - min(sweep, 0.0), 2 * np.pi) <= abs(sweep)
        ends = x[:, None, :] - np.stack([body.starts[k], body.ends[k]])          # (n, 2, 2)
        r = ends[np.arange(len(x)), np.argmin(np.sum(ends * ends, axis=2), axis=1)]   # from the nearer end
        scale = (rho - radius) / np.where(rho > 0, rho, np.inf)                   # (n,) (rho - R) / rho, 0 at c
        z.append(np.where(inside, (rho - radius) ** 2, np.sum(r * r, axis=1)))
        dz.append(2 * np.where(inside[:, None], scale[:, None] * radial, r))
    return np.array(z), np.array(dz)


def _normal(body: Body, k: int):
    """x (n, 2) -> unit normals (n, 2) of piece k: the constant inward one, or on an arc the radial
    direction about its centre (0 at the centre)."""
    arc = body.arcs[k] if body.arcs else None
    if arc is None:
        return lambda x: np.broadcast_to(body.normals[k], (len(x), 2))
    center = np.asarray(arc.center, float)

    def radial(x):
        r = x - center
        rho = np.hypot(r[:, 0], r[:, 1])
        return r / np.where(rho > 0, rho, 1.0)[:, None]
    return radial


def _normal_part(field, normal):
    """x (n, 2) -> (field . n) n (n, 2): a roller's data, with normals x -> n (n, 2)."""
    def part(x):
        n = normal(x)
        return np.sum(field(x) * n, axis=1, keepdims=True) * n
    return part


def _bubble(body: Body, pieces: list[int], length: float, x: np.ndarray):
    """beta (n,) = prod_k (1 - exp(-d_k^2 / l^2)) and grad beta (n, 2)."""
    z, dz = _distances(body, pieces, x)
    g, dg = 1 - np.exp(-z / length ** 2), np.exp(-z / length ** 2) / length ** 2
    beta = np.prod(g, axis=0)
    grad = np.zeros((len(x), 2))
    for k in range(len(pieces)):
        others = np.prod(np.delete(g, k, axis=0), axis=0)
        grad += (dg[k] * others)[:, None] * dz[k]
    return beta, grad


def _bubble_lift(body: Body, essential: list[int], field):
    """x (n, 2) -> u^a = (1 - beta) u (n, 2) and its gradient (n, 2, 2), for the field x -> (u, grad u)
    and beta of _bubble over the essential pieces (l a quarter of the body's diameter)."""
    length = 0.25 * float(np.ptp(body.vertices, axis=0).max())

    def lift(x):
        beta, grad_beta = _bubble(body, essential, length, x)
        u, G = field(x)
        return (1 - beta)[:, None] * u, (1 - beta)[:, None, None] * G - u[:, :, None] * grad_beta[:, None, :]
    return lift


def _blend(body: Body, data: dict, x: np.ndarray):
    """sum_k w_k g_k, w_k = prod_(j != k) d_j^2 / sum_i prod_(j != i) d_j^2, and its gradient (numerical)."""
    pieces = sorted(data)

    def value(points):
        z, _ = _distances(body, pieces, points)
        if len(pieces) == 1:
            w = np.ones((1, len(points)))
        else:
            products = np.array([np.prod(np.delete(z, k, axis=0), axis=0) for k in range(len(pieces))])
            total = products.sum(axis=0)
            w = products / np.where(total > 0, total, 1.0)
            on = total == 0                                           # on two pieces at once: a corner
            w[:, on] = 1.0 / len(pieces) * (z[:, on] == 0)
            w[:, on] /= np.maximum(w[:, on].sum(axis=0), 1e-300)
        return np.einsum("kp,kpi->pi", w, np.array([data[k](points) for k in pieces]))

    step = 1e-6 * max(1.0, float(np.ptp(body.vertices, axis=0).max()))
    grad = np.stack([(value(x + step * e) - value(x - step * e)) / (2 * step) for e in np.eye(2)], axis=2)
    return value(x), grad


def place_file(problem: UserProblem, material: Elastic, angle: float, offset, cell: float) -> FileInstance:
    """The problem's body at `angle` with its start point at offset * cell; loads and the exact field global."""
    material = problem.material or material
    corner = np.asarray(offset, float) * cell
    body = problem.body(angle, corner)
    R = body.frame
    lam, mu = material.lam, material.mu

    def to_file(x):
        return problem.start + (x - corner) @ R

    exact = None
    if problem.exact is not None:
        _roller_shear(problem, material)
        u_f, grad_f, b_f = compiled(problem.exact, lam, mu)

        def field_in_grid(x):   # u (n, 2) and grad u (n, 2, 2) of the exact field, grid frame
            X = to_file(x)
            return evaluate(u_f, X)[:, :, 0] @ R.T, rotated(evaluate(grad_f, X), R)

        def exact_fields(x):
            u, G = field_in_grid(x)
            return (u, *local_stress(G, material))
        exact = exact_fields

    def in_grid(field):      # a vector field of the file's frame, in the grid's
        return lambda x: field(to_file(x)) @ R.T

    if problem.body_force is not None:
        body_force = in_grid(vector_field(problem.body_force))
    elif exact is not None:
        body_force = in_grid(lambda X: evaluate(b_f, X)[:, :, 0])
    else:
        body_force = None
    tractions = {}
    for k in body.edges_of_kind("traction"):
        if k in problem.traction:
            tractions[k] = in_grid(vector_field(problem.traction[k]))
        elif exact is not None:
            tractions[k] = (lambda k: lambda x: np.einsum("pij,pj->pi", exact(x)[1], body.outward(k, x)))(k)
    essential = body.essential_edges
    lift = None
    if exact is not None and not all(_vanishes(problem, problem.exact, k, body.kinds[k] == "roller")
                                     for k in essential):
        lift = field_in_grid if problem.lift == "exact" else _bubble_lift(body, essential, field_in_grid)
    elif exact is None and problem.displacement:
        data = {}
        for k, texts in problem.displacement.items():
            field = in_grid(vector_field(texts))
            if body.kinds[k] == "roller":
                field = _normal_part(field, _normal(body, k))
            data[k] = field
        if not all(_vanishes(problem, problem.displacement[k], k, body.kinds[k] == "roller") for k in data):
            def lift(x):
                return _blend(body, data, x)
    loads = Loads(body_force=body_force, tractions=tractions, lift=lift)
    return FileInstance(problem, Parameters(material, 1.0), body, loads, corner, exact)


# --- as a problem of a study (studies.problems.problem) --------------------------------------

class ProblemFile(Problem):
    """The problem a case's problem_file defines, solved at small kinematics (its name is the file's)."""

    name = "problem-file"
    summary = "a problem of your own: a TOML file with the outline, material, loads and optional exact field"
    from_file = True

    def load_types(self) -> tuple[str, ...]:
        return LOAD_TYPES               # the file's loads are its own: the load type is not read

    def size(self, spec) -> float:
        return float(np.ptp(load_problem_file(spec.problem_file).vertices, axis=0).max())

    def validate(self, spec) -> None:
        load_problem_file(spec.problem_file)
        if spec.kinematics != "small":
            raise InputError(f"kinematics {spec.kinematics!r} is not allowed with a problem file; problem files "
                             "are solved at small kinematics")
        if plastic(spec):
            raise InputError(f"material {spec.material!r} is not allowed with a problem file; problem files are "
                             "linear elastic")

    def instance(self, spec) -> FileInstance:
        return place_file(load_problem_file(spec.problem_file), Elastic(spec.E, spec.nu), spec.angle, spec.offset,
                          spec.cell)

    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        return run_small_case(spec, self.instance(spec), keep_fields, solver)


PROBLEM_FILE = ProblemFile()
