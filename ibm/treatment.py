"""How a boundary method imposes the walls inside a load step: one interface for every method.

A treatment's `step(context) -> StepTerms` is called once per load step, on the configuration
at the step start. What it may return (any mix):
- dirichlet, lift: the trial field dw = D dw^h + dw^a (the IBM, dw^a supported in the bands);
  material points integrate the plain part dw^h (a point inside a band is an integration point
  of the plain part), `band` points add W(D dw^h + dw^a) - W(dw^h) (both linearised about the step
  start with band_kinematics "linearised"); points and the outline move
  with the full field D dw^h + dw^a, so no point crosses a wall;
- fixed: prescribed increments of grid DOFs (nodal constraints);
- constraints: rows C and values g of C dU = g (Lagrange multipliers);
- wall(dU) -> (force, tangent): a wall contribution to the internal force and its tangent
  (penalty, Nitsche);
- cells: the grid cells its wall terms touch (their nodes become unknowns).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

from ibm import dirichlet
from ibm.bands import band_quadrature
from ibm.basis import PointBasis
from ibm.constitutive import State
from ibm.geometry import Body
from ibm.grid import Grid
from ibm.quadrature import QuadraturePoints
from ibm.walls import WallLines, wall_lift, wall_predictor


# Nodes with less support than this fraction of a cell are tied to their neighbours in every
# method's large-deformation loop (see baselines.steps.LARGE_DEFAULTS for why).
SUPPORT_THRESHOLD = 0.1


@dataclass(frozen=True, eq=False)
class StepContext:
    """What a treatment sees of one load step (configuration x_n at the step start)."""

    grid: Grid
    body: Body                 # current outline; its essential edges lie on the walls
    lines: WallLines
    increments: np.ndarray     # (n_walls,) wall motion this step along each wall's inward normal
    material: object           # constitutive model (ibm.constitutive)
    x: np.ndarray              # (n_points, d) material points
    volume: np.ndarray         # (n_points,) volumes at x_n
    basis: PointBasis
    state: State
    state_of: Callable[[np.ndarray], np.ndarray]   # points (m, d) -> index of the covering material point
    locking: str = "none"      # ibm.locking: none, or fbar (the mean dilatation at small strain)

    def wall_vector(self, wall: int) -> np.ndarray:
        """The step's displacement g_k (2,) of wall k (a translation along its normal)."""
        return self.increments[wall] * self.lines.normals[wall]

    def wall_of_edge(self) -> dict[int, int]:
        return {edge: wall for wall, edge in enumerate(self.body.essential_edges)}


@dataclass(frozen=True, eq=False)
class StepTerms:
    dirichlet: Callable | None = None            # x (m, d)[, region] -> (D (m, d, d), grad D (m, d, d, d))
    lift: Callable | None = None                 # x (m, d) -> (du^a (m, d), grad du^a (m, d, d))
    band: QuadraturePoints | None = None
    fixed: tuple[np.ndarray, np.ndarray] | None = None          # (dofs, values)
    constraints: tuple[sp.csr_matrix, np.ndarray] | None = None  # (C (n_c, n_dofs), g (n_c,))
    wall: Callable | None = None                 # dU -> (force (n_dofs,), tangent csr)
    cells: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    predictor: np.ndarray | None = None          # (n_dofs,) first Newton iterate of dU (default 0)
    symmetric: bool = True
    support_threshold: float = 0.0               # nodes with less support are tied (ibm.support)
    band_kinematics: str = "finite"              # or "linearised": the band's response about the step start (ibm.newton)
    info: dict = field(default_factory=dict)

    def displacement(self, x: np.ndarray, plain: np.ndarray) -> np.ndarray:
        """The full displacement D dw^h + dw^a at x (m, d) from the plain grid part dw^h (m, d)."""
        u = plain
        if self.dirichlet is not None:
            u = np.einsum("pia,pa->pi", self.dirichlet(x)[0], plain)
        if self.lift is not None:
            u = u + self.lift(x)[0]
        return u


BAND_KINEMATICS = ("auto", "finite", "linearised")


@dataclass(frozen=True)
class ImplicitBoundary:
    """The seed's implicit boundary method in the loop: Dirichlet functions of the walls at the
    step start (band width delta = delta_rel h), a lift carrying the walls' motion, and the band
    correction integrated exactly on band ∩ current body.

    band: the band points' response, "finite" (the model's own at the trial dF) or "linearised"
    (the covering point's step-start response to first order in the increment: affine band forces,
    a constant band tangent; ibm.newton.point_sets); "auto": linearised in 3D, finite in 2D. At
    finite strain the band's own kinematics carries grad D du ~ du_n / delta, du_n the plain field's
    normal trace on a wall: a band point folds once du_n < -delta / 2 and its Hencky stress softens
    past du_n > (e - 1) delta / 2. At delta = 1e-5 h the 3D column's traces at the walls' edges
    exceed that in the first iterates, and Newton stalled under every step cut; linearised, it
    converges in 3-5 iterations a step. The 2D results were measured with the finite band.
    """

    delta_rel: float = 1e-5
    support_threshold: float = SUPPORT_THRESHOLD
    band: str = "auto"

    def __post_init__(self):
        if self.band not in BAND_KINEMATICS:
            raise ValueError(f"band {self.band!r} is not allowed; allowed: {', '.join(BAND_KINEMATICS)}")

    def step(self, context: StepContext) -> StepTerms:
        kinematics = self.band if self.band != "auto" else ("linearised" if context.grid.dim == 3 else "finite")
        body, delta = context.body, self.delta_rel * context.grid.h
        band = band_quadrature(body, context.grid, delta)

        def D(x, region=None):
            return dirichlet.matrix(body, x, delta, region=region)

        return StepTerms(dirichlet=D, lift=wall_lift(body, context.increments, delta), band=band,
                         predictor=wall_predictor(body, context.grid, context.increments),
                         support_threshold=self.support_threshold, band_kinematics=kinematics,
                         info={"delta": delta, "n_band_points": len(band)})
