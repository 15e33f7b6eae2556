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

A third expression u_zeta makes the field 3D, on a box L x H x W (along xi, eta, zeta):
the names are then xi, eta, zeta, L, H, W (W = prm.depth), p, lam, mu, M; the stress is
the full isotropic sigma = lam tr(eps) I + 2 mu eps, b (3,), and the tractions are on the
six faces FACES; field(xi, eta, zeta, prm) -> (u (n, 3), grad (n, 3, 3)).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

NAMES = ("xi", "eta", "L", "H", "p", "lam", "mu")
SIDES = ("base", "right", "top", "left")
OUTWARD = {"base": (0, -1), "right": (1, 0), "top": (0, 1), "left": (-1, 0)}   # local outward normals

# 3D: the box's faces in order (the first four are the rectangle's sides), outward local normals
NAMES_3D = ("xi", "eta", "zeta", "L", "H", "W", "p", "lam", "mu")
FACES = ("base", "right", "top", "left", "front", "back")
OUTWARD_3D = {"base": (0, -1, 0), "right": (1, 0, 0), "top": (0, 1, 0), "left": (-1, 0, 0),
              "front": (0, 0, -1), "back": (0, 0, 1)}


@dataclass(frozen=True)
class Derivation:
    """Symbolic u (d,), grad (d, d), sigma (d, d), body force (d,), traction per side (d,); d = 2 or 3."""

    symbols: dict
    u: object
    grad: object
    sigma: object
    body_force: object
    traction: dict

    @property
    def dimension(self) -> int:
        return self.u.shape[0]


@lru_cache(maxsize=None)
def derive(u_xi: str, u_eta: str, u_zeta: str | None = None) -> Derivation:
    """Differentiate the field: gradient, stress, b = -div sigma, tractions sigma n (sympy).

    u_zeta None: plane strain on the rectangle (SIDES); else 3D on the box (FACES)."""
    import sympy as sp

    if u_zeta is not None:
        return _derive_3d(u_xi, u_eta, u_zeta)
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


def _derive_3d(u_xi: str, u_eta: str, u_zeta: str) -> Derivation:
    """derive's 3D case: the full isotropic stress on the box, tractions on the six FACES."""
    import sympy as sp

    s = {name: sp.Symbol(name, real=True) for name in NAMES_3D}
    namespace = {**s, "M": s["lam"] + 2 * s["mu"], "pi": sp.pi}   # (zeta here is the coordinate, not sympy's function)
    u = sp.Matrix([sp.sympify(text, locals=namespace) for text in (u_xi, u_eta, u_zeta)])
    x = (s["xi"], s["eta"], s["zeta"])
    grad = sp.Matrix(3, 3, lambda i, j: sp.diff(u[i], x[j]))
    eps = (grad + grad.T) / 2
    sigma = 2 * s["mu"] * eps + s["lam"] * eps.trace() * sp.eye(3)
    # cancel, not simplify: the same rational functions of the trigonometric terms, in a fifth of the time
    body_force = sp.Matrix([sp.cancel(-sum(sp.diff(sigma[i, j], x[j]) for j in range(3))) for i in range(3)])
    face = {"base": {s["eta"]: 0}, "right": {s["xi"]: s["L"]}, "top": {s["eta"]: s["H"]}, "left": {s["xi"]: 0},
            "front": {s["zeta"]: 0}, "back": {s["zeta"]: s["W"]}}
    traction = {side: sp.cancel((sigma * sp.Matrix(OUTWARD_3D[side])).subs(face[side])) for side in FACES}
    return Derivation(s, u, grad, sigma, body_force, traction)


@lru_cache(maxsize=None)
def _compiled(texts: tuple[str, ...], what: str):
    """numpy function of NAMES (2D) or NAMES_3D (3D) -> nested list of arrays/scalars."""
    import sympy as sp

    d = derive(*texts)
    expression = {"u": d.u, "grad": d.grad, "body_force": d.body_force}.get(what)
    if expression is None:
        expression = d.traction[what]
    names = NAMES if len(texts) == 2 else NAMES_3D
    return sp.lambdify([d.symbols[name] for name in names], expression.tolist(), modules="numpy")


def _evaluate(texts: tuple[str, ...], what: str, coordinates: tuple, prm) -> np.ndarray:
    coordinates = tuple(np.asarray(c, float) for c in coordinates)
    m = prm.material
    sizes = (prm.width, prm.height) if len(texts) == 2 else (prm.width, prm.height, prm.depth)
    rows = _compiled(texts, what)(*coordinates, *sizes, prm.load, m.lam, m.mu)
    # constants come back as Python scalars: broadcast every entry to the points' shape
    shape = coordinates[0].shape
    value = np.array([[np.broadcast_to(np.asarray(v, float), shape) for v in row] for row in rows])
    return np.moveaxis(value, -1, 0)                       # (n, rows, cols)


@dataclass(frozen=True)
class Field:
    """A displacement field in the local frame, as sympy source text (see module doc);
    u_zeta given: a 3D field, called with the three coordinates xi, eta, zeta."""

    u_xi: str
    u_eta: str
    u_zeta: str | None = None

    @property
    def texts(self) -> tuple[str, ...]:
        return (self.u_xi, self.u_eta) if self.u_zeta is None else (self.u_xi, self.u_eta, self.u_zeta)

    @property
    def dimension(self) -> int:
        return len(self.texts)

    def _split(self, args: tuple) -> tuple[tuple, object]:
        """(coordinates, prm) from (xi, eta, prm) in 2D or (xi, eta, zeta, prm) in 3D."""
        if len(args) != self.dimension + 1:
            names = ("xi, eta" if self.dimension == 2 else "xi, eta, zeta") + ", prm"
            raise TypeError(f"a {self.dimension}D field takes ({names}); got {len(args)} arguments")
        return args[:-1], args[-1]

    def __call__(self, *args) -> tuple[np.ndarray, np.ndarray]:
        """(xi, eta[, zeta], prm) -> u (n, d) and grad (n, d, d), grad[p, i, j] = d u_i / d x_j, local frame."""
        coordinates, prm = self._split(args)
        return (_evaluate(self.texts, "u", coordinates, prm)[:, :, 0],
                _evaluate(self.texts, "grad", coordinates, prm))

    def body_force(self, *args) -> np.ndarray:
        """(xi, eta[, zeta], prm) -> b = -div sigma (n, d), local frame."""
        coordinates, prm = self._split(args)
        return _evaluate(self.texts, "body_force", coordinates, prm)[:, :, 0]

    def traction(self, side: str, *args) -> np.ndarray:
        """(side, xi, eta[, zeta], prm) -> sigma n (n, d) with n the outward normal of `side`
        (one of SIDES in 2D, FACES in 3D), local frame."""
        coordinates, prm = self._split(args)
        return _evaluate(self.texts, side, coordinates, prm)[:, :, 0]

    def derivation(self) -> Derivation:
        return derive(*self.texts)
