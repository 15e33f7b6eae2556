"""The frictional block: a block pressed on an inclined rigid wall, then sheared by a rough top plate
(docs/contact.md). Exact at every load step, so every consistent contact method reproduces it.

In the block's frame (xi along the wall, eta its inward normal), width W, height H, plane strain,
lam, G = mu, M = lam + 2 G:
- phase 1 (t <= 1/2): the top plate (fixed: the block is stuck to it) moves down by p(t) H / M,
  p(t) = 2 t p; the sides carry the oedometric state's traction, sigma_xi_xi = -(lam / M) p(t), so
  eps_xi_xi = 0 and the base needs no shear;
- phase 2: at fixed p the plate moves along the wall by s(t) = 2 (t - 1/2) S; the base sticks while
  G s / H < b (b = mu p for Coulomb, tau_max for Tresca), then slips uniformly:

    tau = min(G s / H, b),  slip = s - tau H / G,
    u_xi = (tau / G) eta + slip,  u_eta = -(p(t) / M) eta,
    sigma_xi_xi = -(lam / M) p(t),  sigma_eta_eta = -p(t),  sigma_xi_eta = tau,

  with the sides carrying +-(sigma_xi_xi e_xi + tau e_eta). S = (1 + sqrt 2) s*, s* = b H / G: the
  base sticks until t = 1/sqrt(2), then slips; frictionless: S = p H / G.
The wall carries P = p W (normal) and T = tau W (along the wall): the force the block puts on it.
"""
from __future__ import annotations

from time import perf_counter

import numpy as np

from baselines.registry import METHODS, treatment
from ibm.contact.laws import ContactLaw
from ibm.exceptions import InputError
from ibm.geometry.outline import rectangle
from ibm.large.load_paths import LoadPath
from ibm.large.loadsteps import Loading, Setup, run
from ibm.models.small_strain import LinearElastic
from studies.problems.contact import ContactProblem, contact_law, contact_record, relative_norm

KINDS = ("roller", "traction", "fixed", "traction")     # base (the contact wall), right side, top plate, left side
PRESSED = 0.5                                           # the load fraction at the end of phase 1
# The plate's travel S in units of s* = b H / G: the stick ends at t = 1/sqrt(2), a load fraction no
# step ends on (a step ending on it leaves the discrete base split between stick and slip by round-off)
SHEAR = 1 + np.sqrt(2)


class FrictionalBlock(ContactProblem):
    name = "frictional-block"
    summary = "a block pressed on an inclined rigid wall, then sheared: Coulomb or Tresca stick, then slip"
    compared = {"P": ("P", "P_exact"), "T": ("T", "T_exact"), "slip length": ("slip_length", "slip_length_exact")}

    def validate(self, spec) -> None:
        super().validate(spec)
        if not spec.load > 0:
            raise InputError(f"load {spec.load:g} is not allowed for problem {self.name!r}; it must be > 0 (the "
                             "pressure on the wall)")

    # --- the exact solution --------------------------------------------------------------------
    @staticmethod
    def history(spec, material, law: ContactLaw):
        """t -> (p(t), tau(t), slip(t)) and the path's kinks (load fractions)."""
        p, H, G = spec.load, spec.height, material.mu
        bound = float(law.bound(np.array([p]))[0])
        S = SHEAR * bound * H / G if bound > 0 else p * H / G

        def at(t: float):
            pressure = p * min(t / PRESSED, 1.0)
            s = S * max(0.0, (t - PRESSED) / (1 - PRESSED))
            b = float(law.bound(np.array([pressure]))[0])
            if G * s / H <= b:
                return pressure, G * s / H, 0.0
            return pressure, b, s - b * H / G

        kinks = [0.0, PRESSED, 1.0]
        if bound > 0:
            kinks.insert(2, PRESSED + (1 - PRESSED) / SHEAR)     # where the stick ends
        return at, np.array(kinks), S

    @staticmethod
    def exact_fields(X_local: np.ndarray, material, pressure: float, tau: float, slip: float):
        """u (n, 2) and the in-plane stress (n, 2, 2), both in the block's frame, at local points (n, 2)."""
        lam, G, M = material.lam, material.mu, material.M
        eta = X_local[:, 1]
        u = np.stack([(tau / G) * eta + slip, -(pressure / M) * eta], axis=1)
        stress = np.array([[-(lam / M) * pressure, tau], [tau, -pressure]])
        return u, np.broadcast_to(stress, (len(eta), 2, 2))

    def setup(self, spec):
        """The load steps' setup, the body's corner (2,), its frame (2, 2) and the history (history())."""
        material = LinearElastic(spec.E, spec.nu)
        law = contact_law(spec)
        corner = np.asarray(spec.offset, float) * spec.cell
        body = rectangle(spec.width, spec.height, KINDS, spec.angle, corner)
        R = body.frame
        xi, eta = R[:, 0], R[:, 1]
        at, kinks, _ = self.history(spec, material, law)
        top = body.essential_edges.index(2)
        translations, right = [], []
        for t in kinks:
            pressure, tau, slip = at(t)
            u_top = np.zeros((len(body.essential_edges), 2))
            u_top[top] = (tau / material.mu * spec.height + slip) * xi - pressure / material.M * spec.height * eta
            translations.append(u_top)
            right.append(-(material.lam / material.M) * pressure * xi + tau * eta)
        right = np.array(right)
        loading = Loading(wall_path=LoadPath(kinks, np.array(translations)),
                          traction_path={1: LoadPath(kinks, right), 3: LoadPath(kinks, -right)})
        setup = Setup(body, material, loading, spec.cell, spec.ppc, spec.basis, spec.steps, contact={0: law})
        return setup, corner, R, at

    # --- a case --------------------------------------------------------------------------------
    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        start = perf_counter()
        setup, corner, R, at = self.setup(spec)
        material, W = setup.material, spec.width
        method = METHODS[spec.method]

        def after_step(p):
            pressure, tau, slip = at(p.t)
            u, stress = self.exact_fields((p.X - corner) @ R, material, pressure, tau, slip)
            u_h = (p.x - p.X) @ R
            stress_h = np.einsum("ia,pij,jb->pab", R, p.sigma[:, :2, :2], R)
            force = np.array([p.steps[-1]["contact_force_x"], p.steps[-1]["contact_force_y"]])
            sliding = pressure > 0 and (slip > 0 or setup.contact[0].bound(np.array([pressure]))[0] == 0)
            return {"err_u": relative_norm(u_h - u, u, p.V0),
                    "err_sigma": relative_norm(stress_h - stress, stress, p.V0),
                    "P": float(-force @ R[:, 1]), "P_exact": pressure * W,
                    "T": float(force @ R[:, 0]), "T_exact": tau * W,
                    "active_length_exact": W if pressure > 0 else 0.0,
                    "slip_length_exact": W if sliding else 0.0}

        used = method.used(spec.method_parameters, load_steps=True)        # the load steps' defaults
        result = run(setup, treatment(spec.method, used), after_step=after_step, checkpoint=checkpoint)
        final = result.steps[-1]
        law = setup.contact[0]
        curves = ("t", "P", "P_exact", "T", "T_exact", "active_length", "active_length_exact", "slip_length",
                  "slip_length_exact", "max_penetration", "err_u", "err_sigma", "newton_iterations", "cuts",
                  "active_set_changes", "residuals")
        own = {"err_u": final["err_u"], "err_sigma": final["err_sigma"],
               **{k: final[k] for k in ("P", "P_exact", "T", "T_exact", "active_length", "active_length_exact",
                                        "slip_length", "slip_length_exact")}}
        return {**contact_record(spec, law, used, result, own, curves + ("active_set_rounds",)),
                "time_s": perf_counter() - start}


FRICTIONAL_BLOCK = FrictionalBlock()
