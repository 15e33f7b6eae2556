"""Prandtl's smooth strip footing at small strain (studies.footing): q_max / c against 2 + pi."""
import pytest

from studies.footing import PRANDTL, run_footing

SMALL = dict(angle=90.0, width_over_B=3.0, depth_over_B=2.0, steps=20)


@pytest.mark.parametrize("method", ["lagrange", "penalty"])
def test_footing_edge_on_a_node_reaches_prandtl_within_five_percent_at_b_over_h_16(method):
    """The footing's edge on a grid node (offset 0): 5.33 c at B/h = 16 (5.50 at 8), 3.6 % above 2 + pi
    (measured the same for lagrange, penalty and nitsche); the plateau is flat to 0.1 %."""
    result = run_footing(method, offset=(0.0, 0.0), B_over_h=16, **SMALL)
    assert result["stopped"] is None
    assert 1.0 <= result["q_over_c"] / PRANDTL <= 1.05
    q = result["q"]
    assert abs(q[-1] - q[-3]) <= 1e-3 * q[-1]


def test_footing_locks_without_b_bar_and_a_mid_cell_edge_costs_one_cell():
    """B/h = 8: without B-bar the pressure keeps rising (locking); with the edge inside a cell
    (offset 0.37) the collapse pressure is 6.08 c against 5.50 c on a node: the constraint spreads
    over the cut cell (measured at B/h = 16: 5.72 c against 5.33 c)."""
    node = run_footing("lagrange", offset=(0.0, 0.0), B_over_h=8, **SMALL)
    locked = run_footing("lagrange", offset=(0.0, 0.0), B_over_h=8, locking="none", **SMALL)
    inside = run_footing("lagrange", offset=(0.37, 0.29), B_over_h=8, **SMALL)
    assert locked["q_over_c"] > 1.1 * node["q_over_c"] and locked["q"][-1] > locked["q"][-5] * 1.005
    assert inside["q_over_c"] > 1.05 * node["q_over_c"]
