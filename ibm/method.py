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
from ibm.solve import active_dofs, solve_system


def solve_ibm(model: Model, delta_rel: float = 1e-5, estimate_condition: bool = True) -> Solution:
    """Solve with Dirichlet functions of band width delta = delta_rel * h."""
    start = perf_counter()
    grid, body = model.grid, model.body
    delta = delta_rel * grid.h

    def D(x):
        return dirichlet.matrix(body, x, delta)

    points, band = model.points.quadrature(), band_quadrature(body, grid, delta)
    edges = {k: edge_quadrature(body, grid, k, delta) for k in model.loads.tractions}

    def with_band(form):   # material-point form plus the exact band correction
        return form(model, points) + form(model, band, D) - form(model, band)

    K = with_band(forms.stiffness)
    f = with_band(forms.body_force) + with_band(forms.lift_force) + forms.traction_force(model, edges, D)
    assembled = perf_counter()

    dofs = active_dofs(grid, points.cells, band.cells)
    U = np.zeros(2 * grid.n_nodes)
    U[dofs], info = solve_system(K[dofs][:, dofs], f[dofs], estimate_condition)
    solved = perf_counter()

    evaluate = forms.field_evaluator(model, U, D)
    u, sigma, sigma_zz = evaluate(points.x, points.cells)
    info.update(ndof=len(dofs), n_band_points=len(band), delta=delta,
                time_assemble=assembled - start, time_solve=solved - assembled,
                time_s=perf_counter() - start)
    return Solution(u, sigma, sigma_zz, evaluate, info)
