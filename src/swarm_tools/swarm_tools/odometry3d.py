"""A 3D agent's state on ``/swarm/states`` (``nav_msgs/Odometry``), read without a ROS decoder.

A 3D state carries the position (x, y, z), the quaternion of its frame [x y z]
(`swarm_core.model.natural.quaternion_from_frame`) and twist.angular = (0, −v, u).  The bag
report and the Python API read 3D runs with these helpers (no ROS import here)."""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from swarm_core.model.natural import frame_from_quaternion_3d
from swarm_ros.msg_checks import reason
from swarm_ros.protocol import odometry_head

#: float64 indexes in the pose/twist block (`swarm_ros.protocol`'s layout): the sender tag, angular.y
_I_TAG, _I_WY = 7 + 35, 47


def cdr_to_odometry_3d(raw: bytes):
    """(child_frame_id, sec, nanosec, (x, y, z), (qx, qy, qz, qw), angular.y, angular.z, sender
    tag) of a serialized ``nav_msgs/Odometry`` (either byte order)."""
    end, _, name, sec, nsec, o = odometry_head(raw)
    x, y, z, qx, qy, qz, qw = struct.unpack_from(end + '7d', raw, o)
    tag, = struct.unpack_from(end + 'd', raw, o + 8 * _I_TAG)
    wy, wz = struct.unpack_from(end + '2d', raw, o + 8 * _I_WY)
    return name, sec, nsec, (x, y, z), (qx, qy, qz, qw), wy, wz, tag


def check_values_3d(name, t, pos, q, w, row, newest):
    """Why a 3D state must be rejected (a `swarm_ros.msg_checks.Reason`), 'repeat' for an exact
    repeat of the newest one of that agent, or None: an unknown agent, a non-finite value, an
    orientation that is not a unit quaternion, an older stamp or a second state for one stamp.
    ``w``: (angular.y, angular.z); ``newest``: {name: (t, *pos, *q)}."""
    if name not in row:
        return reason('unknown-agent', f'state from unknown agent {name[:40]!r}')
    vals = (*pos, *q)
    if not all(math.isfinite(v) for v in (*vals, *w, t)):
        return reason('non-finite', f'state of {name!r} with a non-finite pose/twist/stamp {vals + tuple(w) + (t,)}')
    if abs(sum(c * c for c in q) - 1.0) > 1e-6:
        return reason('not-unit', f'state of {name!r}: orientation is not a unit quaternion')
    if name in newest:
        t0 = newest[name][0]
        if t < t0:
            return reason('past-stamp', f'state of {name!r} stamped t={t:.3f}, older than its newest t={t0:.3f} '
                          '(a stamp from the past)')
        if t == t0:
            if tuple(newest[name][1:]) == vals:
                return 'repeat'
            return reason('duplicate', f'second, different state of {name!r} for t={t:.3f}: duplicate agent '
                          'name (two publishers?)')
    return None


@dataclass
class States3D:
    """The newest state of each agent of a 3D run (rows in the run's order), named as in a 3D
    `swarm_core.engine.trajectory.Trajectory`."""
    names: list
    t: np.ndarray           # (N,) sim time of each row's state
    r: np.ndarray           # (N, 3) positions
    x: np.ndarray           # (N, 3) headings: the frames' x
    y: np.ndarray           # (N, 3)
    z: np.ndarray           # (N, 3)
    u: np.ndarray           # (N,) the curvatures held over the step that ended at t
    v: np.ndarray


def states_3d(order, got: dict) -> States3D:
    """`States3D` of ``got`` ({name: (t, position, quaternion, u, v)}) in the order ``order``."""
    rows = [got[nm] for nm in order]
    q = np.array([row[2] for row in rows], dtype=float).reshape(-1, 4)
    x, y, z = frame_from_quaternion_3d(*q.T)
    return States3D(list(order), np.array([row[0] for row in rows], dtype=float),
                    np.array([row[1] for row in rows], dtype=float).reshape(-1, 3), x, y, z,
                    np.array([row[3] for row in rows], dtype=float), np.array([row[4] for row in rows], dtype=float))
