"""Realtime batches of states, without DDS: the one ``/swarm/agent_states`` message an agent
process sends per tick (`process_io.AgentStatesWriter`) decodes (`process_io.decode_batch`)
into the same heard table (`realtime_core.HeardStates`) as the same states sent one by one on
``/swarm/states``, and each state in it goes through the same checks (run id, finite values,
roster, one sender per agent, past and future stamps)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from swarm_agent.process_io import AgentStatesWriter, decode_batch
from swarm_agent.realtime_core import HeardStates
from swarm_core.model.frenet import quaternion_from_heading
from swarm_ros import protocol as P
from swarm_ros.layouts import ProcessStates
from swarm_ros.msg_checks import FUTURE_TOLERANCE, Senders, check_values, refused

N, RUN = 10, 'run42'
ROSTER = [f'agent_{i}' for i in range(N)]


class _Pub:
    def __init__(self):
        self.sent = []

    def publish(self, raw):
        self.sent.append(raw)


class _Node:
    """What `AgentStatesWriter` uses of a node: one publisher."""

    def create_publisher(self, _type, topic, _qos):
        self.topic, self.pub = topic, _Pub()
        return self.pub


class _Log(list):
    """A `RejectLog` stand-in: the kinds rejected."""

    def __call__(self, kind, _text):
        self.append(str(kind))


def _agents(rng, rows, t):
    """Agents as `AgentStatesWriter` reads them: index, run_id and ``own`` (what each last
    published on /swarm/states: sec, nanosec, x, y, qz, qw, u)."""
    qz, qw = quaternion_from_heading(rng.uniform(-np.pi, np.pi, len(rows)))
    out = []
    for j, i in enumerate(rows):
        sec, nsec = P.time_to_stamp(t[j])
        x, y = rng.uniform(-5, 5, 2)
        own = (sec, nsec, float(x), float(y), float(qz[j]), float(qw[j]), float(rng.normal()))
        out.append(SimpleNamespace(index=i, run_id=RUN, agent_name=ROSTER[i], own=own))
    return out


def _batch(agents, tag=None):
    node = _Node()
    w = AgentStatesWriter(node, realtime=True)
    if tag is not None:
        w.tag = tag
    w.publish(agents)
    assert node.topic == P.AGENT_STATES and len(node.pub.sent) == 1
    return node.pub.sent[0], w.tag


def _own_echo(name, tag, own, reject) -> bool:
    """Is this state one of the reader's own agents (``own``: name -> sender tag)?  From another
    publisher it is rejected as a duplicate agent name."""
    if name not in own:
        return False
    if tag != own[name]:
        reject('dup-self', f'state claiming to be {name!r} (this agent) from another publisher')
    return True


def _one_by_one(agents, tag, heard, senders, own, now, log):
    """The same states as /swarm/states messages, decoded and each checked as it was
    (`check_values`, one sender per name, the reader's own agents only from itself)."""
    for a in agents:
        raw = P.OdometryWriter(a.agent_name, tag=tag)(*a.own)
        name, sec, nsec, pose, wz, sender = P.cdr_to_odometry_tagged(raw)
        t = sec + nsec * 1e-9
        if _own_echo(name, sender, own, log) or refused(log, check_values(
                name, t, pose, wz, heard.row, heard.newest, now, FUTURE_TOLERANCE) or senders.check(name, sender)):
            continue
        senders.accept(name, sender)
        heard.hear(name, (t, pose[0], pose[1], pose[4], pose[5], wz))


def test_a_batch_gives_the_table_the_states_one_by_one_give():
    rng = np.random.default_rng(3)
    mine = [1, 4]                                        # the reader's own agents
    ticks = [(_agents(rng, [0, 2, 3, 7], [0.1, 0.1, 0.15, 0.1]), _agents(rng, [5, 6, 8, 9], [0.1] * 4)),
             (_agents(rng, [0, 2, 3, 7], [0.2, 0.25, 0.2, 0.2]), _agents(rng, [5, 8], [0.2, 0.3]))]
    a, b = HeardStates(ROSTER), HeardStates(ROSTER)
    a.own[mine] = True
    sb, log_a, log_b = Senders(), _Log(), _Log()
    own_tag = 5.0
    for tick in ticks:
        for p, agents in enumerate(tick):
            raw, tag = _batch(agents, tag=100.0 + p)
            m = decode_batch(raw, RUN, ROSTER, own_tag, log_a)
            assert len(m.index) == len(agents)
            a.take(m, ROSTER, 0.3, FUTURE_TOLERANCE, log_a)
            _one_by_one(agents, 100.0 + p, b, sb, {ROSTER[i]: own_tag for i in mine}, 0.3, log_b)
    assert not log_a and not log_b
    assert a.newest == b.newest and len(a.newest) == 8
    assert np.array_equal(a.t, b.t) and np.array_equal(a.state, b.state)
    for now in (0.3, 0.55):
        ra, xa = a.table(now, 0.3, mine)
        rb, xb = b.table(now, 0.3, mine)
        assert np.array_equal(ra, rb) and np.array_equal(xa, xb)
    assert a.newest['agent_8'][0] == P.time_to_stamp(0.3)[0] + P.time_to_stamp(0.3)[1] * 1e-9


def test_each_state_of_a_batch_is_checked():
    rng = np.random.default_rng(5)
    heard, log = HeardStates(ROSTER), _Log()
    own_tag = 5.0
    heard.own[1] = True

    def hear(raw):
        m = decode_batch(raw, RUN, ROSTER, own_tag, log)
        if m is not None:
            heard.take(m, ROSTER, 1.0, FUTURE_TOLERANCE, log)

    first = _agents(rng, [0, 2], [0.5, 0.5])
    hear(_batch(first, tag=7.0)[0])
    assert set(heard.newest) == {'agent_0', 'agent_2'} and not log
    hear(_batch(_agents(rng, [0], [0.9]), tag=7.0)[0].replace(b'run42', b'run43'))      # another run
    hear(_batch(_agents(rng, [2], [0.6]), tag=8.0)[0])                              # a second process for agent_2
    hear(_batch(_agents(rng, [1], [0.6]), tag=8.0)[0])                              # claims the reader's agent
    hear(_batch(_agents(rng, [3], [1.0 + FUTURE_TOLERANCE + 0.1]), tag=8.0)[0])     # from the future
    hear(_batch(_agents(rng, [0], [0.4]), tag=7.0)[0])                              # from the past
    assert log == ['other-run', 'second-publisher', 'dup-self', 'future-stamp', 'past-stamp']
    assert heard.newest['agent_0'][0] == 0.5 and 'agent_3' not in heard.newest
    assert heard.newest['agent_2'][1:5] == first[1].own[2:6]
    del log[:]
    hear(_batch(_agents(rng, [1, 4], [0.7, 0.7]), tag=own_tag)[0])                  # the reader's own batch
    assert not log and 'agent_4' not in heard.newest
    x = np.zeros((4, 1))
    x[3] = 1.0
    for bad in (ProcessStates(8.0, [N], [0.7], x, [0.0]),                            # outside the roster
                ProcessStates(8.0, [3, 3], [0.7, 0.7], np.repeat(x, 2, 1), [0.0, 0.0]),   # an agent twice
                ProcessStates(8.0, [3], [0.7], 2 * x, [0.0])):                     # not a unit quaternion
        hear(bad.to_cdr(RUN))
    data = P.cdr_to_float64_array(ProcessStates(8.0, [3], [0.7], x, [0.0]).to_cdr(RUN)).copy()
    data[-2] = np.nan                                                                # a non-finite pose
    hear(P.float64_array_to_cdr(data))
    assert log == ['unknown-agent', 'duplicate', 'not-planar', 'non-finite'] and 'agent_3' not in heard.newest


def test_a_mixed_batch_is_taken_as_its_states_one_by_one():
    """Batches mixing good states with repeats, duplicates, past and future stamps, a second
    process and claims on the reader's agent: taken at once, the table and the kinds refused
    are those of the same states checked one by one."""
    rng = np.random.default_rng(11)
    a, b, sb, log_a, log_b = HeardStates(ROSTER), HeardStates(ROSTER), Senders(), _Log(), _Log()
    a.own[1] = True
    own = {'agent_1': 5.0}
    sent = {}
    for tick in range(60):
        tag = float(rng.choice([7.0, 8.0, 9.0]))
        rows = sorted(rng.choice(N, size=rng.integers(1, 6), replace=False).tolist())
        t = np.round(rng.uniform(0, 4.0, len(rows)), 1)
        agents = _agents(rng, rows, t)
        for ag in agents:                                 # some exact repeats of a state sent before
            if ag.index in sent and rng.random() < 0.3:
                ag.own = sent[ag.index]
            sent[ag.index] = ag.own
        m = decode_batch(_batch(agents, tag=tag)[0], RUN, ROSTER, 5.0, log_a)
        a.take(m, ROSTER, 1.0 + tick * 0.05, FUTURE_TOLERANCE, log_a)
        _one_by_one(agents, tag, b, sb, own, 1.0 + tick * 0.05, log_b)
        assert sorted(set(log_a)) == sorted(set(log_b)), tick
        del log_a[:], log_b[:]
    assert a.newest == b.newest and np.array_equal(a.state, b.state)


def test_a_3d_process_answers_the_world_with_its_bank_rows_in_the_order_asked():
    """Lockstep in 3D: a lone agent's answer is packed from plain floats, a container's from
    the bank, whole or gathered; each decodes to the rows asked, in the order asked (a repeat
    comes before the moved ones), as `NaturalStates.message` of those rows."""
    from swarm_agent.natural_core import NaturalStates
    from swarm_ros.layouts import NaturalAgentStates
    rng = np.random.default_rng(5)
    for k, js in ((1, [0]), (3, [0, 1, 2]), (3, [2, 0, 1]), (3, [1])):
        b = NaturalStates(k)
        b.pos[:], b.x[:], b.y[:], b.z[:] = rng.normal(size=(4, k, 3))
        b.u[:], b.v[:], b.step[:] = rng.normal(size=k), rng.normal(size=k), rng.integers(0, 99, k)
        lock = SimpleNamespace(dim=3, bank=b, rows=np.array([4, 1, 5][:k]))
        node = _Node()
        w = AgentStatesWriter(node, realtime=False)
        w.publish_rows(lock, np.array(js), RUN)
        got = NaturalAgentStates.from_cdr(node.pub.sent[0], RUN)
        assert got.tag == w.tag and got.index.tolist() == lock.rows[js].tolist()
        assert got.step.tolist() == b.step[js].tolist()
        np.testing.assert_array_equal(got.state, np.stack([b.pos[js], b.x[js], b.y[js], b.z[js]]))
        np.testing.assert_array_equal(got.uv, np.stack([b.u[js], b.v[js]], axis=1))
        assert node.pub.sent[0] == b.message(w.tag, lock.rows[js], np.array(js)).to_cdr(RUN)
