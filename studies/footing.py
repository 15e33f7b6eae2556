"""Prandtl's strip footing at small strain: a smooth rigid footing pushed into weightless von Mises soil.

Half model in the local frame (xi along the base, eta up): width W, depth H, the base fixed, the
far side and the symmetry line (xi = 0) rollers, the footing a roller wall on the top from
xi = 0 to B / 2 moved down by the settlement, the rest of the top free. The collapse pressure of
a Tresca (von Mises in plane strain: c = sigma_y / sqrt(3)) weightless half-space is
q = (2 + pi) c = 5.142 c, smooth or rough.

The footing's force comes from the domain: with v = (eta / H) e_eta, which vanishes on the base
and has no normal component on the two side rollers (whose shear traction is zero), equilibrium
gives the footing's resultant as int sigma : grad v = (1 / H) int sigma_eta_eta over the body; the
mean footing pressure is q = -(1 / H) sum_p V_p sigma_eta_eta,p / (B / 2). For each grid method it
is its own footing force (the test field lies in the grid's space), so the same sum serves every
grid method; `fem` (baselines.fem_plastic) takes the residual at the footing's constrained DOFs.
"""
from __future__ import annotations

import numpy as np

PRANDTL = 2 + np.pi


def footing_body(width: float, depth: float, footing: float, angle: float, corner: np.ndarray):
    """The half model (local frame rotated by angle - 90 degrees like every problem)."""
    from ibm.geometry import Body, frame_of_angle
    R = frame_of_angle(angle)
    local = np.array([[0.0, 0.0], [width, 0.0], [width, depth], [footing / 2, depth], [0.0, depth]])
    kinds = ("fixed", "roller", "free", "roller", "roller")     # base, far side, free top, footing, symmetry
    return Body(np.asarray(corner, float) + local @ R.T, kinds, frame=R), R


def run_footing(method: str, angle: float = 90.0, offset=(0.37, 0.29), B_over_h: float = 16, B: float = 1.0,
                width_over_B: float = 5.0, depth_over_B: float = 3.0, settlement_over_B: float = 0.02,
                steps: int = 40, ppc: int = 2, basis: str = "mpm", locking: str = "fbar",
                yield_stress: float = 100.0, E: float = 1e5, nu: float = 0.3, parameters: dict | None = None) -> dict:
    """Settle the footing by settlement_over_B * B in `steps` steps; q per step, q_max / c."""
    from baselines.steps import treatment
    from ibm.loadsteps import Loading, Setup, run
    from ibm.newton import StepFailure
    from ibm.small_strain import VonMises

    h = B / B_over_h
    corner = np.asarray(offset, float) * h
    W, H = width_over_B * B, depth_over_B * B
    body, R = footing_body(W, H, B, angle, corner)
    motion = np.zeros(len(body.essential_edges))
    motion[body.essential_edges.index(3)] = settlement_over_B * B
    setup = Setup(body, VonMises(E, nu, yield_stress=yield_stress), Loading(wall_motion=motion), h, ppc, basis,
                  steps, locking=locking)
    c = yield_stress / np.sqrt(3)
    curve = []

    def after_step(progress):
        s_eta = np.einsum("i,pij,j->p", R[:, 1], progress.sigma[:, :2, :2], R[:, 1])
        q = -float(np.sum(progress.V0 * s_eta)) / H / (B / 2)
        curve.append((progress.t * settlement_over_B * B, q))
        return {"q": q}

    failure = None
    try:
        if method == "fem":        # body-fitted P2, the footing's nodes moved (baselines.fem_plastic)
            from baselines.fem_plastic import run_fem_plastic

            def after_fem_step(record):      # the residual at the footing's constrained DOFs
                q = abs(float(record["forces"][3] @ R[:, 1])) / (B / 2)
                curve.append((record["t"] * settlement_over_B * B, q))
                return {"q": q}
            run_fem_plastic(body, setup.material, {}, h, steps, after_step=after_fem_step, motions={3: motion[2]})
        else:
            run(setup, treatment(method, parameters or {}), after_step=after_step)
    except StepFailure as error:
        failure = str(error)
    q = np.array([q for _, q in curve])
    return {"method": method, "angle": angle, "B_over_h": B_over_h, "locking": locking, "c": c,
            "q_max": float(q.max(initial=0.0)), "q_over_c": float(q.max(initial=0.0) / c),
            "settlement": [s for s, _ in curve], "q": q.tolist(), "stopped": failure}
