"""Prandtl's smooth strip footing at small strain (studies.problems.footing): q_max / c against 2 + pi."""
import pytest

from studies.problems.footing import PRANDTL, run_footing

SMALL = dict(angle=90.0, width_over_B=3.0, depth_over_B=2.0, steps=20)


@pytest.mark.parametrize("method,angle", [("lagrange", 90.0), ("penalty", 90.0), ("ibm", 90.0), ("lagrange", 30.0),
                                          ("ibm", 30.0)])
def test_footing_edge_on_a_node_reaches_prandtl_within_five_percent_at_b_over_h_16(method, angle):
    """The footing's edge on a grid node (offset 0), B/h = 16: at 90 degrees 5.33 c (lagrange,
    penalty, nitsche; 3.6 % above 2 + pi) and 5.34 c (ibm, 3.8 %); at 30 degrees, where the footing
    and every side cut the grid, 5.37 c (lagrange, 4.5 %) and 5.38 c (ibm, 4.6 %). The plateau is
    flat to 0.1 %."""
    result = run_footing(method, offset=(0.0, 0.0), B_over_h=16, **{**SMALL, "angle": angle})
    assert result["stopped"] is None
    assert 1.0 <= result["q_over_c"] / PRANDTL <= 1.05
    q = result["q"]
    assert abs(q[-1] - q[-3]) <= 1e-3 * q[-1]


@pytest.mark.slow
@pytest.mark.parametrize("method", ["lagrange", "ibm"])
def test_footing_at_b_over_h_32_inclined_is_within_three_percent(method):
    """B/h = 32 at 30 degrees, the edge on a node (13k unknowns, 20 steps): 5.26 c for both (2.3 %
    above 2 + pi); at 90 degrees 5.24 (lagrange) and 5.25 (ibm), measured."""
    result = run_footing(method, offset=(0.0, 0.0), B_over_h=32, **{**SMALL, "angle": 30.0})
    assert result["stopped"] is None and 1.0 <= result["q_over_c"] / PRANDTL <= 1.03


def test_the_offset_places_the_footings_edge_at_every_angle():
    """offset (0, 0) puts the edge (B/2, H) of the local frame on a grid node at 30 degrees too, while
    the corner and the sides are off the grid lines."""
    import numpy as np

    from ibm.geometry.frames import frame_of_angle
    from studies.problems.footing import edge_corner
    h, B, H = 0.0625, 1.0, 2.0
    for offset in [(0.0, 0.0), (0.37, 0.29)]:
        corner = edge_corner(30.0, offset, h, B, H)
        edge = corner + frame_of_angle(30.0) @ np.array([B / 2, H])
        assert np.allclose(edge / h - np.round(edge / h - np.array(offset)), offset, atol=1e-9)
        assert np.abs(corner / h - np.round(corner / h)).max() > 0.05


def test_the_edge_inside_a_cell_costs_most_at_mid_cell():
    """B/h = 8 at 90 degrees: q_max / c is 5.50 with the edge on a node, 5.80, 6.04 and 5.82 with it a
    quarter, a half and three quarters across its cell: symmetric about mid-cell, so the cost is
    the fan's centre (the mechanism's singular point) inside one bilinear cell, not the footing's
    constraint reaching the cell's far node (which would rise towards the near end)."""
    q = [run_footing("lagrange", offset=(x, 0.0), B_over_h=8, **SMALL)["q_over_c"] for x in (0.0, 0.25, 0.5, 0.75)]
    assert q[2] > max(q[1], q[3]) > min(q[1], q[3]) > q[0]
    assert abs(q[1] - q[3]) < 0.02 * q[2] and q[2] > 1.08 * q[0]


def test_footing_locks_without_b_bar_and_a_mid_cell_edge_costs_more():
    """B/h = 8: without B-bar the pressure keeps rising (locking); with the edge inside a cell
    (offset 0.37, 0.29) the collapse pressure is 6.08 c against 5.50 c on a node (measured at B/h = 16:
    5.72 c against 5.33 c)."""
    node = run_footing("lagrange", offset=(0.0, 0.0), B_over_h=8, **SMALL)
    locked = run_footing("lagrange", offset=(0.0, 0.0), B_over_h=8, locking="none", **SMALL)
    inside = run_footing("lagrange", offset=(0.37, 0.29), B_over_h=8, **SMALL)
    assert locked["q_over_c"] > 1.1 * node["q_over_c"] and locked["q"][-1] > locked["q"][-5] * 1.005
    assert inside["q_over_c"] > 1.05 * node["q_over_c"]


def test_footing_from_the_command_line(capsys):
    """--cell 20 gives B/h = 8 (B = 160): 6.07 c with the edge inside a cell at the default offset."""
    import json

    from studies.cli import main
    code = main(["solve", "--problem", "footing", "--method", "penalty", "--cell", "20", "--steps", "20", "--ppc", "2",
                 "--basis", "mpm", "--locking", "fbar", "--json"])
    record = json.loads(capsys.readouterr().out)
    assert code == 0 and record["B_over_h"] == 8.0 and record["c"] == pytest.approx(100 / 3 ** 0.5)
    assert 1.1 <= record["q_over_c"] / PRANDTL <= 1.25 and len(record["q"]) == len(record["settlement"]) == 20


@pytest.mark.parametrize("arguments,message", [
    (["--method", "nodal", "--ppc", "2"], "method 'nodal' refuses walls off the grid lines"),
    (["--yield-stress", "50"], "problem 'footing' has its own material, geometry and load (B = 160"),
    (["--ppc", "1"], "ppc 1 is not allowed for 'footing'; it must be >= 2"),
    (["--footing", "glued", "--ppc", "2"], "footing 'glued' is not allowed; allowed: smooth, rough"),
])
def test_bad_footing_options_are_one_line(arguments, message, capsys):
    from studies.cli import main
    assert main(["solve", "--problem", "footing", "--steps", "20"] + arguments) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_body_fitted_fem_footing_is_within_five_percent_at_b_over_h_16_inclined():
    """P2 triangles with the footing's edge a mesh vertex, at 30 degrees: 5.29 c at B/h = 16 (2.9 %
    above 2 + pi; 5.42 c at 8), its force the residual at the footing's constrained DOFs."""
    result = run_footing("fem", angle=30.0, B_over_h=16, **{k: v for k, v in SMALL.items() if k != "angle"})
    assert result["stopped"] is None and 1.0 <= result["q_over_c"] / PRANDTL <= 1.05


def test_rough_footing_is_only_for_the_footing(capsys):
    from studies.cli import main
    assert main(["solve", "--problem", "confined-block", "--footing", "rough"]) == 2
    err = capsys.readouterr().err
    assert "footing 'rough' is for problem 'footing', not 'confined-block'" in err
    assert len(err.strip().splitlines()) == 1


def test_f_bar_at_large_strain_collapses_the_footing_and_its_lack_locks():
    """Von Mises on Hencky in the updated Lagrangian loop, B/h = 8 at 90 degrees, the edge on a node:
    with F-bar (each point stressed with its cell's mean Jacobian) q_max = 5.56 c (the small-strain
    B-bar's 5.50, with the current depth and geometry), then a plateau slowly falling (5.54 c);
    without it 6.70 c and still rising at the last step (6.58 c at small strain)."""
    fbar = run_footing("lagrange", offset=(0.0, 0.0), B_over_h=8, kinematics="large", **SMALL)
    locked = run_footing("lagrange", offset=(0.0, 0.0), B_over_h=8, kinematics="large", locking="none", **SMALL)
    assert fbar["stopped"] is None and locked["stopped"] is None and fbar["kinematics"] == "large"
    assert 1.0 <= fbar["q_over_c"] / PRANDTL <= 1.10 and abs(fbar["q"][-1] - fbar["q"][-3]) <= 5e-3 * fbar["q"][-1]
    assert locked["q_over_c"] > 1.15 * fbar["q_over_c"] and locked["q"][-1] > 1.004 * locked["q"][-3]


def test_rigid_footing_in_contact_is_the_smooth_footing_with_its_edge_on_a_node():
    """The footing as a rigid body the soil's free top touches (frictionless contact, footing 'rigid'): with its
    edge on a grid node it carries what the smooth roller footing carries, 5.502 c at B/h = 8 (penalty; the
    contact force on the rigid body, which the domain's test field gives too)."""
    rigid = run_footing("penalty", offset=(0.0, 0.0), B_over_h=8, footing="rigid", **SMALL)
    smooth = run_footing("penalty", offset=(0.0, 0.0), B_over_h=8, **SMALL)
    assert rigid["stopped"] is None and rigid["footing"] == "rigid"
    assert rigid["q_over_c"] == pytest.approx(smooth["q_over_c"], rel=2e-3)
    assert rigid["q_over_c"] == pytest.approx(5.502, rel=2e-3)


@pytest.mark.slow
def test_rigid_footing_costs_less_with_its_edge_mid_cell():
    """Mid-cell (offset 0.5) at B/h = 8 the rigid footing gives 5.90 c where the roller footing gives 6.15 c:
    contact lets the soil beside the edge leave the footing's corner, but the cost of the edge inside a
    bilinear cell stays most of what it was (docs/contact.md)."""
    rigid = run_footing("penalty", offset=(0.5, 0.0), B_over_h=8, footing="rigid", **SMALL)
    smooth = run_footing("penalty", offset=(0.5, 0.0), B_over_h=8, **SMALL)
    assert rigid["q_over_c"] == pytest.approx(5.90, rel=5e-3) and smooth["q_over_c"] == pytest.approx(6.15, rel=5e-3)


@pytest.mark.parametrize("arguments,message", [
    (["--footing", "rigid", "--method", "ibm"], "method 'ibm' refuses contact walls"),
    (["--footing", "rigid", "--method", "fem", "--locking", "none"], "footing 'rigid' is for the grid methods"),
    (["--footing", "rigid", "--friction", "0.3", "--adhesion", "1"], "not both"),
    (["--friction", "0.3"], "friction 0.3 is for a problem with a contact wall"),
    (["--footing", "rigid", "--kinematics", "large"], "kinematics 'large' is not allowed for the rigid footing"),
])
def test_bad_rigid_footing_options_are_one_line(arguments, message, capsys):
    from studies.cli import main
    assert main(["solve", "--problem", "footing", "--steps", "20", "--ppc", "2", "--method", "penalty"]
                + arguments) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
