"""The ROS 2 graph's shared constants and codecs: topic names, QoS profiles and depths, sim-time
stamps, and the raw CDR of the messages the per-step path sends and reads without message
objects (Float64MultiArray, nav_msgs/Odometry with its sender tag, geometry_msgs/Twist(Stamped),
rosgraph_msgs/Clock).

What each topic carries, who publishes it, its QoS, the JSON topics and the lockstep cycle are
described once, in docs/ros-graph.md; the packed lockstep layouts are declared in `swarm_ros.layouts`.
"""
from __future__ import annotations

import json
import math
import struct

import numpy as np

STATES = '/swarm/states'
LAMBDA = '/swarm/lambda'
LAMBDA_SETPOINT = '/commander/lambda_setpoint'   # [λ, ramp]: swarm lambda → the commander
LEADERS = '/swarm/leaders'
CLOCK = '/clock'
TARGET = '/world/target'
BARRIER = '/world/barrier'
MARKERS = '/world/markers'
METRICS = '/world/metrics'
#: lockstep: the commander node's live commands to the world, which decides each step (`run_control.forward_text`)
LOCK_COMMAND = '/lockstep/command'
LOCK_STEP = '/lockstep/step'
LOCK_AGENT_STATES = '/lockstep/agent_states'
#: lockstep: the MuJoCo robot world's poses of its robots after each physics step (`layouts.RobotStates`)
LOCK_ROBOT_STATES = '/lockstep/robot_states'
#: realtime: one message per agent process and tick with its agents' new states (`layouts.ProcessStates`)
AGENT_STATES = '/swarm/agent_states'
#: realtime: the commander's decision of each tick (λ, leaders, s_k: `layouts.RealtimeDecision`), what
#: the agents and the world read; /swarm/lambda and /<agent>/steering are for the record and for
#: commands, which only the commander reads (docs/ros-graph.md, docs/commands.md)
DECISION = '/swarm/decision'
#: realtime: the world's sim time with the run id and its sender tag (`layouts.RunClock`): the
#: one clock a node of a run follows (`run_clock`); /clock is for the recorder and the tools
RUN_CLOCK = '/swarm/clock'
#: publisher depth of /swarm/agent_states (transient-local): a late reader gets each process's
#: newest states (the first ones included while the run starts)
AGENT_STATES_DEPTH = 10
EVENTS = '/swarm/events'
FAULT_REQUEST = '/swarm/fault_request'
RUN = '/swarm/run'
#: publisher depth of /swarm/states (transient-local): history a late or slow reader can get
STATES_DEPTH = 100


def steering_topic(agent: str) -> str:
    return f'/{agent}/steering'


#: lockstep with a recorder (``wait_for_recorder``): wall seconds a node waits for the
#: recorder's readers to match its writers before it takes part anyway (with a warning)
RECORDER_MATCH_WAIT = 30.0

#: history of the volatile per-step writers (/clock, /swarm/lambda, steering): a reader that
#: falls behind, or a datagram repaired late, still finds the sample
STEP_DEPTH = 100

#: the lockstep critical path of one step, in order: agents → world → agents
CRITICAL_PATH = (LOCK_AGENT_STATES, LOCK_STEP)


def lockstep_messages(n: int, writers: int, *, clock_every: int = 1, publish_every: int = 10,
                      view_every: int = 20) -> dict:
    """Messages per lockstep step on each topic (docs/ros-graph.md, The lockstep cycle): ``n``
    agents in ``writers`` agent processes (each a writer of /lockstep/agent_states), the
    world's ``clock_every`` and ``view_every``, the commander's ``publish_every``.  The
    leaders, the steering topics and /swarm/events carry messages only when something changes;
    a topic not listed carries none per step."""
    per = {LOCK_AGENT_STATES: writers, LOCK_STEP: 1,
           STATES: n, CLOCK: 1 / clock_every, LAMBDA: 1 / publish_every}
    if view_every:
        per.update({METRICS: 1 / view_every, MARKERS: 1 / view_every})
    return per


def qos_latched(depth: int = 1):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def qos_reliable(depth: int = 10):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def qos_kept_latched():
    """A lockstep reader that keeps every message until it is taken (reliable, transient-local,
    KEEP_ALL): a flood of refused messages (another run's, a peer's) cannot push an unread one
    of this run out of its history, so it only comes later.  History is not part of QoS
    matching: the writers keep their own depth."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def qos_cmd_vel(lockstep: bool):
    """A robot agent's ``cmd_vel`` writer and the robot world's reader (reliable, depth 10).
    Lockstep: transient-local.  Each command is sent once, and the robot world holds its step
    until it has every one, so a reader matched after the agent sent it must still get it (a
    volatile writer drops it, and the run stalls at its first step); a controller's volatile
    reader matches it all the same.  Realtime: volatile (a replayed command would be stale).
    The MuJoCo robot world reads lockstep commands with `qos_kept_latched`."""
    return qos_latched(10) if lockstep else qos_reliable(10)


def step_of(t: float, dt: float) -> int:
    return int(round(t / dt))


def time_to_stamp(t: float):
    """(sec, nanosec) of a sim time t ≥ 0."""
    sec = math.floor(t)
    nsec = int(round((t - sec) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return int(sec), nsec


def stamp_to_time(stamp) -> float:
    return stamp_seconds(stamp.sec, stamp.nanosec)


def stamp_seconds(sec: int, nanosec: int) -> float:
    """Sim time of a stamp (sec, nanosec), as a raw decoder gives it."""
    return sec + nanosec * 1e-9


def event_json(kind: str, t, **fields) -> str:
    """The JSON text of a ``/swarm/events`` message."""
    return json.dumps(dict(t=None if t is None else float(t), kind=str(kind), **fields))


# ------------------------------------------------------------------ raw CDR of Float64MultiArray

#: the encapsulation header of a serialized message: CDR, little endian
CDR_LE = b'\x00\x01\x00\x00'


def float64_array_to_cdr(data: np.ndarray) -> bytes:
    """Serialized std_msgs/Float64MultiArray (what publish() accepts) with an empty layout."""
    data = np.ascontiguousarray(data, dtype='<f8')
    return float64_array_header(data.size) + data.tobytes()


def float64_array_header(size: int) -> bytes:
    """The bytes of a serialized Float64MultiArray with an empty layout before its ``size``
    doubles (little-endian)."""
    return CDR_LE + struct.pack('<IIII', 0, 0, size, 0)


#: the bytes of a little-endian serialized Float64MultiArray with an empty layout up to its size
_EMPTY_LAYOUT_LE = CDR_LE + struct.pack('<II', 0, 0)


def cdr_to_float64_array(raw: bytes) -> np.ndarray:
    """``data`` of a serialized std_msgs/Float64MultiArray (any layout)."""
    if raw[:12] == _EMPTY_LAYOUT_LE:             # what this project sends: no layout to walk
        return np.frombuffer(raw, dtype='<f8', count=int.from_bytes(raw[12:16], 'little'), offset=20)
    little = raw[1] == 1
    end = '<' if little else '>'
    o = 4
    ndim, = struct.unpack_from(end + 'I', raw, o)
    o += 4
    for _ in range(ndim):
        ln, = struct.unpack_from(end + 'I', raw, o)
        o += 4 + ln
        o = (o - 4 + 3) // 4 * 4 + 4
        o += 8
    o += 4                                        # data_offset
    size, = struct.unpack_from(end + 'I', raw, o)
    o += 4
    o = (o - 4 + 7) // 8 * 8 + 4
    return np.frombuffer(raw, dtype=end + 'f8', count=size, offset=o)


# ------------------------------------------------------------------ raw CDR of nav_msgs/Odometry
#
# Layout (XCDR1, offsets after the 4-byte encapsulation header): header.stamp (int32 sec,
# uint32 nanosec), header.frame_id (uint32 length incl. NUL, bytes), child_frame_id (aligned
# to 4, same), then aligned to 8 the 85 float64 of pose.pose (position 3, orientation 4),
# pose.covariance (36), twist.twist (linear 3, angular 3), twist.covariance (36).

_ODOM_DOUBLES = 7 + 36 + 6 + 36
_I_X, _I_Y, _I_Z, _I_QX, _I_QY, _I_QZ, _I_QW = 0, 1, 2, 3, 4, 5, 6
_I_VX = 43
_I_WY, _I_WZ = 47, 48
#: pose.covariance[35] (the yaw variance, unused by a planar agent that reports none): the
#: agent's SENDER TAG, a random integer 1..2^31 each agent process draws once (0 = untagged).
#: The world and realtime agents bind each agent name to the first tag heard for it and reject
#: states of that name with another tag (swarm_ros.msg_checks.Senders): rclpy Jazzy gives no
#: publisher gid in its message info, and its EventsExecutor cannot call message-info callbacks.
SENDER_TAG_INDEX = 35
_I_TAG = 7 + SENDER_TAG_INDEX


def string_to_cdr(s: str, off: int) -> tuple[bytes, int]:
    """Padding + length + bytes of a CDR string written at body offset `off`; new offset."""
    b = s.encode() + b'\0'
    pad = (-off) % 4
    out = b'\0' * pad + struct.pack('<I', len(b)) + b
    return out, off + len(out)


class OdometryWriter:
    """Serialized ``nav_msgs/Odometry`` of one agent or robot (what ``publish()`` accepts as
    bytes): a fixed frame_id (default ``world``) and child_frame_id, twist.linear.x = ``vx``
    (default 1: unit speed), zero covariances but the sender ``tag`` in
    pose.covariance[`SENDER_TAG_INDEX`]."""

    def __init__(self, child_frame_id: str, frame_id: str = 'world', tag: float = 0.0):
        off = 8                                          # after the stamp
        frame, off = string_to_cdr(frame_id, off)
        child, off = string_to_cdr(child_frame_id, off)
        pad = (-off) % 8
        self._names = frame + child + b'\0' * pad
        self._body = np.zeros(_ODOM_DOUBLES, dtype='<f8')
        self._body[_I_TAG] = tag

    def __call__(self, sec: int, nanosec: int, x: float, y: float, qz: float, qw: float, wz: float,
                 vx: float = 1.0) -> bytes:
        b = self._body
        b[_I_X], b[_I_Y], b[_I_QZ], b[_I_QW], b[_I_WZ], b[_I_VX] = x, y, qz, qw, wz, vx
        return CDR_LE + struct.pack('<iI', sec, nanosec) + self._names + b.tobytes()

    def full(self, sec: int, nanosec: int, r, q, u: float, v: float) -> bytes:
        """A 3D state: position ``r`` (x, y, z), orientation ``q`` (qx, qy, qz, qw: the
        quaternion of the frame [x y z]), twist.linear.x = 1 and twist.angular = (0, −v, u)
        (REP 103: u turns x towards y about z, v turns it towards z about −y)."""
        b = self._body
        b[_I_X:_I_Z + 1] = r
        b[_I_QX:_I_QW + 1] = q
        b[_I_VX], b[_I_WY], b[_I_WZ] = 1.0, -v, u
        return CDR_LE + struct.pack('<iI', sec, nanosec) + self._names + b.tobytes()


def cdr_string(raw: bytes, off: int, end: str) -> tuple[str, int]:
    """The CDR string at offset ``off`` (aligned to 4 after the encapsulation header) of
    ``raw`` in byte order ``end`` ('<' or '>'), and the offset after it."""
    off = (off - 4 + 3) // 4 * 4 + 4
    n, = struct.unpack_from(end + 'I', raw, off)
    return raw[off + 4:off + 3 + n].decode('utf-8', 'replace'), off + 4 + n


def cdr_byte_order(raw: bytes) -> str:
    """'<' or '>': the byte order of a serialized message (its encapsulation header)."""
    return '<' if raw[1] & 1 else '>'


def odometry_head(raw: bytes):
    """The walk to the pose of a serialized ``nav_msgs/Odometry`` (either byte order): (struct
    byte-order mark, frame_id, child_frame_id, sec, nanosec, byte offset of the pose (its first
    float64; the twist and covariance follow at fixed float64 indexes))."""
    end = '<' if raw[1] & 1 else '>'
    sec, nsec, n = struct.unpack_from(end + 'iII', raw, 4)
    frame = raw[16:15 + n].decode('utf-8', 'replace')
    o = 16 + n                                       # after header.frame_id
    o = (o - 4 + 3) // 4 * 4 + 4
    n, = struct.unpack_from(end + 'I', raw, o)
    name = raw[o + 4:o + 3 + n].decode('utf-8', 'replace')
    o += 4 + n
    return end, frame, name, sec, nsec, (o - 4 + 7) // 8 * 8 + 4


def cdr_to_odometry_full(raw: bytes):
    """The one decoder of a serialized planar ``nav_msgs/Odometry`` (either byte order):
    (frame_id, child_frame_id, sec, nanosec, (x, y, qx, qy, qz, qw), linear.x, angular.z,
    sender tag); a 3D state: `swarm_tools.odometry3d.cdr_to_odometry_3d`."""
    end, frame, name, sec, nsec, o = odometry_head(raw)
    x, y, _, qx, qy, qz, qw = struct.unpack_from(end + '7d', raw, o)
    tag, vx = struct.unpack_from(end + '2d', raw, o + 8 * _I_TAG)       # adjacent fields
    wz, = struct.unpack_from(end + 'd', raw, o + 8 * _I_WZ)
    return frame, name, sec, nsec, (x, y, qx, qy, qz, qw), vx, wz, tag


def cdr_to_odometry_tagged(raw: bytes):
    """(child_frame_id, sec, nanosec, (x, y, qx, qy, qz, qw), angular.z, sender tag
    (pose.covariance[`SENDER_TAG_INDEX`])) of a serialized ``nav_msgs/Odometry`` (either
    byte order, any frame_id)."""
    _, name, sec, nsec, pose, _, wz, tag = cdr_to_odometry_full(raw)
    return name, sec, nsec, pose, wz, tag


# ------------------------------------------------------------------ raw CDR of geometry_msgs/Twist(Stamped)
#
# TwistStamped: header.stamp (int32 sec, uint32 nanosec), header.frame_id (uint32 length incl.
# NUL, bytes), then aligned to 8 the 6 float64 of twist (linear x, y, z, angular x, y, z).
# Twist: the 6 float64 alone.  A robot agent sends linear.x and angular.z; the others are 0.


class TwistWriter:
    """Serialized ``geometry_msgs/TwistStamped`` with a fixed frame_id (``stamped``; else
    ``geometry_msgs/Twist``) of one robot's command (linear.x = ``v``, angular.z = ``omega``):
    what ``publish()`` accepts as bytes, without a message object per command."""

    def __init__(self, frame_id: str = '', stamped: bool = True):
        self.stamped = stamped
        frame, off = string_to_cdr(frame_id, 8)
        self._frame = frame + b'\0' * ((-off) % 8)

    def __call__(self, sec: int, nanosec: int, v: float, omega: float) -> bytes:
        twist = struct.pack('<6d', v, 0.0, 0.0, 0.0, 0.0, omega)
        if not self.stamped:
            return CDR_LE + twist
        return CDR_LE + struct.pack('<iI', sec, nanosec) + self._frame + twist


def cdr_to_twist(raw: bytes, stamped: bool = True):
    """The one decoder of a serialized ``geometry_msgs/TwistStamped`` (``stamped``; else
    ``Twist``, stamp 0) in either byte order: (sec, nanosec, linear.x, angular.z)."""
    end = cdr_byte_order(raw)
    o, sec, nsec = 4, 0, 0
    if stamped:
        sec, nsec, n = struct.unpack_from(end + 'iII', raw, 4)
        o = 16 + n
        o = (o - 4 + 7) // 8 * 8 + 4
    v, _, _, _, _, omega = struct.unpack_from(end + '6d', raw, o)
    return sec, nsec, v, omega


def clock_to_cdr(t: float) -> bytes:
    """Serialized ``rosgraph_msgs/Clock`` of sim time t (what ``publish()`` accepts as bytes)."""
    return CDR_LE + struct.pack('<iI', *time_to_stamp(t))
