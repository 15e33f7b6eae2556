"""The discretised problem every boundary method works on, and the solution it returns."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ibm.geometry.outline import Body

from ibm.exceptions import InputError
from ibm.discretise.grid import Grid
from ibm.models.elastic import Elastic
from ibm.discretise.points import MaterialPoints, material_points

VectorField = Callable[[np.ndarray], np.ndarray]                           # x (n, 2) -> (n, 2)
Lift = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]              # x -> u (n, 2), grad u (n, 2, 2)


@dataclass(frozen=True, eq=False)
class Loads:
    """Body force b(x), tractions t(x) per traction edge, and the essential-data lift u^a.

    The lift carries all essential data: n_k . u^a = u_n on roller k, u^a = u on fixed edges.
    None means zero. grad u^a[p, i, j] = d u_i / d x_j.
    """

    body_force: VectorField | None = None
    tractions: dict[int, VectorField] = field(default_factory=dict)
    lift: Lift | None = None


@dataclass(frozen=True, eq=False)
class Model:
    """What a small-strain solve reads: the body, its material and loads, the grid and the material
    points (build_model makes one)."""

    body: Body
    material: Elastic
    loads: Loads
    grid: Grid
    points: MaterialPoints

    @property
    def dim(self) -> int:
        return self.grid.dim

    @property
    def C(self) -> np.ndarray:
        """The material's Voigt stiffness in the grid's dimension."""
        return self.material.stiffness(self.grid.dim)

    def lift(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.loads.lift is None:
            d = x.shape[1]
            return np.zeros((len(x), d)), np.zeros((len(x), d, d))
        return self.loads.lift(x)


def build_model(body: Body, material: Elastic, loads: Loads, h: float, ppc: int = 1) -> Model:
    """The small-strain model of `body` on a grid of cell size `h` covering it, with ppc x ppc material
    points per cell; InputError for a traction on an edge that is not a traction edge."""
    for k in loads.tractions:
        if not (0 <= k < body.n_edges) or body.kinds[k] != "traction":
            raise InputError(f"traction given on edge {k}, which is not a traction edge")
    grid = Grid.covering(body, h)
    return Model(body, material, loads, grid, material_points(body, grid, ppc))


@dataclass(frozen=True, eq=False)
class BoundaryTraction:
    """Traction sigma n (outward n) a method recovers on its essential edges.

    x (m, 2) points, weight (m,) length weights, edge (m,) edge ids, value (m, 2) the traction.
    """

    x: np.ndarray
    weight: np.ndarray
    edge: np.ndarray
    value: np.ndarray


@dataclass(frozen=True, eq=False)
class Solution:
    """Displacement u (n, 2) and stress sigma (n, 2, 2), sigma_zz (n,) at the material points.

    evaluate(x, cells) gives (u, sigma, sigma_zz) anywhere inside the body; info holds
    diagnostics (ndof, timings, condition estimate, ...). Grid methods keep the nodal values
    nodal (2 n_nodes,) of u^h (u = D u^h + u^a in the IBM, u^h + u^a otherwise); methods with
    strong constraints keep their reactions: piece -> the residual K U - f on its constrained
    DOFs, (2,).
    """

    u: np.ndarray
    sigma: np.ndarray
    sigma_zz: np.ndarray
    evaluate: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
    info: dict
    tractions: BoundaryTraction | None = None   # multiplier methods: recovered boundary traction
    nodal: np.ndarray | None = None              # grid methods: nodal values of u^h (2 n_nodes,)
    reactions: dict[int, np.ndarray] | None = None   # strong constraints: piece -> force (2,)
