"""A problem from another package: a closed-form field, registered through the entry-point group
ibm_mpm.problems (pyproject.toml) as a ClosedFormProblem (studies.problems.closed_form).

two-wave: two half-waves across the base, rollers on the base and both sides (the normal
displacement and the shear stress vanish there), its own traction on the top and the body force
b = -div sigma derived from the field by sympy.
"""
from __future__ import annotations

from studies.problems.closed_form import ClosedFormProblem
from studies.problems.library import symbolic

FIELD = symbolic(
    "two-wave",
    "two half-waves across the base, rollers on base and sides, its traction on top, b = -div sigma",
    ("roller", "roller", "traction", "roller"),
    u=("p * H / M * sin(2 * pi * xi / L) * cos(pi * eta / (2 * H))",
       "p * H / (2 * M) * cos(2 * pi * xi / L) * sin(pi * eta / (2 * H))"))

TWO_WAVE = ClosedFormProblem("two-wave", {"pressure": FIELD})
