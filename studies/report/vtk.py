"""ParaView files of one case (meshio, VTU): material points, background grid, body outline.

    STEM_points.vtu   vertex cells at the material points with point data
                      displacement, displacement_exact, displacement_error (3-vectors, z = 0),
                      stress, stress_exact (3x3 tensors, zz from plane strain), volume,
                      err_u, err_sigma (|error| / max |exact|, as in the error maps)
    STEM_grid.vtu     the background grid's quads (the whole covering grid)
    STEM_body.vtu     the body outline as line cells, with the edge kind as a cell field
Input is the dict of arrays of studies.run.runner.point_fields.

Large kinematics (studies.run.large.large_fields: "outline" and x of shape (k, n, 2)) gives a
ParaView time series instead (write_series):
    STEM_points_NNNN.vtu   per stored step NNNN: vertex cells at the current positions x with
                           displacement (x - X), displacement_exact, displacement_error,
                           stress (3x3), sigma_eta, sigma_eta_exact, sigma_eta_error, volume, J
    STEM_outline_NNNN.vtu  per stored step: the tracked outline as line cells, edge_kind as cell data
    STEM_grid.vtu          the background grid (the same at every step)
    STEM.pvd               the collection, timestep = load fraction t (written last)
"""
from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from ibm.norms import pointwise_relative

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


def _write_atomic(mesh: meshio.Mesh, directory: Path, name: str) -> Path:
    """Write `mesh` as directory/NAME.vtu through a temporary file, then replace."""
    path = directory / f"{name}.vtu"
    temporary = directory / f".{name}.tmp.vtu"
    meshio.write(temporary, mesh, binary=True)
    temporary.replace(path)
    return path


def _kind_codes(kinds) -> np.ndarray:
    return np.array([EDGE_KIND_CODES.get(str(k), -1) for k in kinds], dtype=int)


def series_points_mesh(fields: dict, k: int) -> meshio.Mesh:
    """Stored step k of large-kinematics fields: points at x[k] with displacement, stress, F and errors."""
    x, X = fields["x"][k], fields["X"]
    n = len(X)
    u = x - X
    u_exact = fields["u_exact"][k]
    s_eta, s_exact = fields["sigma_eta"][k], fields["sigma_exact"][k]
    volume = fields["volume"][k]
    data = {
        "displacement": _xyz(u), "displacement_exact": _xyz(u_exact), "displacement_error": _xyz(u - u_exact),
        "stress": np.asarray(fields["sigma"][k], float).reshape(n, 9),
        "sigma_eta": s_eta, "sigma_eta_exact": s_exact, "sigma_eta_error": s_eta - s_exact,
        "volume": volume, "J": volume / fields["V0"],
    }
    if "F" in fields:   # the deformation gradient (3 x 3, plane strain F_zz = 1)
        data["F"] = np.asarray(fields["F"][k], float).reshape(n, 9)
    return meshio.Mesh(_xyz(x), [("vertex", np.arange(n).reshape(-1, 1))], point_data=data)


def series_outline_mesh(fields: dict, k: int) -> meshio.Mesh:
    """Stored step k's outline: closed polygon, edge i from vertex i to i + 1, edge_kind per line cell."""
    vertices = fields["outline"][k]
    m = len(vertices)
    lines = np.stack([np.arange(m), (np.arange(m) + 1) % m], axis=1)
    return meshio.Mesh(_xyz(vertices), [("line", lines)], cell_data={"edge_kind": [_kind_codes(fields["outline_kind"])]})


def _pvd_text(entries: list[tuple[float, int, str]]) -> str:
    lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1">', "  <Collection>"]
    lines += [f'    <DataSet timestep="{t!r}" part="{part}" file={quoteattr(name)}/>'
              for t, part, name in entries]
    lines += ["  </Collection>", "</VTKFile>", ""]
    return "\n".join(lines)


def write_series(fields: dict, directory: str | Path, stem: str) -> list[Path]:
    """Large-kinematics time series: STEM_points_NNNN.vtu and STEM_outline_NNNN.vtu per stored step
    (NNNN = the step number), STEM_grid.vtu and the collection STEM.pvd (timestep = load fraction t,
    parts 0 points, 1 outline, 2 grid), written last; return the paths, the .pvd last."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = [_write_atomic(grid_mesh(fields["grid_h"], fields["grid_lower"], fields["grid_shape"]),
                           directory, f"{stem}_grid")]
    entries = []
    for k, (step, t) in enumerate(zip(np.asarray(fields["step"]).ravel(), np.asarray(fields["t"], float).ravel())):
        points = _write_atomic(series_points_mesh(fields, k), directory, f"{stem}_points_{int(step):04d}")
        outline = _write_atomic(series_outline_mesh(fields, k), directory, f"{stem}_outline_{int(step):04d}")
        paths += [points, outline]
        entries += [(float(t), 0, points.name), (float(t), 1, outline.name), (float(t), 2, paths[0].name)]
    pvd = directory / f"{stem}.pvd"
    temporary = directory / f".{stem}.tmp.pvd"
    temporary.write_text(_pvd_text(entries))
    temporary.replace(pvd)
    paths.append(pvd)
    return paths


def write_case(fields: dict, directory: str | Path, stem: str) -> list[Path]:
    """Write STEM_points.vtu, STEM_grid.vtu and STEM_body.vtu into `directory`; return the paths.
    Large-kinematics fields (an "outline" and x per step) go to write_series instead."""
    if "outline" in fields and np.ndim(fields["x"]) == 3:
        return write_series(fields, directory, stem)
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
