"""Prandtl's strip footing at small strain: a smooth rigid footing pushed into weightless von Mises soil.

Half model in the local frame (xi along the base, eta up): width W, depth H, the base fixed, the
far side and the symmetry line (xi = 0) rollers, the footing a wall on the top from xi = 0 to
B / 2 moved down by the settlement (smooth: a roller; rough: fixed, the soil stuck to it), the
rest of the top free. The offset places the footing's edge, its singular point, in its cell. The collapse pressure of
a Tresca (von Mises in plane strain: c = sigma_y / sqrt(3)) weightless half-space is
q = (2 + pi) c = 5.142 c, smooth or rough.

The footing's force comes from the domain: with v = (eta / H) e_eta, which vanishes on the base
and has no normal component on the two side rollers (whose shear traction is zero), equilibrium
gives the footing's resultant as int sigma : grad v = (1 / H) int sigma_eta_eta over the body; the
mean footing pressure is q = -(1 / H) sum_p V_p sigma_eta_eta,p / (B / 2). For each grid method it
is its own footing force (the test field lies in the grid's space), so the same sum serves every
grid method; `fem` (baselines.fem.plastic) takes the residual at the footing's constrained DOFs.
"""
from __future__ import annotations

import numpy as np

from baselines.fem.plastic import ORDER, run_fem_plastic
from baselines.registry import METHODS, treatment
from ibm.contact.rigid import RigidBody
from ibm.exceptions import InputError
from ibm.geometry.frames import frame_of_angle
from ibm.geometry.outline import Body
from ibm.large.load_paths import LoadPath
from ibm.large.loadsteps import Loading, Setup, run
from studies.problems.collapse import CollapseProblem
from studies.problems.contact import law_of, require_contact
from studies.problems.materials import (FRICTIONAL, bearing_capacity_factor, material_record, soil_model,
                                       surcharge_factor)
from studies.report.rows import curve, fmt
from studies.run.collapse_runs import final_fields, step_cuts, until_failure, with_defaults

PRANDTL = 2 + np.pi
FOOTING_WIDTH = 160.0          # B in a case of a study: B / h = 16 at the default cell 10


SURCHARGE_RAMP = 0.25      # a surcharge is put on over this first part of the load steps, then held
FOOTINGS = {"smooth": "roller", "rough": "fixed"}     # the footing piece's kind: free to slide, or stuck
RIGID = "rigid"        # the footing a rigid body the soil's free top touches (contact: ibm.contact.rigid)
SURFACES = (*FOOTINGS, RIGID)


def footing_body(width: float, depth: float, footing: float, angle: float, corner: np.ndarray,
                 surface: str = "smooth"):
    """The half model (local frame rotated by angle - 90 degrees like every problem)."""
    if surface not in FOOTINGS:
        raise InputError(f"footing {surface!r} is not allowed; allowed: {', '.join(FOOTINGS)}")
    R = frame_of_angle(angle)
    local = np.array([[0.0, 0.0], [width, 0.0], [width, depth], [footing / 2, depth], [0.0, depth]])
    kinds = ("fixed", "roller", "free", FOOTINGS[surface], "roller")     # base, far side, free top, footing, symmetry
    return Body(np.asarray(corner, float) + local @ R.T, kinds, frame=R), R


def rigid_footing(width: float, depth: float, footing: float, angle: float, corner: np.ndarray,
                  settlement: float):
    """The half model with its whole top free, and the rigid footing that touches it from the symmetry line to
    B / 2 (a B / 4 thick block reaching B / 4 past the symmetry line), moved down by `settlement`."""
    R = frame_of_angle(angle)
    corner = np.asarray(corner, float)
    local = np.array([[0.0, 0.0], [width, 0.0], [width, depth], [0.0, depth]])
    body = Body(corner + local @ R.T, ("fixed", "roller", "free", "roller"), frame=R)   # base, far side, top, symmetry
    block = np.array([[-footing / 4, depth], [footing / 2, depth], [footing / 2, depth + footing / 4],
                      [-footing / 4, depth + footing / 4]])
    motion = LoadPath([0.0, 1.0], [[0.0, 0.0, 0.0], [*(-settlement * R[:, 1]), 0.0]])
    return body, RigidBody(vertices=corner + block @ R.T, motion=motion), R


def half_model(friction_angle: float) -> tuple[float, float]:
    """(width, depth) / B of the half model: 5 B x 3 B, or a quarter more than Prandtl's mechanism for a
    weightless frictional soil reaches (its log spiral's surface end and deepest point), where that is more."""
    reach, deepest = prandtl_mechanism(friction_angle)
    return max(5.0, float(np.ceil(1.25 * reach))), max(3.0, float(np.ceil(1.25 * deepest)))


def prandtl_mechanism(friction_angle: float) -> tuple[float, float]:
    """How far from the centre line Prandtl's mechanism under a smooth footing reaches along the surface, and how
    deep, over B: the active wedge (sides at 45 + phi / 2) of side r0 = (B / 2) / cos(45 + phi / 2), the log
    spiral r0 exp(theta tan phi) over 90 degrees about the footing's edge, the passive wedge at 45 - phi / 2."""
    phi = np.radians(friction_angle)
    wedge = np.pi / 4 + phi / 2
    theta = np.linspace(0.0, np.pi / 2, 2001)
    radius = 0.5 / np.cos(wedge) * np.exp(theta * np.tan(phi))
    deepest = float(np.max(-radius * np.sin(theta - (np.pi - wedge))))
    return 0.5 + 2 * float(radius[-1]) * np.cos(np.pi / 2 - wedge), deepest


def settlement(friction_angle: float) -> float:
    """The settlement / B a case pushes to: 0.02 at phi = 0, in proportion to N_c beyond (the collapse pressure
    and with it the elastic settlement before it grow with N_c)."""
    return 0.02 * bearing_capacity_factor(friction_angle) / PRANDTL


def exact_factor(row) -> float:
    """A footing row's exact q / c: N_c + (q0 / c) N_q (2 + pi for von Mises without a surcharge, and for a row
    stored before frictional soils)."""
    exact = row.get("q_over_c_exact", np.nan)
    return float(exact) if exact is not None and np.isfinite(exact) else PRANDTL


def soil_label(row) -> str:
    """'von Mises', or the frictional soil's name with its angles."""
    material, surcharge = row.get("material"), row.get("surcharge", 0.0)
    beside = f", q0 = {fmt(surcharge)}" if isinstance(surcharge, (int, float)) and surcharge > 0 else ""
    if not isinstance(material, str) or material not in FRICTIONAL:
        return "von Mises" + beside
    return f"{material} φ = {fmt(row['friction_angle'])}°, ψ = {fmt(row['dilation_angle'])}°{beside}"


def edge_corner(angle: float, offset, h: float, footing: float, depth: float) -> np.ndarray:
    """The body's corner that puts the footing's edge (its singular point) at the grid node + offset * h:
    offset (0, 0) puts it on a node at every angle, while the footing and every side stay inclined."""
    edge = frame_of_angle(angle) @ np.array([footing / 2, depth])
    return np.asarray(offset, float) * h - (edge - h * np.floor(edge / h + 1e-9))


def run_footing(method: str, angle: float = 90.0, offset=(0.37, 0.29), B_over_h: float = 16, B: float = 1.0,
                width_over_B: float = 5.0, depth_over_B: float = 3.0, settlement_over_B: float = 0.02,
                steps: int = 40, ppc: int = 2, basis: str = "mpm", locking: str = "fbar",
                yield_stress: float = 100.0, E: float = 1e5, nu: float = 0.3, parameters: dict | None = None,
                footing: str = "smooth", keep_fields: bool = False, kinematics: str = "small",
                checkpoint=None, friction: float = 0.0, adhesion: float = 0.0, material: str = "von-mises",
                cohesion: float = 0.0, friction_angle: float = 0.0, dilation_angle: float | None = None,
                surcharge: float = 0.0) -> dict:
    """Settle the footing (smooth: a roller, rough: fixed) by settlement_over_B * B in `steps` steps;
    q and the Newton iterations per step, q_max / c, the step cuts; with keep_fields, "fields"
    (collapse_runs.final_fields). kinematics "large": von Mises on Hencky (ibm.models.plasticity) in the
    updated Lagrangian loop (grid methods). checkpoint: (grid methods) a file each converged step is
    saved to, the curve with it; a run that finds it resumes (ibm.large.loadsteps.run) to the same result."""
    h = B / B_over_h
    W, H = width_over_B * B, depth_over_B * B
    body_fitted = METHODS[method].supports.body_fitted
    if kinematics not in ("small", "large") or (kinematics == "large" and (body_fitted or footing == RIGID)):
        raise InputError(f"kinematics {kinematics!r} is not allowed for the {footing} footing with {method!r}; "
                         "allowed: small, and large for the grid methods' smooth and rough footings")
    if surcharge and (footing == RIGID or body_fitted or kinematics == "large"):
        raise InputError(f"a surcharge is for the grid methods' smooth and rough footings at small kinematics, not "
                         f"the {footing} footing with {method!r} at {kinematics} kinematics")
    model = soil_model(material, kinematics, E, nu, yield_stress, 0.0, cohesion, friction_angle, dilation_angle)
    corner = edge_corner(angle, offset, h, B, H)
    top: dict = {}        # edge -> LoadPath of its traction (the surcharge on the free top)
    if footing == RIGID:        # the soil's free top touches the rigid footing, which moves down
        if body_fitted:
            raise InputError(f"the rigid footing is for the grid methods with contact, not {method!r}")
        law = law_of(friction, adhesion)
        body, rigid, R = rigid_footing(W, H, B, angle, corner, settlement_over_B * B)
        setup = Setup(body, model, Loading(), h, ppc, basis, steps, locking=locking, contact={2: law},
                      obstacles={2: rigid})
    else:
        body, R = footing_body(W, H, B, angle, corner, footing)
        motion = np.zeros(len(body.essential_edges))
        motion[body.essential_edges.index(3)] = settlement_over_B * B
        if surcharge:          # on the free top beside the footing, ramped over the first SURCHARGE_RAMP, then held
            pressed = -surcharge * R[:, 1]
            top = {2: LoadPath([0.0, SURCHARGE_RAMP, 1.0], [np.zeros(2), pressed, pressed])}
        setup = Setup(body, model, Loading(wall_motion=motion, traction_path=top), h, ppc, basis, steps,
                      locking=locking)
    c = cohesion if material in FRICTIONAL else yield_stress / np.sqrt(3)
    phi = friction_angle if material in FRICTIONAL else 0.0
    kept = {"curve": [], "iterations": []}        # per converged step; checkpointed, refilled on resume

    def after_step(progress):
        # large strain: the test field (eta / H_t) e_eta on the current body, H_t = H - settlement deep
        settlement = progress.t * settlement_over_B * B
        volume, depth = (progress.V0, H) if kinematics == "small" else (progress.volume, H - settlement)
        if footing == RIGID:        # the force the soil puts on the rigid footing
            step = progress.steps[-1]
            q = float(np.array([step["obstacle_force_x"], step["obstacle_force_y"]]) @ R[:, 1]) / (B / 2)
        else:
            # the test field also meets the surcharge on the free top (W - B / 2 long): its force comes off
            s_eta = np.einsum("i,pij,j->p", R[:, 1], progress.sigma[:, :2, :2], R[:, 1])
            q0 = -float(top[2].at(progress.t) @ R[:, 1]) if top else 0.0
            q = (-float(np.sum(volume * s_eta)) / depth - q0 * (W - B / 2)) / (B / 2)
        kept["curve"].append((settlement, q))
        kept["iterations"].append(int(progress.steps[-1]["newton_iterations"]))
        return {"q": q}

    extra = {}
    if body_fitted:            # body-fitted P2, the footing's nodes moved (baselines.fem.plastic)

        def after_fem_step(record):      # the residual at the footing's constrained DOFs
            q = abs(float(record["forces"][3] @ R[:, 1])) / (B / 2)
            kept["curve"].append((record["t"] * settlement_over_B * B, q))
            kept["iterations"].append(int(record["newton_iterations"]))
            return {"q": q}
        progress, failure = until_failure(run_fem_plastic, body, setup.material, {}, h, steps,
                                          after_step=after_fem_step, motions={3: motion[2]})
        if keep_fields:
            extra["fields"] = final_fields(body, h, 0, ORDER, progress)
    else:
        progress, failure = until_failure(run, setup, treatment(method, with_defaults(method, parameters, footing)),
                                          after_step=after_step, checkpoint=checkpoint, extra=kept)
        if keep_fields:
            extra["fields"] = final_fields(body, h, setup.margin, 0, progress)
    q = np.array([q for _, q in kept["curve"]])
    return {"method": method, "angle": angle, "B_over_h": B_over_h, "locking": locking, "footing": footing,
            "kinematics": kinematics, "c": c, "friction": friction, "adhesion": adhesion, "material": material,
            **({"cohesion": cohesion, "friction_angle": friction_angle, "dilation_angle": model.dilation_angle}
               if material in FRICTIONAL else {}),
            "q_max": float(q.max(initial=0.0)), "q_over_c": float(q.max(initial=0.0) / c),
            "q_over_c_exact": bearing_capacity_factor(phi) + surcharge / c * surcharge_factor(phi),
            "surcharge": surcharge,
            "settlement": [s for s, _ in kept["curve"]], "q": q.tolist(), "newton_iterations": kept["iterations"],
            "step_cuts": step_cuts(progress), "stopped": failure, **extra}


# --- as a problem of a study (studies.problems.problem) -----------------------------------------

class Footing(CollapseProblem):
    name = "footing"
    summary = ("Prandtl's strip footing settled into weightless von Mises soil, beside (2 + pi) c, or frictional "
               "soil, beside Prandtl and Reissner's N_c")
    large_kinematics = True
    figures = ("load-settlement", "plastic-zones", "locking")
    own_settings = {"footing": SURFACES}
    materials = tuple(FRICTIONAL)
    surcharge = True

    table_title = "Footing: the peak pressure q_max over c and over its exact N_c (Prandtl's 2 + π on von Mises soil)"
    curve_figure = ("load-settlement", "Load-settlement curves of every method beside Prandtl's 2 + π")
    target, within = "2 + π = 5.142", 0.05

    def own_data(self) -> str:
        return (f"B = {FOOTING_WIDTH:g}, a 5 B x 3 B half model, E = 1e5, nu = 0.3, sigma_y = 100, settled by "
                "0.02 B; or --material mohr-coulomb or drucker-prager with --cohesion and --friction-angle")

    def area(self, spec) -> float:
        width, depth = half_model(self._friction_angle(spec))
        return width * depth * FOOTING_WIDTH ** 2

    @staticmethod
    def _friction_angle(spec) -> float:
        return spec.friction_angle if spec.material in FRICTIONAL else 0.0

    def takes_contact_law(self, spec) -> bool:
        return spec.footing == RIGID

    def validate(self, spec) -> None:
        super().validate(spec)
        if spec.footing == RIGID and spec.method in METHODS:
            if METHODS[spec.method].supports.body_fitted:
                raise InputError(f"footing 'rigid' is for the grid methods with contact, not {spec.method!r}")
            require_contact(spec.method, "footing 'rigid'")
            law_of(spec.friction, spec.adhesion)
        if spec.surcharge and (spec.footing == RIGID or spec.kinematics == "large" or (
                spec.method in METHODS and METHODS[spec.method].supports.body_fitted)):
            raise InputError(f"surcharge {spec.surcharge:g} is for the grid methods' smooth and rough footings at "
                             f"small kinematics, not the {spec.footing} footing with {spec.method!r} at "
                             f"{spec.kinematics} kinematics")
        if spec.material in FRICTIONAL and not spec.cohesion > 0:
            raise InputError(f"cohesion {spec.cohesion:g} is not allowed for problem {self.name!r}; it must be > 0 "
                             "(its measure is q / c against N_c)")

    def run_own(self, spec, parameters: dict, keep_fields: bool, checkpoint) -> dict:
        soil = material_record(spec) if spec.material in FRICTIONAL else {}
        phi = self._friction_angle(spec)
        width, depth = half_model(phi)
        result = run_footing(spec.method, spec.angle, spec.offset, B_over_h=FOOTING_WIDTH / spec.cell,
                             B=FOOTING_WIDTH, width_over_B=width, depth_over_B=depth,
                             settlement_over_B=settlement(phi), steps=spec.steps, ppc=spec.ppc,
                             basis=spec.basis, locking=spec.locking, parameters=parameters, footing=spec.footing,
                             keep_fields=keep_fields, kinematics=spec.kinematics, checkpoint=checkpoint,
                             friction=spec.friction, adhesion=spec.adhesion, surcharge=spec.surcharge, **soil)
        return {"problem": spec.problem, "offset": list(spec.offset), "basis": spec.basis, "cell": spec.cell,
                "ppc": spec.ppc, "steps": spec.steps, "B": FOOTING_WIDTH, "E": 1e5, "nu": 0.3,
                **({} if soil else {"yield_stress": 100.0}), "width_over_B": width, "depth_over_B": depth, **result}

    def target_name(self, group) -> str:
        exact = sorted({exact_factor(row) for _, row in group.iterrows()})
        if exact == [PRANDTL]:
            return self.target
        return "N_c = " + " or ".join(f"{value:.2f}" for value in exact)

    def table_entry(self, row, good: bool, setting) -> dict:
        return {"B/h": row["B_over_h"] if good else np.nan, "footing": setting(row, "footing"),
                "locking": setting(row, "locking"), "soil": soil_label(row),
                "q_max / c": row["q_over_c"] if good else "failed",
                "exact q / c": exact_factor(row),
                "q_max / exact": row["q_over_c"] / exact_factor(row) if good else "failed"}

    def load_ratio(self, rows):
        return rows["q_over_c"] / rows.apply(exact_factor, axis=1)

    def reading(self, group, names, angle: float, cell: float):
        ratio = self.load_ratio(group)
        values = ", ".join(f"{m} {q:.2f} ({100 * (r - 1):+.1f} %)" for m, q, r in zip(names, group["q_over_c"], ratio))
        soils = ", ".join(dict.fromkeys(soil_label(row) for _, row in group.iterrows()))
        soils = "" if soils == "von Mises" else f" ({soils})"
        setting = f"θ = {fmt(angle)}°, B/h = {fmt(group['B_over_h'].iloc[0])}{soils}"
        return f"Footing at {setting}: q_max / c {values}", ratio

    def locked_reading(self, case, lock, remedy) -> str:
        q, q_remedy = curve(lock, "q"), curve(remedy, "q")
        rise = 100 * (q[-1] - q[-2]) / q[-2] if len(q) > 1 else np.nan
        rise_remedy = 100 * (q_remedy[-1] - q_remedy[-2]) / q_remedy[-2] if len(q_remedy) > 1 else np.nan
        return (f"Locked (locking none), {case.method} at θ = {fmt(case.angle)}°, "
                f"B/h = {fmt(lock['B_over_h'])}: q_max = {lock['q_over_c']:.2f} c, "
                f"{100 * (lock['q_over_c'] / PRANDTL - 1):+.0f} % against 2 + π, where B-bar gives "
                f"{remedy['q_over_c']:.2f} c ({100 * (remedy['q_over_c'] / PRANDTL - 1):+.1f} %); over "
                f"the last load step its pressure still rose {rise:.1f} % (B-bar: {rise_remedy:.1f} %).")

    def curve(self, row):
        return 100 * curve(row, "settlement") / row["B"], curve(row, "q") / row["c"]

    def draw_limit(self, ax, row) -> None:
        exact = exact_factor(row)
        label = "2 + π (Prandtl)" if exact == PRANDTL else f"exact q / c = {exact:.2f} (Prandtl, Reissner)"
        ax.axhline(exact, color="black", lw=1.0, linestyle=(0, (4, 2)), label=label, zorder=3)
        ax.set_xlabel("settlement / B (%)")
        ax.set_ylabel("mean footing pressure q / c")

    def setting_label(self, row) -> str:
        if np.isfinite(row.get("B_over_h", np.nan)):
            return f"θ = {row['angle']:g}°, B/h = {row['B_over_h']:g}"
        return super().setting_label(row)


FOOTING = Footing()
