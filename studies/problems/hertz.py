"""Hertz's line contact: an elastic half cylinder pressed onto a rigid plane (docs/contact.md).

Quarter model in the body's frame (xi along the plane, eta its normal into the body), radius R =
width: the quarter disc touches the plane at the origin; its arc may touch the plane (the contact
edge, with an obstacle), the symmetry line xi = 0 is a roller wall, and its flat top, the half
cylinder's diameter, is a roller plate moved towards the plane by the settlement `load`. For a
cylinder carrying P per unit length on a rigid plane (Johnson, Contact Mechanics, 1985, §4.3):

    a^2 = 4 P R / (pi E*),   p(xi) = p0 sqrt(1 - xi^2 / a^2),   p0 = 2 P / (pi a),   E* = E / (1 - nu^2),

asymptotically for a << R (the settlement depends on the body's size, a and p0 do not). The quarter
carries P / 2. The discrete pressure sits on the few points of each cell that its bilinear field can
close against the curved edge, so a is read from the pressure's moments, exact for Hertz's
distribution: a = 2 sqrt(int p xi^2 / int p) (the contact wall's pressure_spread), and p0 from
P and that a; active_length, the length of the points in contact, is a few points per cell.
"""
from __future__ import annotations

from time import perf_counter

import numpy as np

from baselines.registry import METHODS, treatment
from ibm.contact.laws import Obstacle
from ibm.exceptions import InputError
from ibm.geometry.arcs import Arc
from ibm.geometry.frames import frame_of_angle
from ibm.geometry.outline import Body
from ibm.large.loadsteps import Loading, Setup, run
from ibm.models.small_strain import LinearElastic
from studies.problems.contact import ContactProblem, contact_law, contact_record

SETTLEMENT = 0.02        # the settlement per radius that puts a / R near 0.1 (the default load)


class Hertz(ContactProblem):
    name = "hertz"
    summary = "an elastic half cylinder pressed onto a rigid plane: Hertz's contact half-width and pressure"
    compared = {"a": ("a", "a_exact"), "p0": ("p0", "p0_exact")}

    def load_types(self) -> tuple[str, ...]:
        return ("settlement",)

    def default_load(self, width: float, height: float) -> float:
        return SETTLEMENT * width

    def size(self, spec) -> float:
        return spec.width

    def area(self, spec) -> float:
        return np.pi * spec.width ** 2 / 4

    def validate(self, spec) -> None:
        super().validate(spec)
        largest = 0.05 * spec.width
        if not 0 < spec.load <= largest:
            raise InputError(f"load {spec.load:g} (the plate's settlement) is not allowed for problem {self.name!r}; it "
                             f"must be in (0, width / 20 = {largest:g}]: Hertz's solution needs a << R (the default "
                             f"{SETTLEMENT:g} width puts a / R near 0.1)")

    def setup(self, spec):
        """The load steps' setup, the touching point (2,) and the body's frame (2, 2)."""
        R = spec.width
        frame = frame_of_angle(spec.angle)
        origin = np.asarray(spec.offset, float) * spec.cell            # the touching point
        local = np.array([[0.0, 0.0], [R, R], [0.0, R]])                 # arc, flat top (the plate), symmetry line
        body = Body(origin + local @ frame.T, ("free", "roller", "roller"), frame=frame,
                    arcs=(Arc(origin + np.array([0.0, R]) @ frame.T), None, None))
        motion = np.zeros(len(body.essential_edges))
        motion[body.essential_edges.index(1)] = spec.load
        setup = Setup(body, LinearElastic(spec.E, spec.nu), Loading(wall_motion=motion), spec.cell, spec.ppc,
                      spec.basis, spec.steps, contact={0: contact_law(spec)},
                      obstacles={0: Obstacle(origin, frame[:, 1])})
        return setup, origin, frame

    def run(self, spec, keep_fields: bool = False, solver: str = "auto", progress: bool = False,
            checkpoint=None) -> dict:
        start = perf_counter()
        setup, origin, frame = self.setup(spec)
        E_star = spec.E / (1 - spec.nu ** 2)
        R = spec.width
        method = METHODS[spec.method]

        def after_step(p):
            step = p.steps[-1]
            P = -2 * float(np.array([step["contact_force_x"], step["contact_force_y"]]) @ frame[:, 1])
            a = 2 * step.get("pressure_spread", 0.0)
            a_exact = float(np.sqrt(4 * max(P, 0.0) * R / (np.pi * E_star)))
            return {"P": P, "a": a, "a_exact": a_exact,
                    "p0": 2 * P / (np.pi * a) if a > 0 else 0.0, "p0_exact": 2 * P / (np.pi * a_exact) if P > 0 else 0.0}

        used = method.used(spec.method_parameters, load_steps=True)        # the load steps' defaults
        result = run(setup, treatment(spec.method, used), after_step=after_step, checkpoint=checkpoint)
        final = result.steps[-1]
        curves = ("t", "P", "a", "a_exact", "active_length", "p0", "p0_exact", "pressure_peak", "max_penetration",
                  "newton_iterations", "cuts", "active_set_changes", "residuals")
        law = setup.contact[0]
        own = {**{k: final[k] for k in ("P", "a", "a_exact", "p0", "p0_exact", "pressure_peak")},
               "a_error": final["a"] / final["a_exact"] - 1 if final["a_exact"] > 0 else None,
               "a_over_R": final["a_exact"] / R, "active_length": final["active_length"]}
        return {**contact_record(spec, law, used, result, own, curves), "time_s": perf_counter() - start}


HERTZ = Hertz()
