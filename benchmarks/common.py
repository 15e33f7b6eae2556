"""Problem builders shared by the benchmarks: the IBM system of confined-block at 30 degrees
and scikit-fem's own Q1 elasticity on a body-fitted mesh with the same number of unknowns."""
from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from benchmarks.skfem_block import SIZE, skfem_assembly, skfem_basis, skfem_solve  # noqa: F401  (re-exported)
from ibm import dirichlet
from ibm.small import forms
from ibm.quadrature.bands import band_quadrature, edge_quadrature
from ibm.small.model import Model, build_model
from studies.run.case import CaseSpec, instance_of

ANGLE = 30.0
DELTA_REL = 1e-5


def ibm_study() -> list[str]:
    """The command `ibm-study` of this environment, as a process argv prefix (on PATH or not)."""
    script = Path(sys.executable).with_name("ibm-study")
    return [str(script)] if script.exists() else [sys.executable, "-m", "studies.cli"]


def cells_for(ndof: int) -> int:
    """Cells across the body giving about `ndof` unknowns (2 per node, ~n^2 nodes)."""
    return max(2, int(round(np.sqrt(ndof / 2))))


@lru_cache(maxsize=4)
def ibm_model(n_cells: int, ppc: int = 1) -> Model:
    h = SIZE / n_cells
    instance = instance_of(CaseSpec(angle=ANGLE, cell=h, ppc=ppc, width=SIZE, height=SIZE))
    return build_model(instance.body, instance.parameters.material, instance.loads, h, ppc)


@dataclass(frozen=True, eq=False)
class Quadratures:
    model: Model
    points: object
    band: object
    edges: dict
    D: object


@lru_cache(maxsize=4)
def ibm_quadratures(n_cells: int, ppc: int = 1) -> Quadratures:
    model = ibm_model(n_cells, ppc)
    delta = DELTA_REL * model.grid.h

    def D(x):
        return dirichlet.matrix(model.body, x, delta)

    band = band_quadrature(model.body, model.grid, delta)
    edges = {k: edge_quadrature(model.body, model.grid, k, delta) for k in model.loads.tractions}
    return Quadratures(model, model.points.quadrature(), band, edges, D)


def ibm_assembly(q: Quadratures) -> tuple[sp.csr_matrix, np.ndarray]:
    """Material-point stiffness + band correction + loads, into CSR: what solve_ibm assembles."""
    model, points, band, D = q.model, q.points, q.band, q.D

    def with_band(form):
        return form(model, points) + form(model, band, D) - form(model, band)

    K = forms.corrected_stiffness(model, points, band, D)
    f = with_band(forms.body_force) + with_band(forms.lift_force) + forms.traction_force(model, q.edges, D)
    return K, f
