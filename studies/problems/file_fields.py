"""The fields of a problem file (studies.problems.problem_file): sympy expressions in x and y, checked
when the file is read and compiled to numpy functions of the file-frame points (u, grad u and
b = -div sigma of an exact field).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ibm.exceptions import InputError

SYMBOLS = ("x", "y")


def fail(path, key: str, message: str):
    raise InputError(f"problem file {path}: {key}: {message}")


def expression(path, key: str, text: str):
    import sympy as sp
    x, y = sp.symbols("x y", real=True)
    try:
        parsed = sp.sympify(text, locals={"x": x, "y": y, "pi": sp.pi, "E": sp.E})
    except (sp.SympifyError, SyntaxError, TypeError, ValueError):
        fail(path, key, f"{text!r} does not parse as an expression in x and y")
    if not isinstance(parsed, sp.Expr):
        fail(path, key, f"{text!r} is not an expression in x and y")
    other = sorted(str(s) for s in parsed.free_symbols - {x, y})
    if other:
        fail(path, key, f"{text!r} names {', '.join(other)}; only x and y are allowed")
    return parsed


@lru_cache(maxsize=64)
def compiled(texts: tuple[str, ...], lam: float, mu: float):
    """numpy functions of (x, y) for u (2,), grad u (2, 2) and b = -div sigma (2,) of the field texts."""
    import sympy as sp
    x, y = sp.symbols("x y", real=True)
    u = sp.Matrix([expression("", "u", t) for t in texts])
    grad = sp.Matrix(2, 2, lambda i, j: sp.diff(u[i], (x, y)[j]))
    eps = (grad + grad.T) / 2
    sigma = 2 * mu * eps + lam * eps.trace() * sp.eye(2)
    b = sp.Matrix([-sp.diff(sigma[i, 0], x) - sp.diff(sigma[i, 1], y) for i in range(2)])
    return tuple(sp.lambdify((x, y), m.tolist(), modules="numpy") for m in (u, grad, b))


def evaluate(function, X: np.ndarray) -> np.ndarray:
    """(n, ...) values of a lambdified nested list at file-frame points X (n, 2)."""
    rows = function(X[:, 0], X[:, 1])
    value = np.array([[np.broadcast_to(np.asarray(v, float), X[:, 0].shape) for v in row] for row in rows])
    return np.moveaxis(value, -1, 0)


def vector_field(texts: tuple[str, str]):
    u, _, _ = compiled(texts, 0.0, 0.0)
    return lambda X: evaluate(u, X)[:, :, 0]
