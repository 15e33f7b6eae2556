"""Problem builders shared by the benchmarks: the IBM system of confined-block at 30 degrees
and scikit-fem's own Q1 elasticity on a body-fitted mesh with the same number of unknowns."""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from ibm import dirichlet, forms
from ibm.bands import band_quadrature, edge_quadrature
from ibm.model import Model, build_model
from studies.case import CaseSpec, instance_of

SIZE = 100.0
ANGLE = 30.0
DELTA_REL = 1e-5


def cells_for(ndof: int) -> int:
    """Cells across the body giving about `ndof` unknowns (2 per node, ~n^2 nodes)."""
    return max(2, int(round(np.sqrt(ndof / 2))))


@lru_cache(maxsize=4)
def ibm_model(n_cells: int, ppc: int = 1) -> Model:
    h = SIZE / n_cells
    instance = instance_of(CaseSpec(angle=ANGLE, cell=h, ppc=ppc, size=SIZE))
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


def skfem_basis(n_cells: int):
    """Body-fitted Q1 basis of the square (scikit-fem's own mesh and element)."""
    from skfem import Basis, ElementQuad1, ElementVector, MeshQuad
    s = np.linspace(0.0, SIZE, n_cells + 1)
    mesh = MeshQuad.init_tensor(s, s).with_boundaries({
        "left": lambda x: x[0] < 1e-9 * SIZE, "right": lambda x: x[0] > SIZE * (1 - 1e-9),
        "bottom": lambda x: x[1] < 1e-9 * SIZE, "top": lambda x: x[1] > SIZE * (1 - 1e-9)})
    return Basis(mesh, ElementVector(ElementQuad1()))


def skfem_assembly(basis, E: float = 1e4, nu: float = 0.3) -> sp.csr_matrix:
    """scikit-fem's Q1 elasticity: skfem.models.elasticity.linear_elasticity, BilinearForm.assemble."""
    from skfem.models.elasticity import lame_parameters, linear_elasticity
    return linear_elasticity(*lame_parameters(E, nu)).assemble(basis)


def skfem_solve(basis, K: sp.csr_matrix, load: float = 10.0) -> np.ndarray:
    """The body-fitted confined block with scikit-fem's defaults: rollers by condense, skfem.solve.

    Solved in the block's own frame: a body-fitted mesh of the block turned by 30 degrees
    gives the same matrix up to an orthogonal change of variables, so the same cost.
    """
    from skfem import LinearForm, condense, solve
    from skfem.helpers import dot

    @LinearForm
    def pressure(v, w):
        return dot(v, w.n) * (-load)

    from skfem import FacetBasis
    top = FacetBasis(basis.mesh, basis.elem, facets=basis.mesh.boundaries["top"])
    f = pressure.assemble(top)
    rollers = np.concatenate([basis.get_dofs("left").nodal["u^1"], basis.get_dofs("right").nodal["u^1"],
                              basis.get_dofs("bottom").nodal["u^2"]])
    return solve(*condense(K, f, D=rollers))
