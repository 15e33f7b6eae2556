"""Problems with exact solutions, as data.

A problem is a rectangle (width L, height H) in its local frame (xi along the base, eta
inward normal to the base), one boundary kind per side (base, right, top, left), and an
exact displacement field in that frame. Stresses, tractions on traction sides and the
rotation into the grid at angle theta are derived here once for every problem:
u = R u_loc, grad u = R grad_loc R^T, sigma = R sigma_loc R^T.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ibm.geometry import Body, InputError, rectangle
from ibm.material import Elastic
from ibm.model import Loads

# (xi, eta) arrays, parameters -> u_loc (n, 2), grad_loc (n, 2, 2) with grad[p, i, j] = d u_i / d x_j
LocalField = Callable[[np.ndarray, np.ndarray, "Parameters"], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Parameters:
    """Physical parameters of a problem instance (units are consistent but arbitrary)."""

    material: Elastic
    load: float          # pressure p (or the problem's load scale)
    width: float = 100.0
    height: float = 100.0


@dataclass(frozen=True)
class Problem:
    name: str
    summary: str
    kinds: tuple[str, str, str, str]          # base, right, top, left
    exact: LocalField
    body_force: Callable[[np.ndarray, np.ndarray, Parameters], np.ndarray] | None = None  # local (n, 2)
    lift: LocalField | None = None
    reported: str = "sigma_eta_eta"           # the stress component err_sigma reports


def local_stress(grad: np.ndarray, material: Elastic) -> tuple[np.ndarray, np.ndarray]:
    """Plane-strain stress (n, 2, 2) and sigma_zz (n,) from a displacement gradient (n, 2, 2)."""
    eps = 0.5 * (grad + grad.transpose(0, 2, 1))
    trace = eps[:, 0, 0] + eps[:, 1, 1]
    sigma = 2 * material.mu * eps + material.lam * trace[:, None, None] * np.eye(2)
    return sigma, material.lam * trace


@dataclass(frozen=True, eq=False)
class Instance:
    """A problem placed in the grid: the body, its loads and the exact fields (global frame)."""

    problem: Problem
    parameters: Parameters
    body: Body
    loads: Loads
    corner: np.ndarray

    @property
    def frame(self) -> np.ndarray:
        return self.body.frame

    @property
    def direction(self) -> np.ndarray:
        """Unit e_eta: the loaded direction whose normal stress err_sigma reports."""
        return self.frame[:, 1]

    def to_local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xl = (x - self.corner) @ self.frame
        return xl[:, 0], xl[:, 1]

    def exact(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u (n, 2), sigma (n, 2, 2), sigma_zz (n,) at global points x (n, 2)."""
        R = self.frame
        u, grad = self.problem.exact(*self.to_local(x), self.parameters)
        sigma, zz = local_stress(grad, self.parameters.material)
        return u @ R.T, R @ sigma @ R.T, zz

    def exact_gradient(self, x: np.ndarray) -> np.ndarray:
        _, grad = self.problem.exact(*self.to_local(x), self.parameters)
        return self.frame @ grad @ self.frame.T


def place(problem: Problem, parameters: Parameters, angle: float, offset, cell: float) -> Instance:
    """Put the problem's body at `angle` with its base corner at offset * cell from a grid node."""
    corner = np.asarray(offset, float) * cell
    body = rectangle(parameters.width, parameters.height, problem.kinds, angle, corner)
    R = body.frame

    def to_local(x):
        xl = (x - corner) @ R
        return xl[:, 0], xl[:, 1]

    def traction_on(edge):
        outward = -body.normals[edge]

        def traction(x):
            _, grad = problem.exact(*to_local(x), parameters)
            sigma, _ = local_stress(grad, parameters.material)
            return np.einsum("ij,pjk,lk,l->pi", R, sigma, R, outward)
        return traction

    body_force = None
    if problem.body_force is not None:
        def body_force(x):
            return problem.body_force(*to_local(x), parameters) @ R.T

    lift = None
    if problem.lift is not None:
        def lift(x):
            u, grad = problem.lift(*to_local(x), parameters)
            return u @ R.T, R @ grad @ R.T

    tractions = {k: traction_on(k) for k in body.edges_of_kind("traction")}
    loads = Loads(body_force=body_force, tractions=tractions, lift=lift)
    return Instance(problem, parameters, body, loads, corner)


# --- the problem library -------------------------------------------------------------

def _confined_block(xi, eta, prm: Parameters):
    """Rollers on base and sides, pressure p on top: u_eta = -(p/M) eta, u_xi = 0."""
    strain = -prm.load / prm.material.M
    u = np.stack([np.zeros_like(eta), strain * eta], axis=1)
    grad = np.zeros((len(eta), 2, 2))
    grad[:, 1, 1] = strain
    return u, grad


PROBLEMS: dict[str, Problem] = {}


def register(problem: Problem) -> Problem:
    PROBLEMS[problem.name] = problem
    return problem


register(Problem(
    "confined-block",
    "square, rollers on base and sides, uniform pressure on top (the seed's validation problem)",
    ("roller", "roller", "traction", "roller"), _confined_block))


def get_problem(name: str) -> Problem:
    if name not in PROBLEMS:
        from difflib import get_close_matches
        close = get_close_matches(name, PROBLEMS, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise InputError(f"unknown problem {name!r}{hint}; allowed: {', '.join(PROBLEMS)}")
    return PROBLEMS[name]
