"""IBM-MPM core: implicit essential boundaries in an implicit Material Point Method.

Data flow: geometry.Body -> grid.Grid -> points.MaterialPoints -> bands (Dirichlet
functions and band quadrature) -> assembly -> solve -> recovery -> errors.
The core imports neither `baselines` nor `studies`.
"""
from ibm.geometry.outline import Body
from ibm.exceptions import InputError
from ibm.models.elastic import Elastic
from ibm.discretise.grid import Grid
from ibm.discretise.points import MaterialPoints, material_points
from ibm.small.model import Loads, Model, Solution, build_model
from ibm.implicit_boundary import solve_ibm

__all__ = [
    "Body", "InputError", "Elastic", "Grid", "MaterialPoints", "material_points",
    "Loads", "Model", "Solution", "build_model", "solve_ibm",
]
