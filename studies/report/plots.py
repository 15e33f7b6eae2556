"""Figures of a study (matplotlib, Agg), gathered by name: the report draws a figure by the name of its
function here ("plots.error_vs"). They are drawn in studies.report.sweep_lines (error against a swept
setting, the 3D cases' errors against orientation), studies.report.maps (error maps, the 3D cases' per-point
errors in a perspective view), studies.report.large_deformation (the column's load steps, profile and
snapshots), studies.report.collapse_figures (the collapse problems' curves and plastic zones) and
studies.report.contact_figures (the contact problems' measures against the load), from the pieces of
studies.report.panels, and written by studies.report.canvas.

Every function takes the results rows of one sweep (and its axes), writes one PNG and returns its path. Failed
cases are drawn as red crosses on the bottom edge of the axes, never as numbers (on the collapse curves: named
in the panel).
"""
from __future__ import annotations

from studies.report.canvas import DRAWN, finish_figure
from studies.report.collapse_figures import collapse_curves, plastic_zones
from studies.report.contact_figures import contact_curves
from studies.report.large_deformation import (
    error_vs_h_with_peer, error_vs_step, newton_iterations, snapshots, stress_profile
)
from studies.report.maps import error_maps, error_view_3d
from studies.report.sweep_lines import cond_vs, error_vs, error_vs_orientation, error_vs_placement

# DRAWN: the PNG and pixels of the figure written last (the report reads them here). finish_figure, which writes
# every figure: a test that wraps it in the modules that call it wraps it here too, so that the report sees
# the patch and draws in the test's process.
__all__ = ["DRAWN", "finish_figure", "collapse_curves", "contact_curves", "cond_vs", "error_maps", "error_view_3d", "error_vs",
           "error_vs_h_with_peer", "error_vs_orientation", "error_vs_placement", "error_vs_step", "newton_iterations",
           "plastic_zones", "snapshots", "stress_profile"]

# The drawing functions as gathered here: the report draws in worker processes only while these are untouched
# here (a test that patches one, to watch or count, gets every figure drawn in its process).
PRISTINE = {name: globals()[name] for name in __all__ if callable(globals()[name])}
