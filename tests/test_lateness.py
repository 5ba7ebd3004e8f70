"""How late a realtime run's states come (`swarm_world.lateness`), without ROS."""
from swarm_world.lateness import ON_TIME_TARGET, Lateness, behind_line, timing_line


def test_on_time_run():
    late = Lateness(2, 0.05, 2.0)
    for k in range(100):
        for i in range(2):
            late.arrive(i, k, k * 0.05, k * 0.05 + 0.004)         # 4 ms sim = 2 ms wall at rtf 2
    s = late.summary(99)
    assert s['on_time_share'] == 1.0 and s['states'] == 200 and s['late'] == 0
    assert s['lateness_p50_ms'] == s['lateness_p99_ms'] == 2.5      # the 2.0-2.5 ms bin's upper edge
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
    assert s['lateness_p50_ms'] == 10.5 and s['lateness_p99_ms'] is None     # p99 among the missed
    assert abs(s['achieved_rtf'] - 150 / 199) < 1e-12
    line = behind_line(s, 1.0)
    assert line.startswith('fell behind: 50.3% of states on time') and f'{ON_TIME_TARGET:.0%}' in line
    assert 'beyond measure' in timing_line(s)


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
