"""A realtime tick never integrates an unbounded number of periods (`realtime_core.CATCH_UP_MAX`):
an agent whose state is far behind the clock (the system clock, ≈1.8e9 s, read by an agent
started without use_sim_time; a run joined late; a clock that jumped) restarts its time at the
clock without a move, where it owed billions of periods in one callback."""
import time

from swarm_agent.realtime_core import CATCH_UP_MAX, due_periods


def test_a_gap_beyond_the_bound_restarts_the_agents_time_without_a_move():
    dt = 0.05
    now = time.time()                                   # the system clock
    t0 = time.perf_counter()
    moving, follow = due_periods(now, [0.0, now - 3 * dt, 0.0], dt, [False, False, True])
    assert time.perf_counter() - t0 < 0.1
    assert moving == [(1, 3, moving[0][2])] and abs(moving[0][2] - now) < dt
    assert [j for j, _ in follow] == [0, 2] and all(abs(t - now) < dt for _, t in follow)
    # the bound itself: CATCH_UP_MAX periods are flown (a starved process), one more is not
    moving, follow = due_periods(CATCH_UP_MAX * dt, [0.0], dt, [False])
    assert moving[0][1] == CATCH_UP_MAX and not follow
    moving, follow = due_periods((CATCH_UP_MAX + 1) * dt, [0.0], dt, [False])
    assert not moving and len(follow) == 1
    # after a stop (SIGCONT) the agent's catch_up_limit applies, as before
    moving, _ = due_periods(now, [0.0], dt, [False], [4])
    assert moving == [(0, 4, now)]
