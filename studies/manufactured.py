"""Displacement fields given as sympy source text, and what sympy derives from them.

A field is declared in a problem's local frame (xi along the base, eta inward normal to
the base) as two expressions in

    xi, eta    local coordinates
    L, H       width and height of the rectangle
    p          the problem's load value (a stress, or the settlement for settlement loading)
    lam, mu, M Lame constants and the P-wave modulus lam + 2 mu

From it sympy derives, once per field (cached), the gradient, the plane-strain stress,
the body force b = -div sigma and the tractions sigma n on the four sides; each is then
lambdified to a vectorised numpy function. Fields are frozen dataclasses, so a problem
declares them as data and calls them as LocalField functions: field(xi, eta, prm) ->
(u (n, 2), grad (n, 2, 2)).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

NAMES = ("xi", "eta", "L", "H", "p", "lam", "mu")
SIDES = ("base", "right", "top", "left")
OUTWARD = {"base": (0, -1), "right": (1, 0), "top": (0, 1), "left": (-1, 0)}   # local outward normals


@dataclass(frozen=True)
class Derivation:
    """Symbolic u (2,), grad (2, 2), sigma (2, 2), body force (2,), traction per side (2,)."""

    symbols: dict
    u: object
    grad: object
    sigma: object
    body_force: object
    traction: dict


@lru_cache(maxsize=None)
def derive(u_xi: str, u_eta: str) -> Derivation:
    """Differentiate the field: gradient, stress, b = -div sigma, tractions sigma n (sympy)."""
    import sympy as sp

    s = {name: sp.Symbol(name, real=True) for name in NAMES}
    namespace = {**s, "M": s["lam"] + 2 * s["mu"], "pi": sp.pi}
    u = sp.Matrix([sp.sympify(u_xi, locals=namespace), sp.sympify(u_eta, locals=namespace)])
    x = (s["xi"], s["eta"])
    grad = sp.Matrix(2, 2, lambda i, j: sp.diff(u[i], x[j]))
    eps = (grad + grad.T) / 2
    sigma = 2 * s["mu"] * eps + s["lam"] * eps.trace() * sp.eye(2)
    body_force = sp.Matrix([sp.simplify(-sum(sp.diff(sigma[i, j], x[j]) for j in range(2))) for i in range(2)])
    edge = {"base": {s["eta"]: 0}, "right": {s["xi"]: s["L"]}, "top": {s["eta"]: s["H"]}, "left": {s["xi"]: 0}}
    traction = {side: sp.simplify((sigma * sp.Matrix(OUTWARD[side])).subs(edge[side])) for side in SIDES}
    return Derivation(s, u, grad, sigma, body_force, traction)


@lru_cache(maxsize=None)
def _compiled(u_xi: str, u_eta: str, what: str):
    """numpy function (xi, eta, L, H, p, lam, mu) -> nested list of arrays/scalars."""
    import sympy as sp

    d = derive(u_xi, u_eta)
    expression = {"u": d.u, "grad": d.grad, "body_force": d.body_force}.get(what)
    if expression is None:
        expression = d.traction[what]
    return sp.lambdify([d.symbols[name] for name in NAMES], expression.tolist(), modules="numpy")


def _evaluate(u_xi, u_eta, what, xi, eta, prm) -> np.ndarray:
    xi, eta = np.asarray(xi, float), np.asarray(eta, float)
    m = prm.material
    rows = _compiled(u_xi, u_eta, what)(xi, eta, prm.width, prm.height, prm.load, m.lam, m.mu)
    # constants come back as Python scalars: broadcast every entry to the points' shape
    value = np.array([[np.broadcast_to(np.asarray(v, float), xi.shape) for v in row] for row in rows])
    return np.moveaxis(value, -1, 0)                       # (n, rows, cols)


@dataclass(frozen=True)
class Field:
    """A displacement field in the local frame, as sympy source text (see module doc)."""

    u_xi: str
    u_eta: str

    def __call__(self, xi, eta, prm) -> tuple[np.ndarray, np.ndarray]:
        """u (n, 2) and grad (n, 2, 2), grad[p, i, j] = d u_i / d x_j, local frame."""
        return (_evaluate(self.u_xi, self.u_eta, "u", xi, eta, prm)[:, :, 0],
                _evaluate(self.u_xi, self.u_eta, "grad", xi, eta, prm))

    def body_force(self, xi, eta, prm) -> np.ndarray:
        """b = -div sigma (n, 2), local frame."""
        return _evaluate(self.u_xi, self.u_eta, "body_force", xi, eta, prm)[:, :, 0]

    def traction(self, side: str, xi, eta, prm) -> np.ndarray:
        """sigma n (n, 2) with n the outward normal of `side` (one of SIDES), local frame."""
        return _evaluate(self.u_xi, self.u_eta, side, xi, eta, prm)[:, :, 0]

    def derivation(self) -> Derivation:
        return derive(self.u_xi, self.u_eta)
