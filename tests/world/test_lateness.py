"""How late a realtime run's states come (`swarm_world.lateness`), without ROS."""
import numpy as np
import pytest

from swarm_world.lateness import GROWTH, ON_TIME_TARGET, Lateness, behind_line, bins_of, ramp, timing_line


def test_on_time_run():
    late = Lateness(2, 0.05, 2.0)
    for k in range(100):
        for i in range(2):
            late.arrive(i, k, k * 0.05, k * 0.05 + 0.004)         # 4 ms sim = 2 ms wall at rtf 2
    s = late.summary(99)
    assert s['on_time_share'] == 1.0 and s['states'] == 200 and s['late'] == 0
    assert s['lateness_p50_ms'] == s['lateness_p99_ms'] == pytest.approx(2.0, rel=0.01)   # its bin's upper edge
    assert s['lateness_p50_ms'] >= 2.0
    assert s['achieved_rtf'] == 2.0
    assert behind_line(s, 2.0) is None
    assert timing_line(s).startswith('timing: 100.0% of 200 states on time')


def test_skipped_periods_and_late_states_count():
    late = Lateness(2, 0.05, 1.0)
    for k in range(0, 100, 2):                  # agent 0 starved: one state per two periods, each late
        late.arrive(0, k, k * 0.05, k * 0.05 + 0.08)
    for k in range(100):
        late.arrive(1, k, k * 0.05, k * 0.05 + 0.01)
    s = late.summary(99)
    assert s['states'] == 50 + 49 + 100                 # 49 states agent 0 skipped never came
    assert s['arrived'] == 150
    assert s['on_time_share'] == 100 / 199
    # agent 0's states come 80 ms late; each one it skipped was superseded 130 ms after its own period
    assert s['lateness_p50_ms'] == pytest.approx(10.0, rel=0.01)
    assert s['lateness_p99_ms'] == pytest.approx(130.0, rel=0.01) and s['lateness_p99_ms'] >= 130.0
    line = behind_line(s, 1.0)
    assert line.startswith('fell behind: 50.3% of states on time') and f'{ON_TIME_TARGET:.0%}' in line
    assert 'p99 130.' in timing_line(s)


def test_a_run_far_behind_still_measures_its_p99():
    """Most states skipped or still owed: the quantiles fall among them and are still numbers."""
    late = Lateness(1, 0.1, 1.0)
    late.arrive(0, 0, 0.0, 0.0)
    late.arrive(0, 50, 5.0, 5.0 + 30.0)                # 49 periods skipped; this one 30 s late
    s = late.summary(60)                               # 9 more owed (steps 51..59)
    assert s['states'] == 2 + 49 + 9 and s['on_time_share'] == 1 / 60
    assert s['lateness_p99_ms'] == pytest.approx(1000 * (30.0 + 4.9), rel=0.01)   # the oldest skipped
    assert 30_000 <= s['lateness_p50_ms'] <= 1000 * (30.0 + 4.9) * GROWTH


def test_histogram_bins_grow_by_one_percent():
    x = np.r_[0.0, 1e-5, 1e-4, np.geomspace(1e-5, 1e7, 3000)]
    b = bins_of(x)
    edge = 1e-4 * GROWTH ** b
    assert np.all(edge[x <= 1e6] >= x[x <= 1e6]) and np.all(edge[x >= 1e-4] <= x[x >= 1e-4] * GROWTH * (1 + 1e-9))
    assert list(ramp([2, 0, 3])) == [0, 1, 0, 1, 2] and len(ramp([])) == 0


def test_a_batch_arrives_as_its_states_one_by_one():
    rng = np.random.default_rng(2)
    a, b = Lateness(6, 0.1, 2.0), Lateness(6, 0.1, 2.0)
    for k in range(0, 80, 3):
        rows = rng.choice(6, size=4, replace=False)
        steps = k + rng.integers(0, 3, 4)
        a.arrive(rows, steps, steps * 0.1, k * 0.1 + 0.05)
        for i, st in zip(rows, steps):
            b.arrive(int(i), int(st), st * 0.1, k * 0.1 + 0.05)
    assert a.summary(80) == b.summary(80) and np.array_equal(a.hist, b.hist)


def test_silent_agent_owes_its_states_unless_a_fault_stopped_it():
    late = Lateness(3, 0.1, 1.0)
    for k in range(10):
        for i in range(3):
            if i == 0 or k < 5:
                late.arrive(i, k, k * 0.1, k * 0.1)
    late.excuse(2)                              # killed at step 5; agent 1 went silent on its own
    s = late.summary(9)
    assert s['states'] == 20 + 4                # agent 1 owes steps 5..8 (step 9 may be in flight)
    assert s['late'] == 4


def test_periods_skipped_before_a_process_first_ticks_are_owed():
    """The clock starts with every state of step 0 held: an agent whose first tick comes
    five periods late owes the four periods it skipped, as it would later in the run."""
    late = Lateness(2, 0.1, 1.0)
    late.start()
    for k in range(1, 10):
        late.arrive(0, k, k * 0.1, k * 0.1)
        if k >= 5:
            late.arrive(1, k, k * 0.1, k * 0.1 + (0.45 if k == 5 else 0.0))
    s = late.summary()
    assert s['states'] == 18 and s['arrived'] == 14
    assert s['late'] == 5                       # steps 1..4 skipped and step 5 itself late
