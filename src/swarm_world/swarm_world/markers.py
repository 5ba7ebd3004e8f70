"""What the world shows: the ``/world/metrics`` values, the ``/world/markers`` of a sample,
and the target and barrier messages.

Message building only (no node, no rclpy): agents as arrows coloured by cluster (leaders
gold), a trail per agent, the target as a sphere and the barrier as a closed line.
"""
from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Point32, PointStamped, PolygonStamped
from visualization_msgs.msg import Marker, MarkerArray

from swarm_core import metrics as M

from swarm_ros import protocol as P

PALETTE = [(0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
           (0.58, 0.4, 0.74), (0.55, 0.34, 0.29)]
LEADER_COLOUR = (1.0, 0.84, 0.0)
#: markers are two messages per agent (built in Python); with more agents than this they go out
#: only every `markers_every` views, so that a view costs about as much at 1,000 agents as at 100
MARKER_AGENTS = 100


def markers_every(n: int) -> int:
    """Publish the markers of one view in this many (1 up to MARKER_AGENTS agents)."""
    return max(1, -(-int(n) // MARKER_AGENTS))


def stamp(t: float) -> Time:
    s = Time()
    s.sec, s.nanosec = P.time_to_stamp(t)
    return s


def geometry_messages(t, target, barrier):
    """(``/world/target`` PointStamped or None without a target, ``/world/barrier``
    PolygonStamped, empty without a barrier) at time t."""
    ts = PointStamped()
    ts.header.frame_id = 'world'
    ts.header.stamp = stamp(t)
    if target is not None:
        ts.point.x, ts.point.y = float(target[0]), float(target[1])
    bs = PolygonStamped()
    bs.header = ts.header
    if barrier is not None:
        bs.polygon.points = [Point32(x=float(x), y=float(y)) for x, y in barrier]
    return (ts if target is not None else None), bs


def metrics_message(t, values: dict) -> DiagnosticArray:
    """``/world/metrics``: one DiagnosticStatus 'swarm' with the values as strings."""
    st = DiagnosticStatus(name='swarm', hardware_id='world', level=DiagnosticStatus.OK,
                          message=f'{values.get("clusters", "?")} cluster(s)')
    st.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
    arr = DiagnosticArray(status=[st])
    arr.header.stamp = stamp(t)
    return arr


def view_values(t, pos, theta, clusters, min_distance, lam, leader_names, target=None, **extra) -> dict:
    """The metric values of one sample (positions and headings of the agents in the table)."""
    vals = dict(t=t, clusters=clusters, polarisation=M.polarisation(theta), min_distance=min_distance,
                **{'lambda': lam}, leaders=','.join(leader_names), agents=len(pos), **extra)
    if target is not None:
        vals['centroid_target_distance'] = float(np.hypot(*(pos.mean(0) - target)))
    return vals


class Trails:
    """The last ``length`` positions of each agent."""

    def __init__(self, n, length):
        self.length = length
        self.points = [[] for _ in range(n)]

    def add(self, i, x, y):
        tr = self.points[i]
        tr.append((float(x), float(y)))
        if len(tr) > self.length:
            del tr[0]
        return tr


def markers_message(t, pos, theta, labels, idx, leaders, trails: Trails, target=None, barrier=None) -> MarkerArray:
    """Markers of agents ``idx`` at rows ``pos``/``theta`` (cluster ``labels``; ``leaders``:
    flags of all agents), their trails (updated here), the target and the barrier."""
    ma = MarkerArray()
    st = stamp(t)
    for row, i in enumerate(idx):
        tr = trails.add(i, pos[row, 0], pos[row, 1])
        m = Marker(ns='agents', id=int(i), type=Marker.ARROW, action=Marker.ADD)
        m.header.frame_id, m.header.stamp = 'world', st
        m.pose.position.x, m.pose.position.y = float(pos[row, 0]), float(pos[row, 1])
        m.pose.orientation.z, m.pose.orientation.w = math.sin(theta[row] / 2), math.cos(theta[row] / 2)
        m.scale.x, m.scale.y, m.scale.z = 0.8, 0.25, 0.25
        r, g, b = PALETTE[labels[row] % len(PALETTE)]
        m.color.r, m.color.g, m.color.b = LEADER_COLOUR if leaders[i] else (r, g, b)
        m.color.a = 1.0
        ma.markers.append(m)
        tm = Marker(ns='trails', id=int(i), type=Marker.LINE_STRIP, action=Marker.ADD)
        tm.header = m.header
        tm.scale.x = 0.05
        tm.color.r, tm.color.g, tm.color.b, tm.color.a = r, g, b, 0.6
        tm.points = [Point(x=a, y=b_) for a, b_ in tr]
        ma.markers.append(tm)
    if target is not None:
        m = Marker(ns='target', id=0, type=Marker.SPHERE, action=Marker.ADD)
        m.header.frame_id, m.header.stamp = 'world', st
        m.pose.position.x, m.pose.position.y = float(target[0]), float(target[1])
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = m.scale.z = 1.0
        m.color.g, m.color.a = 1.0, 1.0
        ma.markers.append(m)
    if barrier is not None:
        m = Marker(ns='barrier', id=0, type=Marker.LINE_STRIP, action=Marker.ADD)
        m.header.frame_id, m.header.stamp = 'world', st
        m.scale.x = 0.1
        m.color.r, m.color.a = 1.0, 1.0
        m.points = [Point(x=float(x), y=float(y)) for x, y in list(barrier) + [barrier[0]]]
        ma.markers.append(m)
    return ma
