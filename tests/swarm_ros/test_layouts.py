"""The packed lockstep messages (swarm_ros.layouts), from their declarations: every message
round-trips, carries its run id, and its one decoder rejects another run, a wrong size, bad
counts and values its field kinds forbid; rclpy reads the same bytes; the docs show the layouts."""
from __future__ import annotations

import dataclasses
import re
import struct

import numpy as np
import pytest

from swarm_ros import protocol as P
from swarm_ros.layouts import MESSAGES, RUN_ID_BYTES, AgentStates, BadMessage, NotFinite, OtherRun, Step
from swarm_ros.layouts import RealtimeDecision as Decision
from tests.helpers import ROOT


def sample(cls, rng, n=3):
    """A message of class ``cls`` with random values its field kinds allow (n rows)."""
    values = {}
    for f in cls.LAYOUT.fields:
        if f.kind == 'count':
            continue
        shape = f.shape({c: (2 if c == 'M' else n) for c in cls.LAYOUT.counts})
        v = rng.normal(size=shape)
        values[f.name] = {
            'float': v, 'finite': v, 'whole': rng.integers(0, 1000, size=shape), 'int': rng.integers(-1, 5, size=shape),
            'flag': v > 0, 'point': np.array([1.5, -2.5]), 'points': np.array([[0.0, 1.0], [2.0, 3.0]]),
            'rendezvous': ((1.0, 2.0), 0.5, True, None), 'point3': np.array([1.5, -2.5, 3.0]),
            'points3': np.array([[0.0, 1.0, 2.0], [2.0, 3.0, 4.0]]), 'height': -1.5,
            'rendezvous3': ((1.0, 2.0, 3.0), 0.5, True, None),
        }[f.kind]
        if not shape and f.kind in ('float', 'finite'):
            values[f.name] = float(v)
        elif not shape:
            values[f.name] = int(values[f.name])
    return cls(**values)


def same(a, b) -> bool:
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, tuple) or x is None:
            if x != y:
                return False
        elif not np.array_equal(np.asarray(x), np.asarray(y)):
            return False
    return True


@pytest.mark.parametrize('cls', MESSAGES, ids=lambda c: c.__name__)
@pytest.mark.parametrize('n', [0, 1, 5, 40])          # 40: more than _SMALL doubles, packed by numpy
def test_every_message_round_trips_with_its_run_id(cls, n):
    rng = np.random.default_rng(n)
    msg = sample(cls, rng, n)
    for rid in ('', 'a', '1a2b3c4d', 'x' * RUN_ID_BYTES):
        raw = msg.to_cdr(rid)
        got = cls.from_cdr(raw, rid)
        assert type(got) is cls and same(got, msg)
        assert same(cls.from_cdr(raw), msg)                       # a node without a run id takes any
        with pytest.raises(OtherRun, match=re.escape(f"of run {(rid or '(none)')!r}, not this run 'zz'")):
            cls.from_cdr(raw, 'zz')
    with pytest.raises(ValueError, match='longer than'):
        msg.to_cdr('x' * (RUN_ID_BYTES + 1))
    rows = [f for f in cls.LAYOUT.fields
            if isinstance(f.dims()[-1], str) and f.name != cls.LAYOUT.count_of[f.dims()[-1]]]
    if n > 1 and rows:                                    # a field of the wrong size is not packed
        a = rows[0]
        with pytest.raises(ValueError):
            dataclasses.replace(msg, **{a.name: np.asarray(getattr(msg, a.name))[..., :-1]}).to_cdr()


@pytest.mark.parametrize('cls', MESSAGES, ids=lambda c: c.__name__)
def test_a_wrong_size_or_bad_counts_are_rejected(cls):
    data = P.cdr_to_float64_array(sample(cls, np.random.default_rng(1)).to_cdr('run1'))
    for bad in (data[:-1], np.append(data, 0.0), data[:cls.LAYOUT.head - 1], data[:0]):
        with pytest.raises(BadMessage):
            cls.from_cdr(P.float64_array_to_cdr(bad), 'run1')
    for at in cls.LAYOUT.counts.values():
        for v in (np.nan, -1.0, 0.5, 1e12):
            bad = data.copy()
            bad[at] = v
            with pytest.raises(BadMessage, match='whole numbers|do not hold'):
                cls.from_cdr(P.float64_array_to_cdr(bad), 'run1')
    for raw in (b'', b'\x00\x01\x00\x00' + bytes(8)):                # not even a Float64MultiArray
        with pytest.raises(BadMessage, match='not a serialized'):
            cls.from_cdr(raw)


@pytest.mark.parametrize('cls', MESSAGES, ids=lambda c: c.__name__)
def test_finite_and_whole_fields_are_checked_and_the_others_are_not(cls):
    msg = sample(cls, np.random.default_rng(2))
    data = P.cdr_to_float64_array(msg.to_cdr())
    plan = cls.LAYOUT.plan(tuple(int(data[i]) for i in cls.LAYOUT.counts.values()))
    for f, a, b, _ in plan.slots:
        if b == a or f.kind == 'count':
            continue
        bad = data.copy()
        bad[a] = np.nan
        raw = P.float64_array_to_cdr(bad)
        if f.kind in ('finite', 'whole', 'int'):
            with pytest.raises(NotFinite, match=f.name):
                cls.from_cdr(raw)
        else:
            cls.from_cdr(raw)                                    # taken: checked by its reader
        if f.kind == 'whole':
            bad[a] = 1.5
            with pytest.raises(BadMessage, match=f'{f.name}( or .*)? is not a whole number'):
                cls.from_cdr(P.float64_array_to_cdr(bad))


def test_rclpy_reads_the_same_record():
    """The bytes are a std_msgs/Float64MultiArray (empty layout) as rclpy serializes it; the
    first RUN_ID_BYTES of ``data`` are the run id, then the fields as declared."""
    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import Float64MultiArray
    msg = AgentStates(9.0, np.array([3, 0]), np.array([7, 7]), np.array([[1.5, 0.0], [-2.0, 1.0], [0.1, 0.0],
                                                                        [0.99, 1.0]]), np.array([0.25, -0.5]))
    raw = msg.to_cdr('abc12345')
    m = deserialize_message(raw, Float64MultiArray)
    assert len(m.layout.dim) == 0
    data = np.array(m.data)
    assert data[:4].tobytes() == b'abc12345'.ljust(RUN_ID_BYTES, b'\0')
    # [run_id(4), K, tag, index(K), step(K), pose(4, K), u(K)]
    assert data[4:].tolist() == [2, 9.0, 3, 0, 7, 7, 1.5, 0.0, -2.0, 1.0, 0.1, 0.0, 0.99, 1.0, 0.25, -0.5]
    # the same bytes but the 4 alignment bytes before ``data`` (rclpy leaves them as they were)
    again = serialize_message(m)
    assert len(again) == len(raw) and again[:16] + again[20:] == raw[:16] + raw[20:]
    assert same(AgentStates.from_cdr(serialize_message(m), 'abc12345'), msg)


def test_step_and_decision_decode_what_their_readers_use():
    s = Step(4, 0.4, 0.5, np.array([False, True]), np.array([0.0, 0.3]), np.array([1.0, 2.0]), np.array([3.0, 4.0]),
             np.zeros(2), np.ones(2), np.array([0.1, 0.2]), np.array([True, False]), None, None, None)
    got = Step.from_cdr(s.to_cdr())
    assert (got.n, got.t, got.lam) == (4, 0.4, 0.5) and isinstance(got.n, int)
    assert got.flags.dtype == bool and got.alive.tolist() == [True, False]
    assert got.target is None and got.barrier is None and got.rendezvous is None
    d = Decision(4, 0.4, 1.0, np.array([True, False]), np.array([0.2, 0.0]), np.array([0, -1]),
                 (None, 2.0, False, 0.5))
    got = Decision.from_cdr(d.to_cdr())
    assert got.slots.tolist() == [0, -1] and got.rendezvous == (None, 2.0, False, 0.5)


def test_the_docs_show_the_declared_layouts():
    text = (ROOT / 'docs' / 'ros-graph.md').read_text()
    for cls in MESSAGES:
        assert cls.LAYOUT.text() in text, cls.LAYOUT.text()


@pytest.mark.parametrize('k', [0, 1, 3])
def test_a_packer_makes_what_encode_makes(k):
    """`Layout.packer`: the bytes of `encode` for the same values, without a message object."""
    rng = np.random.default_rng(k)
    msg = AgentStates(17.0, rng.integers(0, 9, k), rng.integers(0, 99, k), rng.normal(size=(4, k)), rng.normal(size=k))
    values = [msg.tag, *msg.index, *msg.step, *msg.pose.ravel(), *msg.u]
    assert AgentStates.LAYOUT.packer((k,), 'run7')(*values) == msg.to_cdr('run7')
    with pytest.raises(struct.error):
        AgentStates.LAYOUT.packer((k,), 'run7')(*values, 1.0)         # one value too many
