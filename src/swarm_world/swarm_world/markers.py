"""What the world shows: the ``/world/metrics`` values, the ``/world/markers`` of a sample,
and the target and barrier messages.

Message building only (no node, no rclpy): agents as arrows coloured by cluster (leaders
gold), a trail per agent, the target as a sphere and the barrier as a closed line; the markers
are written as serialized bytes (`markers_message`).
"""
from __future__ import annotations

import math
import struct

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point32, PointStamped, PolygonStamped

from swarm_core.analysis import metrics as M
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
        if len(target) == 3:                       # a 3D target
            ts.point.z = float(target[2])
    bs = PolygonStamped()
    bs.header = ts.header
    if barrier is not None:
        bs.polygon.points = [Point32(x=float(p[0]), y=float(p[1]), z=float(p[2]) if len(p) == 3 else 0.0)
                             for p in barrier]
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
    """The last ``length`` positions of each of ``n`` agents: (n, length, 3) points (z = 0),
    the oldest first, and how many each agent has."""

    def __init__(self, n, length):
        self.length = length
        self.points = np.zeros((n, length, 3))
        self.count = np.zeros(n, dtype=np.intp)

    def add(self, idx, pos):
        """A point for each of the agents ``idx`` (distinct) at rows ``pos`` (m, 2)."""
        if not self.length:
            return
        idx = np.asarray(idx, dtype=np.intp)
        full = idx[self.count[idx] == self.length]
        self.points[full, :-1] = self.points[full, 1:]
        self.count[full] -= 1
        self.points[idx, self.count[idx], :pos.shape[1]] = pos          # (m, 2), or (m, 3) in 3D
        self.count[idx] += 1

    def trail(self, i) -> np.ndarray:
        """(k, 3) agent i's trail, the oldest point first."""
        return self.points[i, :self.count[i]]


class _Cdr:
    """A serialized message (XCDR1, little endian) written field by field: each value aligned
    to its own size from the start of the body, as ``rclpy.serialization`` writes it."""

    def __init__(self):
        self.parts = [P.CDR_LE]
        self.off = 0

    def put(self, align, data: bytes):
        pad = -self.off % align
        if pad:
            self.parts.append(bytes(pad))
        self.parts.append(data)
        self.off += pad + len(data)

    def string(self, text):
        b, self.off = P.string_to_cdr(text, self.off)
        self.parts.append(b)

    def points(self, pts):
        """A sequence of geometry_msgs/Point: (k, 3) float64."""
        self.put(4, struct.pack('<I', len(pts)))
        if len(pts):
            self.put(8, np.ascontiguousarray(pts, '<f8').tobytes())

    def bytes(self) -> bytes:
        return b''.join(self.parts)


def _marker_tail() -> bytes:
    """A Marker's fields after ``points``, all empty (colors, texture_resource, texture,
    uv_coordinates, text, mesh_resource, mesh_file, mesh_use_embedded_materials), from an
    offset aligned to 4 (where ``points`` ends): always the same bytes."""
    c = _Cdr()
    c.put(4, struct.pack('<I', 0))                          # colors
    c.string('')                                            # texture_resource
    c.put(4, struct.pack('<iI', 0, 0))                      # texture.header.stamp
    for _ in range(2):                                      # texture.header.frame_id, .format
        c.string('')
    c.put(4, struct.pack('<II', 0, 0))                      # texture.data, uv_coordinates
    for _ in range(3):                                      # text, mesh_resource, mesh_file.filename
        c.string('')
    c.put(4, struct.pack('<I', 0) + b'\0')                 # mesh_file.data, mesh_use_embedded_materials
    return c.bytes()[len(P.CDR_LE):]


_TAIL = _marker_tail()
_ADD = 0          # visualization_msgs/Marker ADD
ARROW, SPHERE, LINE_STRIP = 0, 2, 4


def _marker(c: _Cdr, head: bytes, ns: str, mid: int, kind: int, pose, scale, color, points=()):
    """One visualization_msgs/Marker: ``head`` the serialized header (stamp and frame_id),
    ``pose`` (x, y, z, qx, qy, qz, qw), ``scale`` (3), ``color`` (r, g, b, a), ``points`` (k, 3).
    The tail is `_TAIL` only where ``points`` ends aligned to 4, as it does after the count or
    after float64s."""
    c.put(4, head)
    c.string(ns)
    c.put(4, struct.pack('<iii', mid, kind, _ADD))
    c.put(8, struct.pack('<10d', *pose, *scale))
    c.put(4, struct.pack('<4fiI?', *color, 0, 0, False))            # color, lifetime, frame_locked
    c.points(points)
    c.put(4, _TAIL)


def markers_message(t, pos, theta, labels, idx, leaders, trails: Trails, target=None, barrier=None) -> bytes:
    """Serialized ``/world/markers`` (visualization_msgs/MarkerArray, what ``publish()``
    accepts) of agents ``idx`` at rows ``pos``/``theta`` (cluster ``labels``; ``leaders``: flags
    of all agents), their trails (updated here), the target and the barrier.  Written as bytes:
    two Marker objects per agent and a Point object per trail point cost the world's tick tens
    of ms at a hundred agents (it also publishes the clock)."""
    idx = np.asarray(idx, dtype=np.intp)
    trails.add(idx, pos)
    sec, nanosec = P.time_to_stamp(t)
    stamp_b = struct.pack('<iI', sec, nanosec)
    frame = _Cdr()
    frame.string('world')
    head = stamp_b + frame.bytes()[len(P.CDR_LE):]
    c = _Cdr()
    c.put(4, struct.pack('<I', 2 * len(idx) + (target is not None) + (barrier is not None)))
    theta = np.asarray(theta, float)
    if theta.ndim == 1:                         # headings θ: the planar quaternion (0, 0, sin θ/2, cos θ/2)
        half = theta / 2
        quats = [(0.0, 0.0, math.sin(h), math.cos(h)) for h in half.tolist()]
    else:                                       # 3D: the quaternions of the frames (m, 4)
        quats = theta.tolist()
    for row, i in enumerate(idx.tolist()):
        rgb = PALETTE[labels[row] % len(PALETTE)]
        z = float(pos[row, 2]) if pos.shape[1] == 3 else 0.0
        _marker(c, head, 'agents', i, ARROW, (pos[row, 0], pos[row, 1], z, *quats[row]), (0.8, 0.25, 0.25),
                (*(LEADER_COLOUR if leaders[i] else rgb), 1.0))
        _marker(c, head, 'trails', i, LINE_STRIP, (0.0,) * 6 + (1.0,), (0.05, 0.0, 0.0), (*rgb, 0.6), trails.trail(i))
    if target is not None:
        tz = float(target[2]) if len(target) == 3 else 0.0
        _marker(c, head, 'target', 0, SPHERE, (float(target[0]), float(target[1]), tz, 0.0, 0.0, 0.0, 1.0),
                (1.0, 1.0, 1.0), (0.0, 1.0, 0.0, 1.0))
    if barrier is not None:
        ring = np.array([(p[0], p[1], p[2] if len(p) == 3 else 0.0) for p in list(barrier) + [barrier[0]]], float)
        _marker(c, head, 'barrier', 0, LINE_STRIP, (0.0,) * 6 + (1.0,), (0.1, 0.0, 0.0), (1.0, 0.0, 0.0, 1.0), ring)
    return c.bytes()
