"""The peer's measured results, for figures and tables drawn beside ours.

AMPLE-m (Coombs & Augarde's implicit large-deformation MPM in MATLAB), commit 4cbd757, run in
GNU Octave 7.3.0 on a 2-core AMD EPYC machine: the self-weight column of its setupGrid.m
(E = 1e4, nu = 0, rho g H = 40000 at H = 50, one cell wide, 2 x 2 points per cell, 40 load
steps, Newton tolerance 1e-9), `err_sigma` its own column measure (our err_sigma_ample).
time_s is the load-step loop as AMPLE times it, process_s the whole Octave command.
"""
from __future__ import annotations

AMPLE_COLUMN = {   # basis -> cells up the column -> measured values
    "gimp": {16: {"err_sigma_ample": 3.658906e-3, "time_s": 9.308, "process_s": 9.492},
             32: {"err_sigma_ample": 1.048706e-3, "time_s": 18.324, "process_s": 18.486},
             64: {"err_sigma_ample": 4.357237e-4, "time_s": 39.37, "process_s": 39.598}},
    "mpm": {16: {"err_sigma_ample": 8.669649e-2, "time_s": 9.787, "process_s": 9.957},
            32: {"err_sigma_ample": 8.005598e-2, "time_s": 19.332, "process_s": 19.5},
            64: {"err_sigma_ample": 8.288698e-2, "time_s": 39.2, "process_s": 39.425}},
}
AMPLE_SETUP = {"problem": "column", "E": 1e4, "nu": 0.0, "load": 40000.0, "height": 50.0, "ppc": 2, "steps": 40,
               "angle": 90.0}


def ample_points(rows, basis: str) -> list[tuple[float, float]]:
    """(h, err_sigma_ample) of AMPLE-m for the rows' setup, or [] when the rows are not its column."""
    import numpy as np
    if basis not in AMPLE_COLUMN or not len(rows):
        return []
    for key, value in AMPLE_SETUP.items():
        if key not in rows or not np.all(rows[key].to_numpy() == value):
            return []
    return [(AMPLE_SETUP["height"] / cells, entry["err_sigma_ample"]) for cells, entry in AMPLE_COLUMN[basis].items()]
