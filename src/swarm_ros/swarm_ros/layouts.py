"""The packed lockstep messages, each declared once: a field table from which its numpy
structured dtype, its encoder, its one decoder (with its checks) and its line in
docs/ros-graph.md all follow.

On the wire each is a ``std_msgs/Float64MultiArray`` with an empty ``layout`` whose ``data``
is the bytes of ONE record of the message's dtype: the run id (`RUN_ID_BYTES` ASCII bytes,
NUL-padded: the first four doubles), then float64 fields in declared order.  A field's count
is fixed (``3``) or names a count field declared before it (``'N'``); the decoder reads the
counts, checks that the data holds exactly that many values, then reads each field where the
record's dtype puts it (a view of the received bytes, no copy).  Kinds (what a field's float64
values mean and how they are checked):

``float``  as sent;  ``finite``  rejected if not finite (`NotFinite`);
``whole``  an integer ≥ 0 (int);  ``count``  a whole number of rows (not a message attribute);
``int``  an integer, finite (truncated; −1 = none);  ``flag``  1/0 (decoded > 0.5, bool);
``point``  [has, x, y] → (2,) array or None;  ``points``  rows of (x, y) → (M, 2) array or None
when M = 0;  ``rendezvous``  [on, has_point, x, y, γ, normalised, q0 (−1: the law's)] →
(point or None, γ, normalised, q0 or None) of `swarm_core.faults.agents.Rendezvous`, or None (off).

A node with a run id rejects a message of another run (`OtherRun`); a node without one takes any.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import struct
from typing import Any, NamedTuple

import numpy as np

from swarm_ros.protocol import (
    AGENT_STATES,
    DECISION,
    LOCK_AGENT_STATES,
    LOCK_ROBOT_STATES,
    LOCK_STEP,
    RUN_CLOCK,
    cdr_to_float64_array,
    float64_array_header,
)

#: bytes of the run id field (swarm_ros.runinfo: 1-32 letters, digits, _ or -)
RUN_ID_BYTES = 32
_RUN_DOUBLES = RUN_ID_BYTES // 8


class BadMessage(ValueError):
    """A packed lockstep message that must be rejected; ``kind`` the log key (None: the reader's)."""
    kind = None


class NotFinite(BadMessage):
    """A value of a ``finite`` or ``whole`` field is not finite."""
    kind = 'non-finite'


class OtherRun(BadMessage):
    """The message carries another run's id (a second run on the ROS_DOMAIN_ID)."""
    kind = 'other-run'


class Field(NamedTuple):
    name: str
    count: Any = 1          # 1, an int, a count field's name, or a shape tuple of those
    kind: str = 'float'

    def dims(self) -> tuple:
        return self.count if isinstance(self.count, tuple) else (self.count,)

    def shape(self, counts) -> tuple:
        """The numpy shape of the field for the count values ``counts`` (a dict); () = a scalar."""
        return () if self.count == 1 else tuple(counts[d] if isinstance(d, str) else d for d in self.dims())

    def text(self) -> str:
        dims = '' if self.count == 1 else f'({", ".join(map(str, self.dims()))})'
        return f'{self.name}{dims}' + ('' if self.kind == 'float' else f' {self.kind}')


def _rendezvous(rdv) -> list:
    if rdv is None:
        return [0.0] * 7
    point, gain, norm, coupling = rdv
    x, y = (0.0, 0.0) if point is None else point
    return [1.0, 0.0 if point is None else 1.0, float(x), float(y), float(gain), 1.0 if norm else 0.0,
            -1.0 if coupling is None else float(coupling)]


def _from_rendezvous(r):
    if r[0] < 0.5:
        return None
    point = (float(r[2]), float(r[3])) if r[1] > 0.5 else None
    return point, float(r[4]), bool(r[5] > 0.5), None if r[6] < 0 else float(r[6])


def _rendezvous3(rdv) -> list:
    if rdv is None:
        return [0.0] * 8
    point, gain, norm, coupling = rdv
    x, y, z = (0.0, 0.0, 0.0) if point is None else point
    return [1.0, 0.0 if point is None else 1.0, float(x), float(y), float(z), float(gain), 1.0 if norm else 0.0,
            -1.0 if coupling is None else float(coupling)]


def _from_rendezvous3(r):
    if r[0] < 0.5:
        return None
    point = (float(r[2]), float(r[3]), float(r[4])) if r[1] > 0.5 else None
    return point, float(r[5]), bool(r[6] > 0.5), None if r[7] < 0 else float(r[7])


#: kind → (value → what the record holds, what the record holds → value); None = as is
_CODECS = {
    'float': (None, None), 'finite': (None, None), 'count': (None, None),
    'whole': (None, lambda v: v.astype(np.int64)),
    'int': (None, lambda v: v.astype(int)),
    'flag': (None, lambda v: v > 0.5),
    'point': (lambda p: [0.0, 0.0, 0.0] if p is None else [1.0, float(p[0]), float(p[1])],
              lambda v: v[1:3].copy() if v[0] > 0.5 else None),
    'points': (lambda p: np.zeros((0, 2)) if p is None else np.asarray(p, float).reshape(-1, 2),
               lambda v: v.copy() if len(v) else None),
    'rendezvous': (_rendezvous, _from_rendezvous),
    'point3': (lambda p: [0.0] * 4 if p is None else [1.0, *map(float, np.ravel(p)[:3])],
               lambda v: v[1:4].copy() if v[0] > 0.5 else None),
    'points3': (lambda p: np.zeros((0, 3)) if p is None else np.asarray(p, float).reshape(-1, 3),
                lambda v: v.copy() if len(v) else None),
    'height': (lambda h: [0.0, 0.0] if h is None else [1.0, float(h)], lambda v: float(v[1]) if v[0] > 0.5 else None),
    'rendezvous3': (_rendezvous3, _from_rendezvous3),
}
_SCALAR = {'float': float, 'finite': float, 'whole': int, 'int': int}


class _Plan(NamedTuple):
    """A layout for given count values: its record dtype and, in doubles of ``data``, where
    each field sits and which runs of doubles must be finite, or whole numbers ≥ 0."""
    dtype: np.dtype
    slots: tuple             # (field, start, stop, shape) in declared order
    finite: tuple            # (start, stop, field names): finite, whole, int (merged runs)
    whole: tuple             # (start, stop, field names): whole numbers ≥ 0
    reads: tuple             # (start, stop, ndim, shape, decoder) of each message attribute


def _runs(slots) -> tuple:
    """The places of ``slots`` merged into runs of adjacent doubles: one check per run."""
    out = []
    for f, a, b, _ in slots:
        if out and out[-1][1] == a:
            out[-1] = (out[-1][0], b, out[-1][2] + ' or ' + f.name)
        elif b > a:
            out.append((a, b, f.name))
    return tuple(out)


@functools.lru_cache(maxsize=64)
def _run_id_field(run_id: str) -> bytes:
    rid = run_id.encode()
    if len(rid) > RUN_ID_BYTES:
        raise ValueError(f'run id {run_id!r} longer than {RUN_ID_BYTES} bytes')
    return rid.ljust(RUN_ID_BYTES, b'\0')


#: plans a layout keeps by the count values it received (each message size seen, up to this many)
_PLANS_KEPT = 64

#: records of at most this many doubles (a lone agent's answer) are packed from plain floats:
#: cheaper than numpy for a few values
_SMALL = 64


def _small_body(plan: _Plan, values: dict, size: int) -> bytes:
    """The doubles after the run id, packed with struct (a field of the wrong size: ValueError)."""
    flat = []
    for f, a, b, shape in plan.slots:
        v = values[f.name]
        if not shape:
            flat.append(v)
        elif len(shape) == 1:
            flat.extend(v)
        elif len(shape) == 2:
            for row in v:
                flat.extend(row)
        else:                                        # (4, K, 3): a 3D run's states
            flat.extend(np.ravel(v).tolist())
        if len(flat) != b - _RUN_DOUBLES:
            raise ValueError(f'{f.name}: {len(flat) - a + _RUN_DOUBLES} values, not {shape}')
    return struct.pack(f'<{size}d', *flat)


def _numpy_body(plan: _Plan, values: dict, size: int) -> bytes:
    """`_small_body` by numpy (a field of the wrong shape: ValueError)."""
    data = np.empty(size)
    for f, a, b, shape in plan.slots:
        a, b = a - _RUN_DOUBLES, b - _RUN_DOUBLES
        if len(shape) == 1:
            data[a:b] = values[f.name]
        elif shape:
            data[a:b].reshape(shape)[...] = values[f.name]
        else:
            data[a] = values[f.name]
    return data.tobytes()


class Layout:
    """One packed message: ``topic``, its message class ``cls`` (a dataclass whose fields are
    the declared fields but the counts) and its ``fields`` (`Field`), in wire order."""

    def __init__(self, topic: str, cls, fields):
        self.topic, self.cls, self.fields = topic, cls, tuple(fields)
        self.counts, at = {}, _RUN_DOUBLES           # count name → its place (in doubles)
        for f in self.fields:                        # a count sits at a fixed place, before its use
            if f.kind == 'count':
                assert at is not None, f'{topic}: count {f.name} after a counted field'
                self.counts[f.name] = at
            assert all(d in self.counts for d in f.dims() if isinstance(d, str)), f'{topic}: {f.name}'
            at = None if at is None or any(isinstance(d, str) for d in f.dims()) else at + int(np.prod(f.dims()))
        self.head = max(self.counts.values(), default=_RUN_DOUBLES - 1) + 1    # doubles up to the last count
        # a count's value when packing: the rows of the first field counted by it
        self.count_of = {c: next(f.name for f in self.fields if f.dims()[0] == c) for c in self.counts}
        assert [fl.name for fl in dataclasses.fields(cls)] == [f.name for f in self.fields if f.kind != 'count'], topic
        self.encoders = tuple((f.name, _CODECS[f.kind][0]) for f in self.fields if f.kind != 'count')
        self._count_at = tuple(self.counts.values())
        self._plans = {}                             # count values as received (floats) → plan

    def text(self) -> str:
        """The layout as docs/ros-graph.md shows it: each field with its count and its kind."""
        lines = [f'{self.topic} [run_id({_RUN_DOUBLES})']
        for f in self.fields:
            if len(lines[-1]) + len(f.text()) > 96:
                lines[-1] += ','
                lines.append(' ' * (len(self.topic) + 2) + f.text())
            else:
                lines[-1] += ', ' + f.text()
        return '\n'.join(lines) + ']'

    def plan(self, counts: tuple) -> _Plan:
        """The record of this layout for the count values ``counts`` (declared order)."""
        return _layout_plan(self, counts)

    def encode(self, msg, run_id: str = '') -> bytes:
        """The serialized Float64MultiArray of ``msg`` (an instance of ``cls``) with ``run_id``."""
        values = {name: getattr(msg, name) if enc is None else enc(getattr(msg, name)) for name, enc in self.encoders}
        counts = tuple(len(values[self.count_of[c]]) for c in self.counts)
        values.update(zip(self.counts, counts))
        plan = self.plan(counts)
        size = plan.dtype.itemsize // 8
        body = (_small_body if size <= _SMALL else _numpy_body)(plan, values, size - _RUN_DOUBLES)
        return float64_array_header(size) + _run_id_field(run_id) + body

    def packer(self, counts: tuple, run_id: str = ''):
        """``pack(*values)`` → what `encode` makes of a message with these count values (its
        counts must lead the record) and ``run_id``, from the doubles of every other field in
        wire order (each flattened row-major), without a message object: a lone agent's answer
        of each step."""
        assert all(f.kind == 'count' for f in self.fields[:len(self.counts)]), f'{self.topic}: counts do not lead'
        size = self.plan(tuple(counts)).dtype.itemsize // 8
        head = float64_array_header(size) + _run_id_field(run_id) + struct.pack(f'<{len(counts)}d', *counts)
        body = struct.Struct(f'<{size - _RUN_DOUBLES - len(counts)}d')
        return lambda *values: head + body.pack(*values)

    def decode(self, raw: bytes, run_id: str = ''):
        """The one decoder: the message (``cls``) in a serialized Float64MultiArray, or a
        `BadMessage` (`OtherRun` if ``run_id`` is set and the message's differs, `NotFinite`,
        else a size that does not match its counts or a value not a whole number ≥ 0)."""
        try:
            data = cdr_to_float64_array(raw)
        except Exception as err:                     # struct.error, ...: too short
            raise BadMessage(f'not a serialized Float64MultiArray ({err})') from None
        if data.dtype.byteorder == '>':
            data = data.astype('<f8')
        size = data.size
        if size < self.head:
            raise BadMessage(f'{size} values, fewer than the {self.head} before its counts')
        if run_id and data[:_RUN_DOUBLES].tobytes() != _run_id_field(run_id):
            got = data[:_RUN_DOUBLES].tobytes().rstrip(b'\0').decode('ascii', 'replace')
            raise OtherRun(f'message of run {got or "(none)"!r}, not this run {run_id!r}: another swarm run '
                           'on this ROS_DOMAIN_ID?')
        counts = tuple(map(data.item, self._count_at))
        try:
            plan = self._plans[counts]              # counts seen before: whole numbers ≥ 0
        except KeyError:
            if not all(c.is_integer() and 0 <= c <= size for c in counts):
                raise BadMessage(f'counts {", ".join(self.counts)} = {list(counts)} are not whole numbers ≥ 0') \
                    from None
            plan = self.plan(tuple(int(c) for c in counts))
            if len(self._plans) < _PLANS_KEPT:
                self._plans[counts] = plan
        if size * 8 != plan.dtype.itemsize:
            raise BadMessage(f'{size} values do not hold {dict(zip(self.counts, counts))} '
                             f'(want {plan.dtype.itemsize // 8})')
        for a, b, names in plan.finite:             # a few values: plain floats are cheaper
            if not (all(map(math.isfinite, data[a:b].tolist())) if b - a <= _SMALL
                    else np.isfinite(data[a:b]).all()):
                raise NotFinite(f'a value of {names} is not finite')
        for a, b, names in plan.whole:
            if b - a <= _SMALL:
                if all(v.is_integer() and v >= 0 for v in data[a:b].tolist()):
                    continue
            elif not (data[a:b] != np.abs(np.floor(data[a:b]))).any():
                continue
            raise BadMessage(f'a value of {names} is not a whole number ≥ 0')
        out = []
        for a, b, ndim, shape, dec in plan.reads:
            if ndim == 0:
                out.append(dec(data.item(a)))
            else:
                v = data[a:b] if ndim == 1 else data[a:b].reshape(shape)
                out.append(v if dec is None else dec(v))
        return self.cls(*out)


@functools.lru_cache(maxsize=64)
def _layout_plan(layout: Layout, counts: tuple) -> _Plan:
    """`Layout.plan`, cached by (layout, counts) in a module-level cache rather than on the method:
    the layouts it holds are declared once per message class and live for the process anyway."""
    c = dict(zip(layout.counts, counts))
    dtype = np.dtype([('run_id', f'S{RUN_ID_BYTES}')] + [(f.name, '<f8', f.shape(c)) for f in layout.fields])
    slots = []
    for f in layout.fields:
        a = dtype.fields[f.name][1] // 8
        slots.append((f, a, a + dtype[f.name].itemsize // 8, f.shape(c)))
    reads = tuple((a, b, len(shape), shape, _CODECS[f.kind][1] if shape else _SCALAR[f.kind])
                  for f, a, b, shape in slots if f.kind != 'count')
    return _Plan(dtype, tuple(slots), _runs([s for s in slots if s[0].kind in ('finite', 'whole', 'int')]),
                 _runs([s for s in slots if s[0].kind == 'whole']), reads)


class Packed:
    """What every packed message class has: ``to_cdr`` and ``from_cdr`` (its `Layout`)."""
    LAYOUT: Layout

    def to_cdr(self, run_id: str = '') -> bytes:
        return self.LAYOUT.encode(self, run_id)

    @classmethod
    def from_cdr(cls, raw: bytes, run_id: str = ''):
        return cls.LAYOUT.decode(raw, run_id)


def declare(topic, *fields):
    """Class decorator: ``cls`` is the message of ``topic`` with these `Field` s."""
    def wrap(cls):
        cls.LAYOUT = Layout(topic, cls, fields)
        return cls
    return wrap


@declare(LOCK_AGENT_STATES, Field('K', kind='count'), Field('tag', kind='finite'),
         Field('index', 'K', 'whole'), Field('step', 'K', 'whole'), Field('pose', (4, 'K'), 'finite'),
         Field('u', 'K', 'finite'))
@dataclasses.dataclass(eq=False)
class AgentStates(Packed):
    """What one agent process (a lone agent or a container of K agents) sends per step: the
    state each of its agents published on /swarm/states (the state of t_step, carrying u)."""
    tag: float               # the process's sender tag (msg_checks.ProcessSenders)
    index: np.ndarray        # (K,) the agents' rows in the roster
    step: np.ndarray         # (K,) the step of each state
    pose: np.ndarray         # (4, K) x, y, qz, qw
    u: np.ndarray            # (K,) the u the state carries (u_{step−1})


@declare(LOCK_ROBOT_STATES, Field('n', kind='whole'), Field('tag', kind='finite'), Field('K', kind='count'),
         Field('index', 'K', 'whole'), Field('pose', (4, 'K'), 'finite'))
@dataclasses.dataclass(eq=False)
class RobotStates(Packed):
    """Lockstep: the MuJoCo robot world's poses of its robots at t_n, in model units, as each
    robot's agent reads its odometry (`swarm_robots.world_setup.OdometryPoses`).  The world takes
    these agents' states of t_n from here and only u from their own answers."""
    n: int                   # the step: the physics just reached t_n·L/v0
    tag: float               # the robot world's sender tag (the world binds the topic to its first)
    index: np.ndarray        # (K,) the robots' agents' rows in the roster
    pose: np.ndarray         # (4, K) x, y, qz, qw


@declare(AGENT_STATES, Field('K', kind='count'), Field('tag', kind='finite'),
         Field('index', 'K', 'whole'), Field('t', 'K', 'finite'), Field('pose', (4, 'K'), 'finite'),
         Field('u', 'K', 'finite'))
@dataclasses.dataclass(eq=False)
class ProcessStates(Packed):
    """Realtime: what one agent process sends per tick, the states its agents just published
    on /swarm/states, each with its own stamp (a realtime state's time is not a step count)."""
    tag: float               # the process's sender tag (bound per agent by the readers)
    index: np.ndarray        # (K,) the agents' rows in the roster
    t: np.ndarray            # (K,) the sim time of each state (its /swarm/states stamp)
    pose: np.ndarray         # (4, K) x, y, qz, qw
    u: np.ndarray            # (K,) the u the state carries


@declare(DECISION, Field('n', kind='whole'), Field('t'), Field('N', kind='count'), Field('lam'),
         Field('flags', 'N', 'flag'), Field('steering', 'N'), Field('slots', 'N', 'int'),
         Field('rendezvous', 7, 'rendezvous'))
@dataclasses.dataclass(eq=False)
class RealtimeDecision(Packed):
    """Realtime: the commander's decision of each tick (``n``: the step of its time ``t``), for
    the agents (λ, leaders, each one's s_k) and the world (λ and leaders recorded)."""
    n: int
    t: float
    lam: float
    flags: np.ndarray        # (N,) bool: leaders
    steering: np.ndarray     # (N,) s_k
    slots: np.ndarray        # (N,) int: leader slot (swarm_core.faults.agents), −1 for none
    rendezvous: Any          # the reunion of step n or None


@declare(LOCK_STEP, Field('n', kind='whole'), Field('t'), Field('N', kind='count'), Field('M', kind='count'),
         Field('lam'), Field('flags', 'N', 'flag'), Field('steering', 'N'), Field('x', 'N'), Field('y', 'N'),
         Field('qz', 'N'), Field('qw', 'N'), Field('u', 'N'), Field('alive', 'N', 'flag'),
         Field('target', 3, 'point'), Field('barrier', ('M', 2), 'points'), Field('rendezvous', 7, 'rendezvous'))
@dataclasses.dataclass(eq=False)
class Step(Packed):
    """The world's relay of step n to every agent: states, decision and world geometry."""
    n: int
    t: float
    lam: float
    flags: np.ndarray
    steering: np.ndarray
    x: np.ndarray
    y: np.ndarray
    qz: np.ndarray
    qw: np.ndarray
    u: np.ndarray            # (N,) the u each state of t_n carries (u_{n−1})
    alive: np.ndarray
    target: Any              # (2,) or None
    barrier: Any             # (M, 2) or None
    rendezvous: Any


@declare(RUN_CLOCK, Field('tag', kind='finite'), Field('rtf', kind='finite'), Field('t'))
@dataclasses.dataclass(eq=False)
class RunClock(Packed):
    """Realtime: the world's sim time ``t`` (what it also sends on /clock), sent each tick beside it
    for the nodes of its run, which follow this clock alone (`swarm_ros.run_clock`)."""
    tag: float               # the world's sender tag (the readers bind the clock to the first)
    rtf: float               # sim s per wall s: how fast the run's clock can go
    t: float


# ---------------------------------------------------------------- three dimensions (dim: 3)
# A 3D run's lockstep messages carry each state exactly as the batch engine holds it: the
# position r and the frame [x y z] (``state`` (4, K, 3): r, x, y, z), not a quaternion, so that
# a receiver's table is the batch engine's bit for bit; (u, v) as ``uv`` (K, 2).  A planar run
# sends the planar layouts above, unchanged.

@declare(LOCK_AGENT_STATES, Field('K', kind='count'), Field('tag', kind='finite'),
         Field('index', 'K', 'whole'), Field('step', 'K', 'whole'), Field('state', (4, 'K', 3), 'finite'),
         Field('uv', ('K', 2), 'finite'))
@dataclasses.dataclass(eq=False)
class NaturalAgentStates(Packed):
    """`AgentStates` of a 3D run: each agent's r, x, y, z and the (u, v) its state carries."""
    tag: float
    index: np.ndarray        # (K,)
    step: np.ndarray         # (K,)
    state: np.ndarray        # (4, K, 3) r, x, y, z
    uv: np.ndarray           # (K, 2) (u, v)_{step−1}


@declare(LOCK_STEP, Field('n', kind='whole'), Field('t'), Field('N', kind='count'), Field('M', kind='count'),
         Field('lam'), Field('flags', 'N', 'flag'), Field('steering', ('N', 2)), Field('state', (4, 'N', 3)),
         Field('uv', ('N', 2)), Field('alive', 'N', 'flag'), Field('target', 4, 'point3'),
         Field('barrier', ('M', 3), 'points3'), Field('ground', 2, 'height'), Field('rendezvous', 8, 'rendezvous3'))
@dataclasses.dataclass(eq=False)
class NaturalStep(Packed):
    """`Step` of a 3D run: s_k = (s_u, s_v), the states r, x, y, z (4, N, 3), (u, v), a 3D
    target and barrier, the ground's height (or None) and a rendezvous point [x, y, z]."""
    n: int
    t: float
    lam: float
    flags: np.ndarray
    steering: np.ndarray     # (N, 2)
    state: np.ndarray        # (4, N, 3)
    uv: np.ndarray           # (N, 2)
    alive: np.ndarray
    target: Any              # (3,) or None
    barrier: Any             # (M, 3) or None
    ground: Any              # float or None
    rendezvous: Any

    @property
    def x(self):
        """The positions' first column (N,): what the rules read for the table's size."""
        return self.state[0, :, 0]


@declare(AGENT_STATES, Field('K', kind='count'), Field('tag', kind='finite'),
         Field('index', 'K', 'whole'), Field('t', 'K', 'finite'), Field('pose', (12, 'K'), 'finite'),
         Field('u', ('K', 2), 'finite'))
@dataclasses.dataclass(eq=False)
class NaturalProcessStates(Packed):
    """Realtime `ProcessStates` of a 3D run: each state's r, x, y, z (12 rows: r's three, then
    x's, y's, z's) and its (u, v)."""
    tag: float
    index: np.ndarray        # (K,)
    t: np.ndarray            # (K,)
    pose: np.ndarray         # (12, K) r, x, y, z
    u: np.ndarray            # (K, 2) (u, v)


@declare(DECISION, Field('n', kind='whole'), Field('t'), Field('N', kind='count'), Field('lam'),
         Field('flags', 'N', 'flag'), Field('steering', ('N', 2)), Field('slots', 'N', 'int'),
         Field('rendezvous', 8, 'rendezvous3'))
@dataclasses.dataclass(eq=False)
class NaturalDecision(Packed):
    """Realtime `RealtimeDecision` of a 3D run: s_k = (s_u, s_v), a rendezvous point [x, y, z]."""
    n: int
    t: float
    lam: float
    flags: np.ndarray
    steering: np.ndarray     # (N, 2)
    slots: np.ndarray
    rendezvous: Any


MESSAGES = (AgentStates, RobotStates, ProcessStates, RealtimeDecision, Step, RunClock, NaturalAgentStates,
            NaturalStep, NaturalProcessStates, NaturalDecision)
