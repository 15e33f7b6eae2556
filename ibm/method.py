"""The implicit boundary method, band form: the driver.

    u = D u^h + u^a,   v = D v^h
    K = sum_p B_p^T C B_p V_p  +  int_bands (B~^T C B~ - B^T C B) dOmega
    f = (body force, lift and traction loads, split the same way)
"""
from __future__ import annotations

from time import perf_counter

import numpy as np

from ibm import dirichlet, forms
from ibm.bands import band_quadrature, edge_quadrature
from ibm.model import Model, Solution
from ibm.rigid import require_constrained
from ibm.solve import active_dofs, solve_system
from ibm.support import extension


def solve_ibm(model: Model, delta_rel: float = 1e-5, support_threshold: float = 1e-4,
              estimate_condition: bool = True) -> Solution:
    """Solve with Dirichlet functions of band width delta = delta_rel * h.

    Nodes whose support fraction int_Omega N_I / h^d is below `support_threshold` are
    extended from a well-supported neighbour cell (ibm.support); 0 switches that off.
    """
    start = perf_counter()
    grid, body = model.grid, model.body
    delta = delta_rel * grid.h

    def D(x, region=None):
        return dirichlet.matrix(body, x, delta, region=region)

    points, band = model.points.quadrature(), band_quadrature(body, grid, delta)
    edges = {k: edge_quadrature(body, grid, k, delta) for k in model.loads.tractions}

    def with_band(form):   # material-point form plus the exact band correction
        return form(model, points) + form(model, band, D) - form(model, band)

    K = forms.corrected_stiffness(model, points, band, D, assemble=False)   # = with_band(forms.stiffness)
    f = with_band(forms.body_force) + with_band(forms.lift_force) + forms.traction_force(model, edges, D)
    assembled = perf_counter()

    dofs = active_dofs(grid, points.cells, band.cells)
    tie = extension(grid, model.points, dofs, support_threshold)
    K, f = tie.reduce(K, f, dofs)   # CSR of the final unknowns, straight from K's slots
    # the extension reproduces linear fields, so rigid modes of the reduced system are exact
    require_constrained(K, grid, dofs[tie.kept])
    U = np.zeros(grid.dim * grid.n_nodes)
    kept_dofs = dofs[tie.kept]                                             # (x, y) pairs of the kept nodes
    kept, info = solve_system(K, f, estimate_condition, symmetric=True,  # T^T K T of a symmetric form
                              positions=grid.nodes()[kept_dofs[0::grid.dim] // grid.dim])
    U[dofs] = tie.T @ kept
    solved = perf_counter()

    evaluate = forms.field_evaluator(model, U, D)
    u, sigma, sigma_zz = evaluate(model.points.x, model.points.cells)
    info.update(ndof=len(tie.kept), n_extended=len(tie.extended), min_support=tie.min_support,
                n_band_points=len(band), delta=delta,
                time_assemble=assembled - start, time_solve=solved - assembled,
                time_s=perf_counter() - start)
    return Solution(u, sigma, sigma_zz, evaluate, info, nodal=U)
