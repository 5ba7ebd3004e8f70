"""The realtime tick of a 3D run's agents without ROS (`swarm_agent.natural_realtime`): agents with
a radio model take (u, v) from what their own radio (`natural_radio.NaturalStreamRadio`) delivered,
their container's other agents heard through it too; the agents without one from the process's
table of what it heard."""
from types import SimpleNamespace

import numpy as np

from swarm_agent.natural_core import NaturalAgentCore, NaturalContainerCore
from swarm_agent.natural_realtime import natural_heard, natural_realtime_tick
from swarm_agent.process_io import LeaderMask
from swarm_core.laws import make_law
from swarm_core.model.natural import initial_frames
from swarm_core.natural_radio import NaturalStreamRadio
from swarm_core.radio import CommModel
from swarm_core.step import natural_alive_control

N, DT = 4, 0.1
ROSTER = [f'agent_{i}' for i in range(N)]


class Agent(SimpleNamespace):
    """What the tick reads of an agent node (`agent_node.AgentNode`)."""

    def _now(self):
        return self.clock[0]

    def applied(self, uv):
        self.uv.append(uv)

    def publish_state(self):
        pass

    def reject(self, *why):
        raise AssertionError(why)


def agents(loss, radio):
    """N agents of one process, those in ``radio`` with a radio of ``loss`` (no latency)."""
    rng = np.random.default_rng(4)
    pos = rng.uniform(-1.5, 1.5, (N, 3))
    x, y, z = initial_frames(rng.normal(size=(N, 3)))
    law, clock = make_law({'kind': 'global'}), [0.0]
    out = []
    for i in range(N):
        model = CommModel.from_config(dict(loss=loss), ROSTER, DT, 3)
        core = NaturalAgentCore(i, N, pos[i], np.concatenate([x[i], y[i], z[i]]), law, DT)
        driver = SimpleNamespace(catch_up_limit=4, stale_after=2.0, stream=NaturalStreamRadio(model, i))
        out.append(Agent(index=i, agent_name=ROSTER[i], core=core, driver=driver, clock=clock, t=0.0, dt=DT,
                         halted=None, steering=(0.0, 0.0), lam=0.0, leaders=set(), target=None, barrier=None,
                         ground=None, radio_on=i in radio, step=0, uv=[]))
    return out, clock


def tick(group, lock, heard, clock):
    clock[0] = round(clock[0] + DT, 10)
    natural_realtime_tick(group, lock, heard, LeaderMask(ROSTER), SimpleNamespace(publish=lambda a: None),
                          lambda: False)


def test_radio_agents_of_a_container_hear_each_other_through_their_radios():
    """Agents 0-2 with a radio that delivers all, agent 3 without: after one tick each radio agent
    holds the others' states of that tick (its container's, heard through its radio), and at the
    next its (u, v) is the law's on its radio's table (those states dead-reckoned one period)."""
    group, clock = agents(0.0, radio=(0, 1, 2))
    lock, heard = NaturalContainerCore([a.core for a in group]), natural_heard(ROSTER)
    heard.own[:] = True
    tick(group, lock, heard, clock)
    for a in group:
        a.driver.stream.release(clock[0])                      # delivered at once (no latency)
    for a in group[:3]:
        assert sorted(a.driver.stream.newest) == [j for j in range(N) if j != a.index]
    assert not group[3].driver.stream.newest                  # no radio: the process's table
    b = lock.bank
    sent = {j: (float(b.pos[j, 0]), float(b.x[j, 0])) for j in range(N)}
    for a in group[:3]:                                        # the states of the tick, as published
        assert {j: (s[1], s[4]) for j, s in a.driver.stream.newest.items()} == \
            {j: v for j, v in sent.items() if j != a.index}
    now = clock[0] + DT
    rows, states = group[0].driver.stream.table(now, np.concatenate([b.pos[0], b.x[0], b.y[0], b.z[0]]))
    assert list(rows) == list(range(N))
    pos, x, y, z = (np.ascontiguousarray(states[:, 3 * c:3 * c + 3]) for c in range(4))
    want = natural_alive_control(pos, (x, y, z), [0], group[0].core.law, 0.0, np.zeros(N, bool), np.zeros((1, 2)),
                                 t=now)[0]
    assert np.abs(want).min() > 0
    tick(group, lock, heard, clock)
    np.testing.assert_array_equal(b.u[0], want[0])
    np.testing.assert_array_equal(b.v[0], want[1])


def test_a_radio_that_loses_everything_leaves_each_agent_alone():
    group, clock = agents(1.0, radio=range(N))
    lock, heard = NaturalContainerCore([a.core for a in group]), natural_heard(ROSTER)
    heard.own[:] = True
    for _ in range(3):
        tick(group, lock, heard, clock)
    for a in group:
        a.driver.stream.release(clock[0])
        assert not a.driver.stream.newest and a.driver.stream.heard.sum() == 3 * (N - 1)
    np.testing.assert_array_equal(lock.bank.u, 0.0)             # the global law alone: no pairs, u = v = 0
    np.testing.assert_array_equal(lock.bank.v, 0.0)
