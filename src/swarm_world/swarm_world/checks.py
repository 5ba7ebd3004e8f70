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
    name = msg.child_frame_id
    if name not in row:
        return f'state from unknown agent {name!r}'
    p = msg.pose.pose
    vals = (p.position.x, p.position.y, p.orientation.z, p.orientation.w)
    if not all(math.isfinite(v) for v in vals + (msg.twist.twist.angular.z,)):
        return f'state of {name!r} with a non-finite pose/twist {vals + (msg.twist.twist.angular.z,)}'
    if abs(p.orientation.z ** 2 + p.orientation.w ** 2 - 1.0) > 1e-6 or p.orientation.x or p.orientation.y:
        return f'state of {name!r}: orientation is not a planar unit quaternion'
    t = P.stamp_to_time(msg.header.stamp)
    if name in newest:
        t0 = newest[name][0]
        if t < t0:
            return f'state of {name!r} stamped t={t:.3f}, older than its newest t={t0:.3f} (a stamp from the past)'
        if t == t0:
            if tuple(newest[name][1:5]) == vals:
                return 'repeat'
            return f'second, different state of {name!r} for t={t:.3f}: duplicate agent name (two publishers?)'
    return None
