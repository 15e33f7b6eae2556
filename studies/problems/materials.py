"""The materials a case names (`--material`), the models they make at small and large kinematics, and the
exact bearing-capacity factor of a frictional soil (docs/plasticity.md).

    elastic           linear elastic at small strain, Hencky at large
    von-mises (j2)    von Mises: --yield-stress, --hardening (ibm.models.small_strain, ibm.models.plasticity)
    mohr-coulomb      Mohr-Coulomb: --cohesion, --friction-angle, --dilation-angle (ibm.models.mohr_coulomb)
    drucker-prager    Drucker-Prager matched to Mohr-Coulomb in plane strain (ibm.models.drucker_prager)

The dilation angle left unset is the friction angle (associated flow).
"""
from __future__ import annotations

import math

import numpy as np

from ibm.exceptions import InputError
from ibm.models.constitutive import Hencky, check_frictional
from ibm.models.drucker_prager import DruckerPrager, HenckyDruckerPrager
from ibm.models.mohr_coulomb import HenckyMohrCoulomb, MohrCoulomb
from ibm.models.plasticity import HenckyJ2
from ibm.models.small_strain import LinearElastic, VonMises

VON_MISES = ("von-mises", "j2")         # j2: the same von Mises model, under its older name
FRICTIONAL = {"mohr-coulomb": (MohrCoulomb, HenckyMohrCoulomb), "drucker-prager": (DruckerPrager, HenckyDruckerPrager)}
MATERIALS = ("elastic", *VON_MISES, *FRICTIONAL)


def dilation(spec) -> float:
    """The case's dilation angle (degrees): its own, or its friction angle (associated flow) where unset."""
    return spec.friction_angle if spec.dilation_angle is None else spec.dilation_angle


def model_of(spec, kinematics: str | None = None):
    """The model of the case's material at `kinematics` (the case's where None)."""
    return soil_model(spec.material, kinematics or spec.kinematics, spec.E, spec.nu, spec.yield_stress,
                      spec.hardening, spec.cohesion, spec.friction_angle, dilation(spec))


def soil_model(material: str, kinematics: str, E: float, nu: float, yield_stress: float = 0.0, hardening: float = 0.0,
               cohesion: float = 0.0, friction_angle: float = 0.0, dilation_angle: float | None = None):
    """The model of `material` at `kinematics` (small or large) with its data (dilation None: associated)."""
    small = kinematics == "small"
    if material in FRICTIONAL:
        psi = friction_angle if dilation_angle is None else dilation_angle
        return FRICTIONAL[material][0 if small else 1](E, nu, cohesion=cohesion, friction_angle=friction_angle,
                                                       dilation_angle=psi)
    if material in VON_MISES:
        return (VonMises if small else HenckyJ2)(E, nu, yield_stress=yield_stress, hardening=hardening)
    if material != "elastic":
        raise InputError(f"material {material!r} is not allowed; allowed: {', '.join(MATERIALS)}")
    return (LinearElastic if small else Hencky)(E, nu)


def material_record(spec) -> dict:
    """The material's settings for a case's record: its yield stress and hardening, or its c, phi and psi."""
    if spec.material in FRICTIONAL:
        return {"material": spec.material, "cohesion": spec.cohesion, "friction_angle": spec.friction_angle,
                "dilation_angle": dilation(spec)}
    return {"material": spec.material, "yield_stress": spec.yield_stress, "hardening": spec.hardening}


def check_nonnegative(spec, name: str) -> None:
    """InputError (one line) unless the case's setting `name` is a finite number >= 0."""
    value = getattr(spec, name)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise InputError(f"{name.replace('_', '-')} {value} is not allowed; it must be a finite number >= 0")


def validate_material(spec) -> None:
    """InputError (one line) for a material, or a setting of one, the case cannot take."""
    if spec.material not in MATERIALS:
        raise InputError(f"material {spec.material!r} is not allowed; allowed: {', '.join(MATERIALS)}")
    numbers = ("yield_stress", "hardening", "cohesion", "friction_angle") + (() if spec.dilation_angle is None
                                                                            else ("dilation_angle",))
    for name in numbers:
        check_nonnegative(spec, name)
    given = _given(spec, ("yield_stress", "hardening"))
    if given and spec.material not in VON_MISES:
        raise InputError(f"{given} is for --material von-mises (or j2), not material {spec.material!r}")
    given = _given(spec, ("cohesion", "friction_angle", "dilation_angle"))
    if given and spec.material not in FRICTIONAL:
        raise InputError(f"{given} is for --material {' or '.join(FRICTIONAL)}, not material {spec.material!r}")
    if spec.material in VON_MISES and not spec.yield_stress > 0:
        raise InputError(f"yield-stress {spec.yield_stress} is not allowed for material {spec.material}; "
                         "it must be > 0")
    if spec.material in FRICTIONAL:
        check_frictional(spec.cohesion, spec.friction_angle, dilation(spec))


def _given(spec, names) -> str:
    """'yield-stress 10 and hardening 5': the settings of `names` the case gives (not 0, not unset)."""
    return " and ".join(f"{name.replace('_', '-')} {getattr(spec, name):g}" for name in names
                        if getattr(spec, name) not in (0, None))


def surcharge_factor(friction_angle: float) -> float:
    """N_q = exp(pi tan phi) tan^2(45 + phi / 2) (Prandtl, Reissner): the collapse pressure per unit surcharge
    beside a strip footing on a weightless soil, 1 at phi = 0."""
    phi = np.radians(friction_angle)
    return float(np.exp(np.pi * np.tan(phi)) * np.tan(np.pi / 4 + phi / 2) ** 2)


def bearing_capacity_factor(friction_angle: float) -> float:
    """N_c of a weightless soil under a strip footing (Prandtl 1920, Reissner 1924; associated flow):
    (N_q - 1) cot phi with N_q = exp(pi tan phi) tan^2(45 + phi / 2), and its limit 2 + pi at phi = 0."""
    if friction_angle == 0:
        return 2 + np.pi
    return float((surcharge_factor(friction_angle) - 1) / np.tan(np.radians(friction_angle)))
