"""Realtime agents with a radio model, without ROS (`process_io.realtime_tick`,
`drivers.RealtimeDriver`): in a planar container each radio agent hears its container's other
agents through its radio (their states never come back over DDS: the process drops its own
batch), as in 3D (tests/agent/test_natural_realtime.py); a lone agent hears no one in-process;
and a radio agent refuses a state claiming to be any agent of its process from another
publisher, as the process's table does, planar and 3D."""
from types import SimpleNamespace

import numpy as np
import pytest

from swarm_agent.agent_core import AgentCore
from swarm_agent.container_core import ContainerCore
from swarm_agent.drivers import RealtimeDriver
from swarm_agent.natural_core import NaturalAgentCore
from swarm_agent.natural_realtime import hear_own, natural_heard
from swarm_agent.process_io import LeaderMask, realtime_tick
from swarm_agent.realtime_core import HeardStates
from swarm_core.laws import make_law
from swarm_core.model.frenet import quaternion_from_heading
from swarm_core.model.natural import initial_frames
from swarm_core.radio import CommModel
from swarm_ros import protocol as P
from swarm_ros.layouts import NaturalProcessStates, ProcessStates

N, DT, RUN = 4, 0.1, 'run42'
ROSTER = [f'agent_{i}' for i in range(N)]
TAG = 5.0                                       # the sender tag of the process's batches


class Node(SimpleNamespace):
    """What the tick and the realtime driver read of an agent node (`agent_node.AgentNode`)."""

    def _now(self):
        return self.clock[0]

    def applied(self, u):
        self.us.append(u)

    def publish_state(self):
        qz, qw = self.core.quaternion
        self.own = (*P.time_to_stamp(self.t), *map(float, self.core.pos[0]), qz, qw, self.core.u_last)

    def reject(self, kind, _why):
        self.rejected.append(str(kind))


def planar(radio, loss=0.0):
    """N planar agents, those in ``radio`` with a radio of ``loss`` (no latency), each with its
    realtime driver."""
    rng = np.random.default_rng(4)
    pos, theta = rng.uniform(-1.5, 1.5, (N, 2)), rng.uniform(-np.pi, np.pi, N)
    law, clock = make_law({'kind': 'global'}), [0.0]
    out = []
    for i in range(N):
        node = Node(index=i, agent_name=ROSTER[i], roster=ROSTER, row={nm: k for k, nm in enumerate(ROSTER)}, dim=2,
                    radio=CommModel.from_config(dict(loss=loss), ROSTER, DT), radio_on=i in radio, run_id=RUN,
                    core=AgentCore(i, N, *pos[i], theta[i], law, DT), clock=clock, t=0.0, dt=DT, halted=None,
                    steering=0.0, lam=0.0, leaders=set(), target=None, barrier=None, step=0, us=[], rejected=[])
        node.driver = RealtimeDriver(node, 2.0, 4, 1.0)
        if node.radio_on:
            node.driver.radio_started()
        node.publish_state()
        out.append(node)
    return out, clock


def contained(group, heard):
    """The agents ``group`` in one process, as `container_node.AgentContainer` joins them."""
    for a in group:
        heard.own[a.index] = True
    for a in group:
        a.driver.join(TAG, heard)
        if a.dim == 2:
            heard.hear(a.agent_name, (a.t, *a.own[2:]))
        else:
            hear_own(heard, a)


def tick(group, lock, heard, clock):
    clock[0] = round(clock[0] + DT, 10)
    realtime_tick(group, lock, heard, LeaderMask(ROSTER), SimpleNamespace(publish=lambda agents: None),
                  lambda: False)


def test_planar_radio_agents_of_a_container_hear_each_other_through_their_radios():
    """Agents 0-2 with a radio that delivers all, agent 3 without: after one tick each radio agent
    holds its container's other agents' states of that tick, heard through its radio, and at the
    next its u is the law's on its radio's table (those states dead-reckoned one period)."""
    group, clock = planar(radio=(0, 1, 2))
    lock, heard = ContainerCore([a.core for a in group]), HeardStates(ROSTER)
    contained(group, heard)
    tick(group, lock, heard, clock)
    for a in group[:3]:
        a.driver.stream.release(clock[0])                      # delivered at once (no latency)
        assert sorted(a.driver.stream.newest) == [j for j in range(N) if j != a.index]
        assert {j: s[1:] for j, s in a.driver.stream.newest.items()} == \
            {b.index: b.own[2:] for b in group if b is not a}  # the states of the tick, as published
    assert not group[3].driver.stream.newest                  # no radio: the process's table
    now = round(clock[0] + DT, 10)
    rows, states = group[0].driver.stream.table(now, (*group[0].core.pos[0], *group[0].core.quaternion))
    assert list(rows) == list(range(N))
    want = group[0].core.control(*states.T, 0.0, np.zeros(N, bool), 0.0, row=0, t=now)
    assert want != 0.0
    tick(group, lock, heard, clock)
    assert group[0].us[-1] == want
    assert not any(a.rejected for a in group)


def test_a_lone_radio_agent_hears_no_one_in_process():
    """A container of one (a lone agent process): its tick moves it on its radio's table, itself
    alone until another process's batch comes."""
    group, clock = planar(radio=(1,))
    a = group[1]
    lock, heard = ContainerCore([a.core]), HeardStates(ROSTER)
    contained([a], heard)
    for _ in range(3):
        tick([a], lock, heard, clock)
    assert not a.driver.stream.newest and a.driver.stream.heard.sum() == 0
    assert a.us == [0.0] * 3 and a.step == 3 and a.t == pytest.approx(clock[0])      # the global law alone: u = 0


def natural(radio):
    """N 3D agents, those in ``radio`` with a radio that delivers all."""
    rng = np.random.default_rng(4)
    pos = rng.uniform(-1.5, 1.5, (N, 3))
    x, y, z = initial_frames(rng.normal(size=(N, 3)))
    law, clock = make_law({'kind': 'global'}), [1.0]
    out = []
    for i in range(N):
        node = Node(index=i, agent_name=ROSTER[i], roster=ROSTER, dim=3, radio_on=i in radio, run_id=RUN,
                    radio=CommModel.from_config({}, ROSTER, DT, 3), clock=clock, t=0.0, dt=DT, rejected=[],
                    core=NaturalAgentCore(i, N, pos[i], np.concatenate([x[i], y[i], z[i]]), law, DT))
        node.driver = RealtimeDriver(node, 2.0, 4, 1.0)
        if node.radio_on:
            node.driver.radio_started()
        out.append(node)
    return out, clock


def batch(dim, rows, t, tag):
    """Another process's batch of states of agents ``rows`` at time t, serialized."""
    k = len(rows)
    if dim == 3:
        pose = np.tile(np.array([0.5, 0.5, 0.5, 1, 0, 0, 0, 1, 0, 0, 0, 1], float)[:, None], (1, k))
        return NaturalProcessStates(tag, rows, [t] * k, pose, np.zeros((k, 2))).to_cdr(RUN)
    qz, qw = quaternion_from_heading(np.zeros(k))
    return ProcessStates(tag, rows, [t] * k, np.stack([np.full(k, 0.5), np.full(k, 0.5), qz, qw]),
                         np.zeros(k)).to_cdr(RUN)


@pytest.mark.parametrize('dim', [2, 3])
@pytest.mark.parametrize('radio_first', [True, False], ids=['radio-then-container', 'container-then-radio'])
def test_a_radio_agent_refuses_states_claiming_its_container_mates(dim, radio_first):
    """Agents 0-2 in one process; agent 1 with a radio (from the start, or turned on later by a
    runtime radio event).  Another publisher's batch claiming agent 0, 1 or 2 is refused
    (``dup-self``, as the process's table refuses it) and never reaches the radio; agent 3's
    state from it is heard."""
    group, clock = planar(radio=()) if dim == 2 else natural(radio=())
    clock[0] = 1.0
    a = group[1]
    heard = HeardStates(ROSTER) if dim == 2 else natural_heard(ROSTER)
    if radio_first:
        a.radio_on = True
        a.driver.radio_started()
    contained(group[:3], heard)
    if not radio_first:
        a.radio_on = True
        a.driver.radio_started()
    for j in range(3):
        a.driver.on_input(batch(dim, [j], 0.9, 9.0))
        assert a.rejected == ['dup-self'], j
        del a.rejected[:]
    a.driver.on_input(batch(dim, [2, 3], 0.9, 9.0))
    assert a.rejected == ['dup-self']
    assert a.driver.stream.heard.tolist() == [0, 0, 0, 1]
    a.driver.on_input(batch(dim, [0], 0.9, TAG))           # the process's own batch: not read at all
    assert a.rejected == ['dup-self'] and a.driver.stream.heard.sum() == 1
