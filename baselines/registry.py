"""Every boundary method behind one signature: solve(model, **parameters) -> Solution.

Tests and studies parametrize over METHODS; each method declares the parameters it reads
and their defaults, so callers can pass one settings record to any method.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ibm.model import Model, Solution
from ibm.method import solve_ibm


@dataclass(frozen=True)
class Method:
    name: str
    solve: Callable[..., Solution]
    parameters: dict[str, float] = field(default_factory=dict)   # name -> default
    summary: str = ""

    def __call__(self, model: Model, **settings) -> Solution:
        """Solve, reading only this method's own parameters from `settings`."""
        chosen = {k: settings[k] if settings.get(k) is not None else v for k, v in self.parameters.items()}
        return self.solve(model, **chosen)


METHODS: dict[str, Method] = {}


def register(method: Method) -> Method:
    METHODS[method.name] = method
    return method


register(Method("ibm", solve_ibm, {"delta_rel": 1e-5, "support_threshold": 1e-4},
                "implicit boundary method, band form (Dirichlet functions in a band of width delta)"))
