"""The Python API (swarm_tools.api) without a run: the `swarm run` argv it spells, the checks
before a command is sent, the process groups it finds, and its pytest plugin's entry point.
The API against real runs, the example test and the notebook: tests/tools/ros/test_api_runs.py."""
from __future__ import annotations

import subprocess
import sys

import pytest


def test_run_argv_spells_the_swarm_run_options():
    from swarm_tools.api import run_argv
    assert run_argv('s.yaml', mode='realtime', rtf=4, duration=30, out='o', agents_per_process=6,
                    seed=3, no_figure=True, in_process=False, record=None) == [
        's.yaml', '--mode', 'realtime', '--rtf', '4', '--duration', '30', '--out', 'o',
        '--agents-per-process', '6', '--seed', '3', '--no-figure']


def test_partition_groups_are_checked_before_sending():
    from swarm_tools.live.client import check_lambda, check_partition
    assert check_partition([('agent_0', ' agent_1'), ['agent_2']]) == [['agent_0', 'agent_1'], ['agent_2']]
    for bad, word in (([[]], 'empty group'), ([['a', 'b'], ['b']], "'b' is in more than one group")):
        with pytest.raises(ValueError, match=word):
            check_partition(bad)
    for value, ramp, word in ((1.5, 1.0, 'λ=1.5'), (0.5, -1.0, 'ramp')):
        with pytest.raises(ValueError, match=word):
            check_lambda(value, ramp)


def test_session_pids_finds_a_started_process_group():
    from swarm_tools.api import session_pids
    p = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(30)'], start_new_session=True)
    try:
        assert session_pids(p.pid) == [p.pid]
    finally:
        p.kill()
        p.wait()
    assert session_pids(p.pid) == []


def test_plugin_is_installed_as_a_pytest11_entry_point():
    from importlib.metadata import entry_points
    assert [e.value for e in entry_points(group='pytest11') if e.name == 'swarm_tools'] == [
        'swarm_tools.pytest_plugin']


class _LaggingRun:
    """A run whose ``/clock`` is far ahead of its metrics: a reliable stream held back until DDS
    resends a lost sample (seen in a fast lockstep run: clock at t = 10.9, metrics at t = 2)."""

    proc = None
    running = True
    states = None

    def __init__(self, clock, metric_times):
        self.t, self._times = clock, list(metric_times)

    def metrics(self):
        t = self._times.pop(0) if len(self._times) > 1 else self._times[0]
        return {'t': t, 'clusters': 1}


def test_wait_until_counts_sim_time_on_the_samples_not_the_clock():
    from swarm_tools.api import Swarm, WaitTimeout
    # the clock has run past the timeout; the samples have not
    lagging = _LaggingRun(clock=11.0, metric_times=[0.0, 2.0, 2.0, 2.0, 3.0, 4.0])
    assert Swarm.wait_until(lagging, lambda m: m['t'] >= 3, timeout=10, wall_timeout=5)['t'] == 3.0
    late = _LaggingRun(clock=0.0, metric_times=[1.0, 5.0, 10.5])
    with pytest.raises(WaitTimeout, match=r'after 10 sim s \(t 0.00 → 10.50\)'):
        Swarm.wait_until(late, lambda m: m['clusters'] >= 2, timeout=10, wall_timeout=5)
    stalled = _LaggingRun(clock=0.0, metric_times=[1.0])
    with pytest.raises(WaitTimeout, match='samples stalled at t = 1.0'):
        Swarm.wait_until(stalled, lambda m: m['clusters'] >= 2, timeout=10, wall_timeout=0.2)


def test_a_run_that_ended_before_its_clock_was_heard_is_a_finished_run():
    """`Swarm.start` of a short run: ``swarm run`` may finish before the client hears its clock.
    Exit 0 after its start and its 'done' line is a finished run; an exit before it started,
    or a failure, is not."""
    from swarm_tools.api import finished_run
    log = ['swarm run: run 1a2b3c4d: six seed 0: 6 agents, lockstep, 8 processes\n',
           '[world] finished t=60 (600 steps) in 1.2 s\n', 'swarm run: done in 4.1 s; final clusters 1\n']
    assert finished_run(log, 0, None) == {'run_id': '1a2b3c4d'}
    heard = {'run_id': '1a2b3c4d', 'agents': ['agent_0']}
    assert finished_run(log, 0, heard) is heard
    assert finished_run(log, 1, None) is None                       # it failed
    assert finished_run(log[:2], 0, None) is None                   # no 'done' line
    assert finished_run(['swarm run: bad.yaml: not found\n'], 0, None) is None
