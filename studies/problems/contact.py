"""What the contact problems share (studies.problems.frictional_block, studies.problems.hertz,
studies.problems.passive_wall): a contact wall whose law --friction (Coulomb) or --adhesion (Tresca)
sets, load steps at small kinematics on the body as given, the problem's materials (elastic unless
it says), a method with a contact treatment."""
from __future__ import annotations

import numpy as np

from baselines.registry import METHODS, require
from ibm.contact.laws import ContactLaw
from ibm.exceptions import InputError
from studies.problems.problem import Problem


def contact_law(spec) -> ContactLaw:
    """The wall's law from --friction (Coulomb mu) or --adhesion (Tresca tau_max); neither: frictionless."""
    return law_of(spec.friction, spec.adhesion)


def law_of(friction: float, adhesion: float) -> ContactLaw:
    """Coulomb's law of coefficient `friction`, Tresca's of bound `adhesion`, or none (both 0); not both."""
    if friction and adhesion:
        raise InputError(f"give --friction (Coulomb) or --adhesion (Tresca), not both (got friction "
                         f"{friction:g} and adhesion {adhesion:g})")
    if adhesion:
        return ContactLaw("tresca", adhesion)
    if friction:
        return ContactLaw("coulomb", friction)
    return ContactLaw()


def require_contact(method: str, asking: str) -> None:
    """InputError in one line, naming what is `asking` for contact, unless `method` imposes it."""
    try:
        require(method, "contact")
    except InputError as refusal:
        raise InputError(f"{asking}: {refusal}") from None


class ContactProblem(Problem):
    """The contact problems' protocol: a subclass adds its own checks to `validate` and runs its case."""

    contact = True
    materials: tuple[str, ...] = ("elastic",)
    material_example = ""             # how to ask for one of them, where the default material is not

    def steps_allowed(self, spec) -> bool:
        return True

    def locking_applies(self, spec) -> bool:
        return False

    def fields_refusal(self, spec) -> str:
        return f"problem {self.name!r} keeps no fields yet (its contact measures are in the record's history)"

    def validate(self, spec) -> None:
        super().validate(spec)
        if spec.kinematics != "small":
            raise InputError(f"kinematics {spec.kinematics!r} is not allowed for problem {self.name!r}; allowed: small "
                             "(its contact is imposed on the body as given)")
        if spec.material not in self.materials:
            example = f" ({self.material_example})" if self.material_example else ""
            raise InputError(f"material {spec.material!r} is not allowed for problem {self.name!r}; allowed: "
                             f"{', '.join(self.materials)}{example}")
        if spec.method in METHODS:
            require_contact(spec.method, f"problem {self.name!r}")
        contact_law(spec)


def contact_record(spec, law: ContactLaw, used: dict, result, own: dict, curves: tuple) -> dict:
    """A contact case's record: its settings, the method's parameters `used`, the sizes, the problem's `own`
    results, the wall's force (the last step's), the largest penetration, the Newton iterations, active-set
    changes and step cuts per step, and the per-step `curves` of the run's Progress `result` as its history."""
    final, steps = result.steps[-1], result.steps
    return {
        "problem": spec.problem, "method": spec.method, "angle": spec.angle, "cell": spec.cell, "ppc": spec.ppc,
        "offset": list(spec.offset), "E": spec.E, "nu": spec.nu, "load": spec.load, "load_type": spec.load_type,
        "width": spec.width, "height": spec.height, "kinematics": spec.kinematics, "steps": spec.steps,
        "basis": spec.basis, "material": spec.material, "friction_law": law.friction, "friction": spec.friction,
        "adhesion": spec.adhesion, **used, "ndof": int(final.get("ndof", 0)), "npoints": len(result.X), **own,
        "contact_force": [final["contact_force_x"], final["contact_force_y"]],
        "max_penetration": max(s["max_penetration"] for s in steps),
        "newton_iterations": [s["newton_iterations"] for s in steps],
        "active_set_changes": [s["active_set_changes"] for s in steps],
        "step_cuts": int(sum(s["cuts"] for s in steps)),
        "history": [{k: s.get(k) for k in curves} for s in steps]}


def relative_norm(difference: np.ndarray, exact: np.ndarray, V0: np.ndarray) -> float:
    """sqrt(sum V0 |difference|^2 / sum V0 |exact|^2) over points (n, ...): a field's relative error norm."""
    axes = tuple(range(1, difference.ndim))
    return float(np.sqrt(np.sum(V0 * np.sum(difference ** 2, axis=axes)) / np.sum(V0 * np.sum(exact ** 2, axis=axes))))
