"""What the collapse runs (studies.problems.collapse's cylinder, studies.problems.footing) share: the IBM's band
width on yielding bodies, the final plastic field a study keeps and the count of step cuts."""
from __future__ import annotations

import numpy as np
from skfem import Basis, ElementTriP2, ElementVector

from baselines.registry import METHODS
from ibm.discretise.grid import Grid
from ibm.exceptions import StepFailure

# The IBM's band on these yielding bodies is 1e-2 h unless given (1e-1 h under the rough footing):
# the first Newton iterate puts the walls' motion into the band (strains ~ motion / delta), the
# band's points yield, and with the seed's 1e-5 h the correction's stiffness turns negative
# (docs/choices.md).
IBM_BAND = {"smooth": 1e-2, "rough": 1e-1}


def until_failure(solve, *args, **kwargs):
    """(progress, None) of solve(*args, **kwargs), or (the last converged state, the failure's message)
    when a step fails for good: past a collapse load the steps stop, and what converged stands."""
    try:
        return solve(*args, **kwargs), None
    except StepFailure as error:
        return error.progress, str(error)


def with_defaults(method: str, parameters: dict | None, footing: str = "smooth") -> dict:
    """The method's parameters on a collapse problem: a band's width IBM_BAND h unless given."""
    parameters = dict(parameters or {})
    if "delta_rel" in METHODS[method].names:
        parameters.setdefault("delta_rel", IBM_BAND.get(footing, IBM_BAND["smooth"]))
    return parameters


def final_fields(body, h: float, margin: int, order: int, progress) -> dict[str, np.ndarray]:
    """The points of the last converged (sub)step at their places in the body (small strain: the
    initial ones): x (n, 2) (the grid methods' material points, fem's Gauss points, element by
    element), their equivalent plastic strain alpha (n,), volume (n,),
    the load fraction t, the body's outline and kinds, and the grid (grid methods) or the mesh's
    triangles (fem: corners (n_elements, 3, 2)). body, h: the run's; margin: its grid's cells around
    the body (grid methods); order: fem's Gauss rule (0 for the grid methods); progress: the last
    converged (sub)step's (None, or one without steps, if none converged)."""
    outline, piece = body.polyline()
    fields = {"outline_points": outline, "outline_piece": piece, "vertices": body.vertices,
              "kinds": np.array(body.kinds)}
    if progress is None or not progress.steps:                # not one step converged
        return {**fields, "x": np.zeros((0, 2)), "alpha": np.zeros(0), "volume": np.zeros(0), "t": np.array(0.0)}
    alpha = progress.state.internal["alpha"]
    if order:                                                 # fem: the Gauss points of its P2 mesh
        basis = Basis(progress.polygon.mesh, ElementVector(ElementTriP2()), intorder=order)
        x, volume = np.asarray(basis.global_coordinates().value).reshape(2, -1).T, basis.dx.ravel()
        mesh = progress.polygon.mesh
        fields["triangles"] = mesh.p[:, mesh.t[:3]].transpose(2, 1, 0)
    else:
        grid = Grid.covering(body, h, margin)
        x, volume = progress.X, progress.V0
        fields.update(grid_h=np.array(grid.h), grid_lower=np.array(grid.lower), grid_shape=np.array(grid.shape))
    if len(x) != len(alpha):
        raise RuntimeError(f"the collapse run's {len(alpha)} point states do not match its {len(x)} points")
    return {**fields, "x": np.asarray(x, float), "alpha": np.asarray(alpha, float),
            "volume": np.asarray(volume, float), "t": np.array(float(progress.t))}


def step_cuts(progress) -> int:
    """The step cuts of a load-step run's converged steps (a failed last step's are not counted)."""
    return int(sum(s["cuts"] for s in progress.steps))
