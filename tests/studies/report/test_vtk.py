"""ParaView time series of a large-deformation case (studies.report.vtk.write_series)."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from studies.report import vtk
from studies.run.case import CaseSpec, run_case
from studies.cli import main

SPEC = CaseSpec(problem="column", method="nodal", angle=90, cell=6.25, ppc=2, offset=(0, 0), nu=0.0, load=40000,
                width=6.25, height=50, kinematics="large", steps=4)


@pytest.fixture(scope="module")
def fields():
    return run_case(SPEC, keep_fields=True)["fields"]


def _datasets(pvd):
    root = ET.parse(pvd).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection" and root.get("version") == "0.1"
    return [(float(d.get("timestep")), int(d.get("part")), d.get("file")) for d in root.iter("DataSet")]


def test_series_files_and_collection(fields, tmp_path):
    paths = vtk.write_case(fields, tmp_path, "col")          # dispatches to write_series
    assert paths[-1] == tmp_path / "col.pvd" and all(p.exists() for p in paths)
    assert not list(tmp_path.glob(".*"))                       # no temporaries left
    datasets = _datasets(paths[-1])
    times = sorted({t for t, _, _ in datasets})
    assert len(times) == 4
    np.testing.assert_allclose(times, [0.25, 0.5, 0.75, 1.0], atol=1e-12)
    np.testing.assert_allclose(times, fields["t"], atol=0)
    assert len(datasets) == 3 * 4 and {p for _, p, _ in datasets} == {0, 1, 2}
    for _, _, name in datasets:
        assert (tmp_path / name).exists(), name
    assert {name for _, part, name in datasets if part == 2} == {"col_grid.vtu"}

    last = fields["step"][-1]
    points = meshio.read(tmp_path / f"col_points_{last:04d}.vtu")
    data = points.point_data
    X, x = fields["X"], fields["x"][-1]
    np.testing.assert_allclose(points.points[:, :2], x, atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["displacement"][:, :2], x - X, atol=1e-12, rtol=0)
    assert np.all(data["displacement"][:, 2] == 0)
    assert np.max(np.abs(x - X)) > 1e-3                        # the body did deform
    np.testing.assert_allclose(data["displacement_exact"][:, :2], fields["u_exact"][-1], atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["displacement_error"][:, :2], x - X - fields["u_exact"][-1], atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["stress"], fields["sigma"][-1].reshape(-1, 9), atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["sigma_eta"], fields["sigma_eta"][-1], atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["sigma_eta_exact"], fields["sigma_exact"][-1], atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["sigma_eta_error"], data["sigma_eta"] - data["sigma_eta_exact"], atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["sigma_eta_error"], fields["sigma_eta"][-1] - fields["sigma_exact"][-1],
                               atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["volume"], fields["volume"][-1], atol=1e-12, rtol=0)
    np.testing.assert_allclose(data["J"], fields["volume"][-1] / fields["V0"], atol=1e-12, rtol=0)
    F = data["F"].reshape(-1, 3, 3)
    np.testing.assert_allclose(F, fields["F"][-1], atol=1e-12, rtol=0)
    np.testing.assert_allclose(np.linalg.det(F), data["J"], rtol=1e-12)   # volumes follow det F

    outline = meshio.read(tmp_path / f"col_outline_{last:04d}.vtu")
    m = fields["outline"].shape[1]
    lines = outline.get_cells_type("line")
    assert len(lines) == m == len(fields["outline_kind"])
    np.testing.assert_allclose(outline.points[:, :2], fields["outline"][-1], atol=1e-12, rtol=0)
    codes = [vtk.EDGE_KIND_CODES[str(k)] for k in fields["outline_kind"]]
    np.testing.assert_array_equal(outline.cell_data["edge_kind"][0], codes)

    grid = meshio.read(tmp_path / "col_grid.vtu")
    assert len(grid.get_cells_type("quad")) == int(np.prod(fields["grid_shape"]))


def test_small_strain_fields_keep_the_single_files(tmp_path):
    from studies.run.runner import point_fields
    spec = CaseSpec(problem="column", method="nodal", angle=90, cell=6.25, ppc=2, offset=(0, 0), nu=0.0,
                    load=40000, width=6.25, height=50)
    paths = vtk.write_case(point_fields(run_case(spec, keep_fields=True)["fields"]), tmp_path, "s")
    assert sorted(p.name for p in paths) == ["s_body.vtu", "s_grid.vtu", "s_points.vtu"]


def test_solve_large_writes_the_series(tmp_path, capsys):
    out = tmp_path / "vtk"
    assert main(["solve", "--problem", "column", "--method", "nodal", "--angle", "90", "--cell", "6.25",
                 "--offset", "0", "0", "--width", "6.25", "--height", "50", "--nu", "0", "--load", "40000",
                 "--kinematics", "large", "--steps", "2", "--vtk", str(out)]) == 0
    pvds = list(out.glob("*.pvd"))
    assert len(pvds) == 1
    assert str(pvds[0]) in capsys.readouterr().err
    datasets = _datasets(pvds[0])
    np.testing.assert_allclose(sorted({t for t, _, _ in datasets}), [0.5, 1.0], atol=1e-12)
    assert all((out / name).exists() for _, _, name in datasets)
