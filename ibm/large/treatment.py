"""How a boundary method imposes the walls inside a load step: one interface for every method.

A treatment's `step(context) -> StepTerms` is called once per load step, on the configuration
at the step start. What it may return (any mix):
- dirichlet, lift: the trial field dw = D dw^h + dw^a (the IBM, dw^a supported in the bands);
  material points integrate the plain part dw^h (a point inside a band is an integration point
  of the plain part), `band` points add W(D dw^h + dw^a) - W(dw^h) (both linearised about the step
  start with band_kinematics "linearised"); points and the outline move
  with the full field D dw^h + dw^a, so no point crosses a wall;
- fixed: prescribed increments of grid DOFs (nodal constraints);
- constraints: rows C and values g of C dU = g (Lagrange multipliers), and multiplier_load B, forces
  B lambda on the grid that follow them (Coulomb friction on a slipping piece, mu times its pressure);
- wall(dU) -> (force, tangent): a wall contribution to the internal force and its tangent
  (penalty, Nitsche);
- cells: the grid cells its wall terms touch (their nodes become unknowns);
- accept(dU) -> (contact state, record): on convergence, the history its contact walls keep to
  the next step (StepContext.contact_state) and the step's contact measures;
- refine(dU, multipliers) -> the terms of the next active set, or None once it holds (an active-set
  method: the step is solved again until its set settles).

Walls translate by any vector (StepContext.translations); a wall of StepContext.contact is
unilateral with friction (ibm.contact.laws) instead of a roller. A treatment that imposes either
says so: `vector_walls` and `contact` true (ibm.large.loadsteps refuses them otherwise).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

from ibm.discretise.basis import PointBasis
from ibm.models.constitutive import State
from ibm.geometry.outline import Body
from ibm.discretise.grid import Grid
from ibm.quadrature.rules import QuadraturePoints
from ibm.large.walls import WallLines


# Nodes with less support than this fraction of a cell are tied to their neighbours in every
# method's large-deformation loop: at large deformation the material moves through the grid and
# leaves nodes that a few point domains barely reach, which a Newton update would move far.
SUPPORT_THRESHOLD = 0.1


@dataclass(frozen=True, eq=False)
class StepContext:
    """What a treatment sees of one load step (configuration x_n at the step start)."""

    grid: Grid
    body: Body                 # current outline; its essential edges lie on the walls
    lines: WallLines
    increments: np.ndarray     # (n_walls,) wall motion this step along each wall's inward normal
    material: object           # constitutive model (ibm.models.constitutive)
    x: np.ndarray              # (n_points, d) material points
    volume: np.ndarray         # (n_points,) volumes at x_n
    basis: PointBasis
    state: State
    state_of: Callable[[np.ndarray], np.ndarray]   # points (m, d) -> index of the covering material point
    locking: str = "none"      # ibm.discretise.locking: none, or fbar (the mean dilatation at small strain)
    translations: np.ndarray | None = None    # (n_walls, d) this step's wall translations; None: along the normals
    contact: dict = field(default_factory=dict)          # edge -> ContactLaw (ibm.contact.laws) of a contact wall
    contact_state: dict = field(default_factory=dict)    # what the last step's accept left (arrays)
    obstacles: dict = field(default_factory=dict)        # a contact edge that is no wall -> its Obstacle or RigidBody
    times: tuple[float, float] = (0.0, 0.0)              # the step's load fractions (t0, t1)

    def wall_vector(self, wall: int) -> np.ndarray:
        """The step's displacement g_k (d,) of wall k: its translation (along its normal unless given)."""
        if self.translations is not None:
            return self.translations[wall]
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
    support_threshold: float = 0.0               # nodes with less support are tied (ibm.discretise.support)
    band_kinematics: str = "finite"              # or "linearised": the band's response about the step start (ibm.large.newton)
    info: dict = field(default_factory=dict)
    accept: Callable | None = None               # dU -> (contact state dict, record dict), on convergence
    line_search: bool = False                    # damp Newton updates that do not reduce the residual (contact)
    refine: Callable | None = None               # (dU, multipliers by row of C) -> StepTerms of the next active set, or None
    multiplier_load: sp.csr_matrix | None = None  # B (n_dofs, n_c): forces B lambda that follow the multipliers

    def displacement(self, x: np.ndarray, plain: np.ndarray) -> np.ndarray:
        """The full displacement D dw^h + dw^a at x (m, d) from the plain grid part dw^h (m, d)."""
        u = plain
        if self.dirichlet is not None:
            u = np.einsum("pia,pa->pi", self.dirichlet(x)[0], plain)
        if self.lift is not None:
            u = u + self.lift(x)[0]
        return u


BAND_KINEMATICS = ("auto", "finite", "linearised")
