"""Frames: the rotations (2, 2) and (3, 3) whose columns are a body's local axes e_xi, e_eta (, e_zeta)."""
from __future__ import annotations

import numpy as np


def frame_of_angle(angle_deg: float) -> np.ndarray:
    """Local frame for a body whose side edges make angle_deg with the x-axis.

    Returns R (2, 2) with columns e_xi = (sin t, -cos t) along the base and
    e_eta = (cos t, sin t) normal to the base (inward); angle 90 gives R = I.
    """
    t = np.deg2rad(angle_deg)
    sin, cos = np.sin(t), np.cos(t)
    # cos(90 deg) is 6e-17 in floating point: snap so grid-aligned bodies are exactly aligned
    sin, cos = (0.0 if abs(v) < 1e-15 else v for v in (sin, cos))
    return np.array([[sin, cos], [-cos, sin]])


def frame_3d(theta_deg: float, tilt_deg: float) -> np.ndarray:
    """Local frame of a 3D box: frame_of_angle(theta) about z, then a tilt about the body's own xi axis.

    Returns R (3, 3) = blockdiag(frame_of_angle(theta), 1) @ Rx(tilt) with columns e_xi, e_eta,
    e_zeta, Rx(t) = [[1, 0, 0], [0, cos t, -sin t], [0, sin t, cos t]]; (90, 0) gives R = I.
    """
    planar = np.eye(3)
    planar[:2, :2] = frame_of_angle(theta_deg)
    t = np.deg2rad(tilt_deg)
    sin, cos = (0.0 if abs(v) < 1e-15 else v for v in (np.sin(t), np.cos(t)))   # as frame_of_angle
    return planar @ np.array([[1.0, 0.0, 0.0], [0.0, cos, -sin], [0.0, sin, cos]])
