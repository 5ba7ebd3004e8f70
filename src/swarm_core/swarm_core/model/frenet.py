"""Frenet-Serret agent model: headings, quaternions and frames (no ROS).

The model is that of Morgan & Schwartz, "Dynamic coordinated control laws in multiple agent
models".  docs/model.md states it and lists the fixes applied to the paper's text.  Equation
numbers in these comments are the paper's.

Headings travel between agents as a planar quaternion (z = sin(θ/2), w = cos(θ/2)), the
orientation of a ``nav_msgs/Odometry`` pose.  Every frame vector in this package is computed
from that quaternion (`frame_from_quaternion`), in the batch engine and in the ROS agent node
alike, so both see bit-identical frames and their trajectories agree to rounding.
"""
from __future__ import annotations

import numpy as np


def quaternion_from_heading(theta):
    """Planar unit quaternion (z, w) of heading θ: rotation by θ about the z axis."""
    half = 0.5 * np.asarray(theta, dtype=float)
    return np.sin(half), np.cos(half)


def frame_from_quaternion(qz, qw):
    """Frenet frame of eq. 3 from a planar quaternion: returns (cos θ, sin θ).

    x_k = (cos θ, sin θ), y_k = (−sin θ, cos θ).  cos θ = w² − z², sin θ = 2wz.
    """
    qz = np.asarray(qz, dtype=float)
    qw = np.asarray(qw, dtype=float)
    return qw * qw - qz * qz, 2.0 * qw * qz


def heading_frame(theta):
    """(cos θ, sin θ) of headings θ, computed through the quaternion as agents see it."""
    return frame_from_quaternion(*quaternion_from_heading(theta))


def yaw_from_quaternion(qz, qw):
    """Heading θ in (−π, π] of a planar quaternion (for display and metrics)."""
    return 2.0 * np.arctan2(qz, qw)
