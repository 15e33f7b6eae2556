"""The passive wall: a smooth rigid wall pushed into a von Mises (Tresca in plane strain) or frictional layer
on a smooth rigid base (docs/contact.md). Exact at every load step; Rankine's passive force at the limit.

In the layer's frame (xi along the base, eta up), length L = width, height H, plane strain: the base
and the far side (xi = L) are smooth fixed walls (rollers), the top is free, and the near side
(xi = 0) is a smooth contact wall pushed into the layer by s(t) = t s (s the `load`), while the
soil's weight gamma (--unit-weight) is ramped with it. Smooth walls leave each fibre eta of the
layer in one homogeneous state:

    eps_xi_xi = -s(t) / L,   eps_xi_eta = 0,   sigma_eta_eta = -t gamma (H - eta),

with eps_eta_eta(eta) what the material needs for that sigma_eta_eta (ibm.models.driver, the
same load steps: the run's increments are the reference's), u_xi = s(t) (1 - xi / L) and u_eta
= int_0^eta eps_eta_eta. Equilibrium holds (sigma depends on eta only, sigma_xi_eta = 0, the
weight carried by sigma_eta_eta), so every consistent contact method reproduces it; the
weightless layer's field is linear, so to round-off. The wall carries P(t) = -int_0^H sigma_xi_xi
d eta. Pushed on, the state reaches Rankine's passive one, sigma_xi_xi = sigma_eta_eta - 2 c with
c = sigma_y / sqrt(3) (von Mises in plane strain, its out-of-plane stress the in-plane mean), so

    P -> P_rankine = gamma H^2 / 2 + 2 c H,

exact for this smooth wall (the state is both statically and kinematically admissible). A Mohr-Coulomb
layer (c, phi; studies.problems.materials) reaches sigma_xi_xi = K_p sigma_eta_eta - 2 c sqrt(K_p) with
K_p = (1 + sin phi) / (1 - sin phi), so P -> gamma H^2 K_p / 2 + 2 c H sqrt(K_p); so does the matched
Drucker-Prager cone with associated flow, once its out-of-plane plastic strain rate has died out.
"""
from __future__ import annotations

from time import perf_counter

import numpy as np

from baselines.registry import METHODS, treatment
from ibm.exceptions import InputError
from ibm.geometry.outline import rectangle
from ibm.large.loadsteps import Loading, Setup, run
from ibm.models.driver import mixed_increment
from studies.problems.contact import ContactProblem, contact_law, contact_record, relative_norm
from studies.problems.materials import FRICTIONAL, VON_MISES, dilation, material_record, model_of

KINDS = ("roller", "roller", "free", "roller")      # base, far side, free top, the pushed wall (contact)
PUSH = 0.05              # the default push per layer length: 5 yield strains at E = 1e4, sigma_y = 100
SAMPLES = 2001           # fibres across the height for P and u_eta (trapezoid; exact for the linear field)


class HomogeneousLayer:
    """The layer's exact state, fibre by fibre at heights eta (m,), advanced over the run's load steps."""

    def __init__(self, material, eta: np.ndarray, height: float, unit_weight: float, strain: float):
        self.material, self.eta, self.height = material, eta, height
        self.unit_weight, self.strain = unit_weight, strain       # strain: eps_xi_xi at t = 1 (< 0)
        self.times, self.state, self.sigma = [0.0], material.initial(len(eta)), np.zeros((len(eta), 3, 3))

    def at(self, times: list[float]) -> np.ndarray:
        """sigma (m, 3, 3) after the steps ending at `times` (from t = 0 again unless they extend the last)."""
        if times[:len(self.times) - 1] != self.times[1:]:
            self.times, self.state = [0.0], self.material.initial(len(self.eta))
        for t in times[len(self.times) - 1:]:
            increment = np.zeros((len(self.eta), 3, 3))
            increment[:, 0, 0] = (t - self.times[-1]) * self.strain
            target = -t * self.unit_weight * (self.height - self.eta)
            response = mixed_increment(self.material, self.state, increment, 1, target)
            self.times.append(t)
            self.state, self.sigma = response.state, response.sigma
        return self.sigma

    def strain_eta(self) -> np.ndarray:
        """eps_eta_eta (m,) of the last state."""
        return self.state.F[:, 1, 1] - 1.0


def rankine_force(spec) -> float | None:
    """Rankine's passive force gamma H^2 K_p / 2 + 2 c H sqrt(K_p), K_p = (1 + sin phi) / (1 - sin phi) (von Mises:
    c = sigma_y / sqrt(3), K_p = 1), where the material's limit state is Mohr-Coulomb's in plane strain (not with
    hardening, nor for the cone with non-associated flow); None elsewhere."""
    if spec.material in FRICTIONAL:
        if spec.material == "drucker-prager" and dilation(spec) != spec.friction_angle:
            return None
        c, sine = spec.cohesion, np.sin(np.radians(spec.friction_angle))
    elif spec.hardening == 0:
        c, sine = spec.yield_stress / np.sqrt(3), 0.0
    else:
        return None
    K = (1 + sine) / (1 - sine)
    return spec.unit_weight * spec.height ** 2 * K / 2 + 2 * c * spec.height * np.sqrt(K)


class PassiveWall(ContactProblem):
    name = "passive-wall"
    summary = ("a smooth rigid wall pushed into a von Mises or frictional layer on a smooth base: the exact state "
               "at every step, Rankine's passive force at the limit")
    compared = {"P": ("P", "P_exact"), "P against Rankine": ("P", "P_rankine")}
    materials = (*VON_MISES, *FRICTIONAL)
    material_example = "e.g. --material von-mises --yield-stress 100, or --material mohr-coulomb --cohesion 50"
    weight = True

    def load_types(self) -> tuple[str, ...]:
        return ("settlement",)

    def default_load(self, width: float, height: float) -> float:
        return PUSH * width

    def locking_applies(self, spec) -> bool:
        return True

    def validate(self, spec) -> None:
        super().validate(spec)
        if spec.friction or spec.adhesion:
            raise InputError(f"problem {self.name!r} has a smooth wall (its exact state needs one); got friction "
                             f"{spec.friction:g} and adhesion {spec.adhesion:g}")
        largest = 0.1 * spec.width
        if not 0 < spec.load <= largest:
            raise InputError(f"load {spec.load:g} (the wall's push) is not allowed for problem {self.name!r}; it must "
                             f"be in (0, width / 10 = {largest:g}] (small strain; the default {PUSH:g} width is 5 "
                             "yield strains at E = 1e4, sigma_y = 100)")

    def setup(self, spec):
        """The load steps' setup, the body's corner (2,) and its frame (2, 2)."""
        material = model_of(spec, "small")
        corner = np.asarray(spec.offset, float) * spec.cell
        body = rectangle(spec.width, spec.height, KINDS, spec.angle, corner)
        motion = np.zeros(len(body.essential_edges))
        motion[body.essential_edges.index(3)] = spec.load
        loading = Loading(body_force=-spec.unit_weight * body.frame[:, 1], wall_motion=motion)
        setup = Setup(body, material, loading, spec.cell, spec.ppc, spec.basis, spec.steps, locking=spec.locking,
                      contact={3: contact_law(spec)})
        return setup, corner, body.frame

    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        start = perf_counter()
        setup, corner, R = self.setup(spec)
        L, H, gamma = spec.width, spec.height, spec.unit_weight
        rankine = rankine_force(spec)
        fibres = np.linspace(0.0, H, SAMPLES)
        layer: list[HomogeneousLayer] = []           # made on the first step (the points' heights)

        def after_step(p):
            local = (p.X - corner) @ R                                       # (n, 2): xi, eta
            if not layer:
                layer.append(HomogeneousLayer(setup.material, np.r_[local[:, 1], fibres], H, gamma, -spec.load / L))
            sigma = layer[0].at([s["t"] for s in p.steps])
            n = len(local)
            stress, sample = sigma[:n, :2, :2], sigma[n:]
            strain_eta = layer[0].strain_eta()[n:]
            lift = np.r_[0.0, np.cumsum(0.5 * (strain_eta[1:] + strain_eta[:-1]) * np.diff(fibres))]
            u = np.stack([p.t * spec.load * (1 - local[:, 0] / L), np.interp(local[:, 1], fibres, lift)], axis=1)
            u_h = (p.x - p.X) @ R
            stress_h = np.einsum("ia,pij,jb->pab", R, p.sigma[:, :2, :2], R)
            force = np.array([p.steps[-1]["contact_force_x"], p.steps[-1]["contact_force_y"]])
            return {"err_u": relative_norm(u_h - u, u, p.V0),
                    "err_sigma": relative_norm(stress_h - stress, stress, p.V0),
                    "P": float(-force @ R[:, 0]), "P_exact": float(-np.trapezoid(sample[:, 0, 0], fibres)),
                    "P_rankine": rankine,
                    "shear_on_wall": float(force @ R[:, 1])}

        method = METHODS[spec.method]
        used = method.used(spec.method_parameters, load_steps=True)        # the load steps' defaults
        result = run(setup, treatment(spec.method, used), after_step=after_step, checkpoint=checkpoint)
        final = result.steps[-1]
        curves = ("t", "P", "P_exact", "P_rankine", "shear_on_wall", "active_length", "max_penetration", "err_u",
                  "err_sigma", "newton_iterations", "cuts", "active_set_changes", "residuals")
        own = {k: final[k] for k in ("err_u", "err_sigma", "P", "P_exact", "P_rankine", "shear_on_wall",
                                     "active_length")}
        return {**contact_record(spec, setup.contact[3], used, result, own, curves),
                "unit_weight": gamma, **material_record(spec),
                "locking": spec.locking, "time_s": perf_counter() - start}


PASSIVE_WALL = PassiveWall()
