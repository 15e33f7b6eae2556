"""ParaView files of one case (meshio, VTU): material points, background grid, body outline.

    STEM_points.vtu   vertex cells at the material points with point data
                      displacement, displacement_exact, displacement_error (3-vectors, z = 0),
                      stress, stress_exact (3x3 tensors, zz from plane strain), volume,
                      err_u, err_sigma (|error| / max |exact|, as in the error maps)
    STEM_grid.vtu     the background grid's quads (the whole covering grid)
    STEM_body.vtu     the body outline as line cells, with the edge kind as a cell field
Input is the dict of arrays of studies.runner.point_fields.
"""
from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from ibm.errors import pointwise_relative

EDGE_KIND_CODES = {"free": 0, "traction": 1, "roller": 2, "fixed": 3}


def _xyz(x: np.ndarray) -> np.ndarray:
    """(n, 2) -> (n, 3) with z = 0."""
    return np.column_stack([x, np.zeros(len(x))])


def _tensor3(sigma: np.ndarray, zz: np.ndarray) -> np.ndarray:
    """(n, 2, 2) in-plane stress and (n,) sigma_zz -> (n, 3, 3) flattened to (n, 9)."""
    full = np.zeros((len(sigma), 3, 3))
    full[:, :2, :2] = sigma
    full[:, 2, 2] = zz
    return full.reshape(len(sigma), 9)


def grid_mesh(h: float, lower, shape) -> meshio.Mesh:
    nx, ny = (int(s) for s in shape)
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1))
    nodes = (np.array(lower, float) + np.stack([i.ravel(), j.ravel()], axis=1)) * float(h)   # (n_nodes, 2)
    ci, cj = np.meshgrid(np.arange(nx), np.arange(ny))
    first = (cj * (nx + 1) + ci).ravel()
    quads = np.stack([first, first + 1, first + nx + 2, first + nx + 1], axis=1)   # (n_cells, 4) CCW
    return meshio.Mesh(_xyz(nodes), [("quad", quads)])


def points_mesh(fields: dict) -> meshio.Mesh:
    x = fields["x"]
    n = len(x)
    err_u, err_sigma = pointwise_relative(fields["u_h"], fields["u"], fields["sigma_h"], fields["sigma"],
                                          fields["direction"])
    data = {
        "displacement": _xyz(fields["u_h"]), "displacement_exact": _xyz(fields["u"]),
        "displacement_error": _xyz(fields["u_h"] - fields["u"]),
        "stress": _tensor3(fields["sigma_h"], fields["zz_h"]), "stress_exact": _tensor3(fields["sigma"], fields["zz"]),
        "volume": fields["volume"], "err_u": err_u, "err_sigma": err_sigma,
    }
    return meshio.Mesh(_xyz(x), [("vertex", np.arange(n).reshape(-1, 1))], point_data=data)


def body_mesh(fields: dict) -> meshio.Mesh:
    vertices = fields["vertices"]
    m = len(vertices)
    lines = np.stack([np.arange(m), (np.arange(m) + 1) % m], axis=1)
    kinds = np.array([EDGE_KIND_CODES.get(str(k), -1) for k in fields["kinds"]])
    return meshio.Mesh(_xyz(vertices), [("line", lines)], cell_data={"edge_kind": [kinds]})


def write_case(fields: dict, directory: str | Path, stem: str) -> list[Path]:
    """Write STEM_points.vtu, STEM_grid.vtu and STEM_body.vtu into `directory`; return the paths."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    meshes = {"grid": grid_mesh(fields["grid_h"], fields["grid_lower"], fields["grid_shape"]),
              "body": body_mesh(fields), "points": points_mesh(fields)}   # points last: it marks completion
    paths = []
    for name, mesh in meshes.items():
        path = directory / f"{stem}_{name}.vtu"
        temporary = directory / f".{stem}_{name}.tmp.vtu"
        meshio.write(temporary, mesh, binary=True)
        temporary.replace(path)
        paths.append(path)
    return paths
