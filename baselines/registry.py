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


def _register_baselines() -> None:
    """The boundary-method baselines (imported here so METHODS always lists every method)."""
    from baselines.fem import solve_fem
    from baselines.lagrange import DEFAULT_AUGMENT, solve_lagrange, solve_lagrange_nodal
    from baselines.limit import DEFAULT_DELTA_REL, solve_limit
    from baselines.nodal import solve_nodal
    from baselines.nitsche import DEFAULT_GAMMA, solve_nitsche
    from baselines.penalty import DEFAULT_BETA0, solve_penalty

    register(Method("ibm-limit", solve_limit, {"delta_rel": DEFAULT_DELTA_REL, "support_threshold": 1e-4},
                    "implicit boundary method, delta -> 0 boundary-integral form"))
    register(Method("penalty", solve_penalty, {"beta0": DEFAULT_BETA0, "support_threshold": 1e-4},
                    "boundary-integral penalty, beta = beta0 M / h"))
    register(Method("nitsche", solve_nitsche, {"gamma": DEFAULT_GAMMA, "support_threshold": 1e-4},
                    "symmetric Nitsche, stabilisation gamma M / h"))
    register(Method("lagrange", solve_lagrange, {"augment": DEFAULT_AUGMENT, "support_threshold": 1e-4},
                    "Lagrange multipliers, one constant per edge piece in a cut cell (stable)"))
    register(Method("lagrange-nodal", solve_lagrange_nodal, {"support_threshold": 1e-4},
                    "Lagrange multipliers collocated at grid-line crossings (naive, inf-sup unstable)"))
    register(Method("nodal", solve_nodal, {},
                    "strong constraints on the grid nodes of essential edges (edges on grid lines only)"))
    register(Method("fem", solve_fem, {},
                    "body-fitted finite elements (scikit-fem), rollers imposed strongly"))


_register_baselines()
