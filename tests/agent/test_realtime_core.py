"""The realtime tick of an agent container without DDS (`swarm_agent.realtime_core`): K agents
driven from one table and one law call equal K lone agents fed the same heard states (the same
neighbour tables, the same u and the same moves, bit for bit), with stale states left out."""
import copy

import numpy as np
import pytest

from swarm_agent.agent_core import AgentCore, known_table
from swarm_agent.container_core import ContainerCore
from swarm_agent.realtime_core import (
    FUTURE_TOLERANCE_MAX,
    STALE_AFTER,
    STALE_AFTER_MAX,
    Continued,
    HeardStates,
    advance_periods,
    due_periods,
    shared_controls,
    time_limits,
)
from swarm_core.model.frenet import quaternion_from_heading
from tests.core.laws import paper_law

N, DT, STALE = 12, 0.05, 0.3
MINE = [2, 3, 5, 8, 9]          # the container's agents (roster rows)


def _states(rng, n):
    pos = rng.uniform(-4, 4, (n, 2))
    qz, qw = quaternion_from_heading(rng.uniform(-np.pi, np.pi, n))
    return pos, qz, qw


@pytest.mark.parametrize('law', [paper_law(), paper_law(cutoff_radius=3.0, q0=0.0)])
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
        moving, follow = due_periods(now, times, DT, [False] * len(MINE))
        assert follow == []
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
    moving, follow = due_periods(1.0, [0.95, 0.95, 0.0, 0.9], 0.05, [False, True, False, False], [4, 4, 4, 4])
    assert moving == [(0, 1, 1.0), (2, 4, 1.0), (3, 2, 1.0)]       # after a stop: c moves 4 periods, time reset
    assert follow == [(1, 1.0)]                                      # b halted: its time follows the clock


def test_a_late_tick_flies_every_period_it_missed():
    """A starved process ticks late (here 2 s of clock in one tick): its agents fly every period
    that passed, so they keep unit speed (path = periods flown · dt over the sim time); a frozen
    agent's time follows the clock, so it resumes with one period, not with its whole pause."""
    dt, t, flown = 0.1, [0.0, 0.0, 0.0], [0, 0, 0]
    halted = [False, False, False]
    for k, now in enumerate(np.r_[np.arange(1, 51), np.arange(70, 101)] * dt):   # no tick in 5..7 s
        halted[2] = 20 <= k < 40                                                    # frozen 2..4 s
        moving, follow = due_periods(float(now), t, dt, halted)
        for j, periods, t_new in moving:
            flown[j] += periods
            t[j] = t_new
        for j, t_new in follow:
            t[j] = t_new
    assert flown[:2] == [100, 100] and t[:2] == pytest.approx([10.0, 10.0])       # unit speed: 10 s flown
    assert flown[2] == 100 - 20 and t[2] == pytest.approx(10.0)                   # held still for 20 periods only


def test_continued_sees_a_sigcont_once_per_reader():
    import os
    import signal
    a, b = Continued(), Continued()
    assert not a() and not b()
    os.kill(os.getpid(), signal.SIGCONT)          # as after SIGSTOP: the process was continued
    for _ in range(1000):                         # the handler runs between bytecodes
        if a():
            break
    else:
        pytest.fail('SIGCONT not seen')
    assert b() and not a() and not b()


def test_realtime_time_parameters_range_from_two_periods_to_their_maximum():
    """stale_after and future_tolerance: from two control periods (never above the default,
    which every agent must be able to start with) to 60 and 10 sim s."""
    assert time_limits(0.05, STALE_AFTER, STALE_AFTER_MAX) == (0.1, 60.0)
    assert time_limits(0.05, 2.0, FUTURE_TOLERANCE_MAX) == (0.1, 10.0)
    assert time_limits(5.0, STALE_AFTER, STALE_AFTER_MAX) == (STALE_AFTER, 60.0)    # dt of 5 s: the default
