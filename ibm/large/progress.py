"""The state of a load-step run after its last converged step: points, stresses, outline, walls,
time and the per-step records (ibm.large.loadsteps updates it; ibm.large.checkpoint saves and restores it)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ibm.large.walls import Outline, WallLines


@dataclass
class Progress:
    """The run's state after each converged step (the driver updates it in place)."""

    X: np.ndarray                  # (n, d) initial positions
    V0: np.ndarray                 # (n,) initial volumes
    x: np.ndarray                  # (n, d) current positions
    volume: np.ndarray
    state: object                  # ibm.models.constitutive.State
    sigma: np.ndarray              # (n, 3, 3) Cauchy stress
    outline: Outline               # a FacetedOutline in 3D
    lines: WallLines
    t: float = 0.0
    steps: list = field(default_factory=list)   # one record per load step
    vertex_owner: np.ndarray | None = None      # (n_vertices,) the material point each outline vertex moves with
    contact: dict = field(default_factory=dict)  # the contact walls' history (a treatment's accept)
