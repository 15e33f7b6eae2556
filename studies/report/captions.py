"""The "how to read" captions: the one line the page shows under every figure, by figure kind
(studies.report.figures.Plan puts it on each figure it plans)."""
from __future__ import annotations

# One line under every figure, by kind: what is drawn and which way is better.
_FAILED = "red crosses on the bottom edge are failed cases"
READING = {
    "error-vs-h": ("each line one series, one panel per error measure; lower is better; the dotted guides have "
                   "slopes 1 and 2, so a line parallel to one converges at that order; " + _FAILED),
    "error-vs-angle": ("each line one series, one panel per error measure; lower is better; a flat line means the "
                       "error does not depend on how the body is inclined to the grid; " + _FAILED),
    "error-vs": "each line one series, one panel per error measure; lower is better; " + _FAILED,
    "cond-vs": ("each line one series; lower means a better-conditioned linear system (1-norm estimate of the "
                "equilibrated matrix); " + _FAILED),
    "error-vs-placement": ("one column per series: each dot one random placement of the body in the grid, the bar "
                           "their median; lower is better, a tall spread means the error depends on where the body "
                           "sits; " + _FAILED),
    "error-vs-orientation": ("each line one series, one panel per error measure, the orientations (angle θ about "
                             "z, then tilt ψ about the body's own ξ axis) along x in the sweep's order; lower is "
                             "better; a flat line means the error does not depend on how the body sits in the grid; "
                             + _FAILED),
    "error-view-3d": ("the material points of one case in perspective, each dot coloured by its error (log scale, "
                      "yellow worst), displacement left and loaded-direction stress right, inside the box's edges "
                      "(grey), its faces tinted by boundary kind (blue roller, orange traction, grey free)"),
    "error-maps": ("one column per case, each square one material point coloured by its error (log scale, yellow "
                   "worst), displacement on top and stress below; the outline shows the boundary kind (blue roller, "
                   "black fixed, orange traction, grey free) over the background grid"),
    "error-vs-step": ("each line one case, one panel per error measure; lower is better; a line that climbs with the "
                      "step means the error builds up as the body deforms"),
    "newton-iterations": ("each line one case: the Newton iterations a load step needed (its step cuts included); "
                          "flat and low means every step converged easily, spikes mark the hard steps"),
    "error-vs-h-peer": ("each line one series; lower is better; open circles (where AMPLE-m ran the same case) are "
                        "the peer's own errors, so a line through or below them matches it; the dotted guides have "
                        "slopes 1 and 2; " + _FAILED),
    "stress-profile": ("each marker one material point at the last step, its stress (x) against its initial height "
                       "(y); the black line is the exact solution, so markers on it are exact and scatter is error"),
    "snapshots": ("left to right the body at four load steps: its outline (coloured by boundary kind), the "
                  "background grid, and the points coloured by stress error over the largest exact stress (log "
                  "scale, yellow worst)"),
    "scaling": ("log-log, one line per phase (left) and for memory (right); the fitted exponent p in the legend is "
                "the slope: p = 1 means cost grows in proportion to the unknowns, lower is better"),
    "load-settlement": ("one panel per angle and B/h, one colour per method (dashed: locked, locking none; a method "
                        "listed earlier is drawn wider, so equal curves show as stripes); each dot a converged load "
                        "step; a curve that levels off on the dashed 2 + π line has found Prandtl's collapse pressure, "
                        "one above it overshoots, one still climbing has not collapsed"),
    "pressure-expansion": ("one panel per angle and h, one colour per method (dashed: locked, locking none; a method "
                           "listed earlier is drawn wider, so equal curves show as stripes); each dot a converged load "
                           "step; the thick grey curve is Hill's, so dots on it are right, and a curve that stops at "
                           "the dashed p_lim line has collapsed where it should"),
    "contact-curves": ("one panel per measure the problem compares, against the load fraction t, one colour per "
                       "method; the thin black line with dots is each case's exact value, so a curve on it is right; "
                       "the last panel is the largest penetration in each step (log; lower is better, a penalty's "
                       "falls as 1/beta0)"),
    "locking": ("one panel per case run both ways: dashed without a remedy for locking (none), solid with B-bar "
                "(fbar), the exact limit dashed black; the gap between the two is what locking adds"),
    "plastic-zones": ("one panel per case (at the sweep's finest h) at its last converged step, each square a "
                      "material point (fem: each triangle, its Gauss points' mean) coloured by the equivalent plastic "
                      "strain on a log scale (dark: most), grey where it stayed elastic; the coloured region is the "
                      "collapse mechanism"),
}


def how_to_read(kind: str) -> str:
    """The one-line caption of a figure kind ("error-vs-delta" falls back to "error-vs")."""
    for key in (kind, "error-vs" if kind.startswith("error-vs-") else "", "cond-vs" if kind.startswith("cond-vs-") else ""):
        if key in READING:
            return READING[key] + "."
    raise KeyError(f"no how-to-read caption for figure kind {kind!r}")
