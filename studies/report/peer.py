"""The peer's measured results, for figures and tables drawn beside ours.

AMPLE-m (Coombs & Augarde's implicit large-deformation MPM in MATLAB), commit 4cbd757, run in
GNU Octave 7.3.0 on a 2-core AMD EPYC machine: the self-weight column of its setupGrid.m
(E = 1e4, nu = 0, rho g H = 40000 at H = 50, one cell wide, 2 x 2 points per cell, 40 load
steps, Newton tolerance 1e-9), `err_sigma` its own column measure (our err_sigma_ample).
time_s is the load-step loop as AMPLE times it, process_s the whole Octave command.
"""
from __future__ import annotations

import numpy as np

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
    if basis not in AMPLE_COLUMN or not len(rows):
        return []
    for key, value in AMPLE_SETUP.items():
        if key not in rows or not np.all(rows[key].to_numpy() == value):
            return []
    return [(AMPLE_SETUP["height"] / cells, entry["err_sigma_ample"]) for cells, entry in AMPLE_COLUMN[basis].items()]


# AMPLE-m's elasto-plastic collapse (its setup/setupGrid_collapse.m, commit 4cbd757, the same
# Octave on the same 2-core machine, shared): the 16 x 8 block's half model, h = 2 / A, 6 x 6
# points per cell, 40 steps, Newton tolerance 1e-9. Its final points: the peak (highest point, and
# its x), the axis height (highest point of the column of points next to x = 0), the runout
# (furthest point); the virial identities of studies.problems.ample_collapse (its GIMP domains reach past
# its grid, which has no nodes there, so its virial_xx is not zero); its Newton solves per step
# (its count less one: its first pass only assembles); loop_s its load-step loop, user_s and
# wall_s the whole Octave command (/usr/bin/time).
AMPLE_COLLAPSE = {   # (basis, h, ppc, steps) -> measured values
    ("gimp", 1.0, 6, 40): {"npoints": 2304, "y_peak": 6.17284283, "x_peak": 8.51861459, "y_axis": 5.22658853,
                           "runout": 13.70056779, "virial_xx": 1.516e-4, "virial_yy_minus_1": 1.018e-4,
                           "loop_s": 4016.1, "user_s": 1384.4, "wall_s": 4016.9},
    ("gimp", 2.0, 6, 40): {"npoints": 576, "y_peak": 6.21776278, "x_peak": 8.53595778, "y_axis": 5.05770877,
                           "runout": 13.28725767, "virial_xx": 6.726e-4, "virial_yy_minus_1": 3.397e-4,
                           "loop_s": 1496.6, "user_s": 345.9, "wall_s": 1497.5},
    ("mpm", 2.0, 6, 40): {"npoints": 576, "y_peak": 6.27068384, "x_peak": 8.52510595, "y_axis": 5.03467027,
                          "runout": 13.19345593, "virial_xx": -3.1e-14, "virial_yy_minus_1": 1.1e-15,
                          "loop_s": 1398.6, "user_s": 333.4, "wall_s": 1400.2},
}
# The standard-MPM run at h = 2 step by step (its history, 10 digits): axis height and runout, steps 1-40.
AMPLE_COLLAPSE_MPM_H2_HISTORY = {
    "y_axis": [7.825687651, 7.818060297, 7.810451162, 7.802860137, 7.795287114, 7.787731985, 7.780194643,
               7.772674983, 7.765172899, 7.757688286, 7.750221042, 7.742771061, 7.735338242, 7.727922482,
               7.72052368, 7.713141735, 7.700635064, 7.683506222, 7.663029633, 7.617694235, 7.576999826, 7.518345261,
               7.412645236, 7.283843304, 7.117432747, 6.926158536, 6.731556858, 6.523836399, 6.334411489,
               6.138966583, 5.974445927, 5.83748575, 5.700300732, 5.574026154, 5.46318344, 5.365654262,
               5.272698064, 5.193986026, 5.107053002, 5.034670267],
    "runout": [7.837953972, 7.842573504, 7.847191926, 7.851809235, 7.856425428, 7.8610405, 7.865654448,
               7.870267268, 7.874878958, 7.879489513, 7.884098931, 7.888707207, 7.893314339, 7.897920323,
               7.902525155, 7.907128832, 7.918442144, 7.937684762, 7.961897836, 8.01568873, 8.072694508, 8.153976404,
               8.300977963, 8.46573667, 8.704677823, 8.979929895, 9.283957483, 9.609864233, 9.925192316,
               10.25915173, 10.55840514, 10.84184903, 11.13839396, 11.44087569, 11.75915144, 12.0721269,
               12.37000658, 12.64470657, 12.91203704, 13.19345593],
}
