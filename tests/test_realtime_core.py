"""The realtime tick of an agent container without DDS (`swarm_agent.realtime_core`): K agents
driven from one table and one law call equal K lone agents fed the same heard states (the same
neighbour tables, the same u and the same moves, bit for bit), with stale states left out."""
import copy

import numpy as np
import pytest

from swarm_agent.agent_core import AgentCore, known_table
from swarm_agent.container_core import ContainerCore
from swarm_agent.realtime_core import HeardStates, advance_periods, due_periods, shared_controls
from swarm_core.frenet import quaternion_from_heading
from swarm_core.laws import LawConfig

N, DT, STALE = 12, 0.05, 0.3
MINE = [2, 3, 5, 8, 9]          # the container's agents (roster rows)


def _states(rng, n):
    pos = rng.uniform(-4, 4, (n, 2))
    qz, qw = quaternion_from_heading(rng.uniform(-np.pi, np.pi, n))
    return pos, qz, qw


@pytest.mark.parametrize('law', [LawConfig(), LawConfig(cutoff_radius=3.0, q0=0.0)])
def test_container_tick_equals_lone_agents(law):
    rng = np.random.default_rng(4)
    roster = [f'agent_{i}' for i in range(N)]
    pos, _, _ = _states(rng, N)
    theta = rng.uniform(-np.pi, np.pi, N)
    cores = [AgentCore(i, N, *pos[i], theta[i], law, DT, (0.01, 0.01), np.random.default_rng(i)) for i in MINE]
    lone = copy.deepcopy(cores)
    lock = ContainerCore(cores)
    heard = HeardStates(roster)
    times = [0.0] * len(MINE)
    for c in cores:
        heard.hear(roster[c.index], (0.0, *c.pos[0], *c.quaternion, 0.0))
    leaders = {roster[0], roster[3]}
    mask = np.array([nm in leaders for nm in roster])
    target, barrier = np.array([30.0, 5.0]), np.array([[10.0, -2.0], [12.0, -2.0], [11.0, 1.0]])
    steps_taken = 0
    for tick in [*range(1, 20), *range(21, 41)]:                 # one clock jump of two periods
        now = tick * DT
        others = [i for i in range(N) if i not in MINE and rng.random() < 0.7]   # some fall silent, go stale
        p, qz, qw = _states(rng, N)
        for i in others:
            heard.hear(roster[i], (now - rng.uniform(0, 2 * DT), *p[i], qz[i], qw[i], 0.0))
        lam, steering = rng.uniform(0, 1), rng.uniform(-0.1, 0.1, len(MINE))
        moving = due_periods(now, times, DT, [4] * len(MINE), [False] * len(MINE))
        assert [j for j, _, _ in moving] == list(range(len(MINE)))
        u = shared_controls(cores, heard, now, STALE, lam, mask, steering, target, barrier)
        for j, c in enumerate(lone):
            name = roster[c.index]
            newest = {nm: s for nm, s in heard.newest.items() if nm != name}
            own = (c.pos[0, 0], c.pos[0, 1], *c.quaternion)
            row, rows, flags = known_table(roster, name, own, newest, leaders, now, STALE)
            names = [nm for nm in roster if nm == name or (nm in newest and now - newest[nm][0] <= STALE)]
            got_rows, _ = heard.table(now, STALE, [c.index])
            assert [roster[i] for i in got_rows] == names          # the same neighbour table
            want = c.control(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], lam, flags, steering[j],
                             target, barrier, row=row)
            assert u[j] == want                                     # bit for bit
            for _ in range(moving[j][1]):
                c.advance(want)
        advance_periods(lock, [j for j, _, _ in moving], [p for _, p, _ in moving], u)
        for j, periods, t_new in moving:
            times[j] = t_new
            steps_taken += periods
            c = cores[j]
            np.testing.assert_array_equal(c.pos, lone[j].pos)
            np.testing.assert_array_equal(c.theta, lone[j].theta)
            assert c.quaternion == lone[j].quaternion
            heard.hear(roster[c.index], (t_new, *c.pos[0], *c.quaternion, u[j]))
    assert steps_taken == len(MINE) * 40                            # the jump: two periods in one tick


def test_stale_states_leave_the_table_and_halted_agents_stay():
    roster = ['a', 'b', 'c', 'd']
    heard = HeardStates(roster)
    heard.hear('a', (1.0, 0, 0, 0, 1, 0))
    heard.hear('c', (0.2, 1, 1, 0, 1, 0))
    rows, states = heard.table(1.5, 1.0, [3])
    assert list(rows) == [0, 3]                        # c is 1.3 s old; d is a receiver, always in
    assert states[0].tolist() == [0, 0, 0, 1]
    moving = due_periods(1.0, [0.95, 0.95, 0.0, 0.9], 0.05, [4, 4, 4, 4], [False, True, False, False])
    assert moving == [(0, 1, 1.0), (2, 4, 1.0), (3, 2, 1.0)]       # b halted; c starved: 4 periods, time reset
