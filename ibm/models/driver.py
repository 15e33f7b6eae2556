"""A material-point driver with mixed control: some components of a small-strain increment given,
one normal component found so that its stress reaches a target (docs/contact.md, the passive wall).

A homogeneous state of a body (a layer pushed between smooth walls, each fibre at its own
overburden) is the response of one material point to such a mixed increment: with the strain
increment d eps given except d eps_kk, Newton on d eps_kk solves sigma_kk(d eps) = target with the
model's own algorithmic modulus C_kkkk (ibm.models.small_strain), vectorised over points.
"""
from __future__ import annotations

import numpy as np

from ibm.exceptions import InputError, NotConverged
from ibm.models.constitutive import Response, State

ITERATIONS = 50
TOLERANCE = 1e-12        # on |sigma_kk - target| relative to the stress's largest entry (and 1)


def mixed_increment(model, state: State, increment: np.ndarray, component: int, target: np.ndarray,
                    dim: int = 2) -> Response:
    """The response to the strain increment `increment` (n, 3, 3) (symmetric; its (k, k) entry, k =
    `component`, is found) that brings sigma_kk to `target` (n,), from the converged `state` of a
    small-strain model. Raises NotConverged when Newton does not settle in ITERATIONS."""
    if getattr(model, "kinematics", "") != "small":
        raise InputError(f"the mixed driver is for small-strain models; got {type(model).__name__}")
    if not 0 <= component < dim:
        raise InputError(f"component {component} is not allowed; allowed: 0 to {dim - 1}")
    grad = np.array(increment, float)
    grad[:, component, component] = 0.0
    eye = np.eye(3)
    for _ in range(ITERATIONS):
        response = model.update(eye + grad, state, dim=dim)
        residual = response.sigma[:, component, component] - target
        scale = np.maximum(np.abs(response.sigma).max(axis=(1, 2)), 1.0)
        if np.all(np.abs(residual) <= TOLERANCE * scale):
            return response
        stiffness = response.tangent[:, component, component, component, component]
        grad[:, component, component] -= residual / stiffness
    raise NotConverged(f"the mixed driver did not reach sigma_{component}{component} in {ITERATIONS} iterations "
                       f"(largest residual {np.abs(residual).max():.3g})")
