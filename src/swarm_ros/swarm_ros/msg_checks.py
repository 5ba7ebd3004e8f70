"""Validation of incoming agent states (shared by the world and realtime agents)."""
from __future__ import annotations

import math

from . import protocol as P


def check_state(msg, row, newest):
    """Why a /swarm/states message must be rejected (one line), 'repeat' for an exact repeat of
    the newest accepted state of that agent, or None to accept it.

    Rejected: an unknown agent name; a non-finite pose or twist; a pose that is not a planar
    unit quaternion; a stamp older than the newest one of that agent (a stamp from the past);
    a different state with the same stamp as the newest one of that agent (two publishers
    using one name: a duplicate agent name)."""
    p = msg.pose.pose
    o = p.orientation
    return check_values(msg.child_frame_id, P.stamp_to_time(msg.header.stamp),
                        (p.position.x, p.position.y, o.x, o.y, o.z, o.w), msg.twist.twist.angular.z,
                        row, newest)


def check_values(name, t, pose, wz, row, newest):
    """`check_state` on decoded values: pose = (x, y, qx, qy, qz, qw), wz = twist.angular.z."""
    if name not in row:
        return f'state from unknown agent {name!r}'
    x, y, qx, qy, qz, qw = pose
    vals = (x, y, qz, qw)
    isfinite = math.isfinite
    if not (isfinite(x) and isfinite(y) and isfinite(qz) and isfinite(qw) and isfinite(wz)):
        return f'state of {name!r} with a non-finite pose/twist {vals + (wz,)}'
    if abs(qz ** 2 + qw ** 2 - 1.0) > 1e-6 or qx or qy:
        return f'state of {name!r}: orientation is not a planar unit quaternion'
    if name in newest:
        t0 = newest[name][0]
        if t < t0:
            return f'state of {name!r} stamped t={t:.3f}, older than its newest t={t0:.3f} (a stamp from the past)'
        if t == t0:
            if tuple(newest[name][1:5]) == vals:
                return 'repeat'
            return f'second, different state of {name!r} for t={t:.3f}: duplicate agent name (two publishers?)'
    return None
