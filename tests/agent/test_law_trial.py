"""A live law parameter set is tried before it is taken (`AgentCore.trial`): the new law runs
on the inputs the agent's u came from last (alone, in a container's one law call, through a
radio model, in a realtime tick), and a law that raises there is refused with its one line;
nothing of the agent changes."""
import copy
from types import SimpleNamespace

import numpy as np
import pytest

from swarm_agent.agent_core import AgentCore
from swarm_agent.container_core import ContainerCore
from swarm_agent.realtime_core import HeardStates, shared_controls
from swarm_core.command.plan import law_with
from swarm_core.laws import Law, param
from swarm_core.model.frenet import quaternion_from_heading
from swarm_core.radio import CommModel

N, DT = 3, 0.05
POS = np.array([[0.0, 0.0], [1.0, 0.5], [-0.5, 1.0]])
THETA = np.array([0.1, -0.3, 1.2])


class Picky(Law):
    """Turns by gain; raises above gain 5 once it has neighbours (on its own it never does)."""

    gain = param(1.0, lo=0.0, hi=10.0)

    def control(self, view):
        if self.gain > 5 and len(view.pos) > 1:
            raise ValueError(f'gain {self.gain:g} with neighbours')
        return np.full(view.receivers.size, 0.01 * self.gain)


def _cores(law, comms=None):
    cores = [AgentCore(i, N, *POS[i], THETA[i], law, DT) for i in range(N)]
    if comms:
        for c in cores:
            c.attach_comms(CommModel.from_config(comms, [f'a{i}' for i in range(N)], DT, 0))
    return cores


def _step(n=0):
    qz, qw = quaternion_from_heading(THETA)
    return SimpleNamespace(n=n, t=n * DT, lam=0.3, flags=np.zeros(N, bool), steering=np.zeros(N),
                           x=POS[:, 0].copy(), y=POS[:, 1].copy(), qz=qz, qw=qw, u=np.zeros(N),
                           alive=np.ones(N, bool), target=None, barrier=None, rendezvous=None)


def _same(a, b):
    np.testing.assert_array_equal(a.pos, b.pos)
    np.testing.assert_array_equal(a.theta, b.theta)
    assert (a.step, a.u_last, a.law) == (b.step, b.u_last, b.law)


@pytest.mark.parametrize('groups,comms', [([[0], [1], [2]], None), ([[0, 1, 2]], None),
                                          ([[0, 1, 2]], dict(loss=0.0, latency=0.0))],
                         ids=['alone', 'container', 'radio'])
def test_a_set_that_makes_the_law_raise_on_the_last_table_is_refused(groups, comms):
    law = Picky()
    cores = _cores(law, comms)
    for g in groups:
        assert [kind for _, kind, _ in ContainerCore([cores[i] for i in g]).on_step(_step())] == ['moved'] * len(g)
    for c in cores:
        before, seen = copy.deepcopy(c), c.seen
        why = c.trial(law_with(law, {'gain': 6.0}))
        assert why is not None and 'Picky raised ValueError: gain 6 with neighbours' in why, why
        assert '\n' not in why
        assert c.trial(law_with(law, {'gain': 4.0})) is None
        _same(c, before)
        assert c.seen is seen


def test_before_its_first_u_an_agent_tries_a_set_on_its_own_state():
    law = Picky()
    core = _cores(law)[0]
    assert core.seen is None
    assert core.trial(law_with(law, {'gain': 6.0})) is None          # alone it has no neighbours
    assert core.seen is None and core.step == 0


def test_a_realtime_tick_leaves_the_table_a_set_is_tried_on():
    law = Picky()
    cores = _cores(law)
    roster = [f'a{i}' for i in range(N)]
    heard = HeardStates(roster)
    qz, qw = quaternion_from_heading(THETA)
    for i in range(N):
        heard.hear(roster[i], (0.0, *POS[i], qz[i], qw[i], 0.0))
    mine = cores[:2]
    shared_controls(mine, heard, 0.05, 1.0, 0.2, np.zeros(N, bool), [0.0, 0.0], None, None)
    for c in mine:
        assert 'gain 6 with neighbours' in c.trial(law_with(law, {'gain': 6.0}))
        assert c.trial(law_with(law, {'gain': 2.0})) is None
