"""Realtime deaths are seen (no ROS): an agent silent for the world's ``missing_timeout`` wall
seconds is lost, as lockstep drops a missing agent: a ``lost`` event, out of the view, and its
trajectory not held where it died.  The run of a SIGKILLed agent process:
tests/world/ros/test_realtime_lost.py."""
from __future__ import annotations

import numpy as np
import pytest

from swarm_core.engine.trajectory import TrajectoryRecorder
from swarm_core.faults.agents import Fault, FaultTimeline
from swarm_ros.msg_checks import NewestStates
from swarm_world.parameters import MODE_PARAMETERS
from swarm_world.realtime import RealtimeSchedule, SilenceWatch, newest_view

NAMES = ['a', 'b', 'c']
DT = 0.5
ALL = np.ones(3, bool)


def test_an_agent_silent_for_the_timeout_is_found_once_the_others_are_not():
    w = SilenceWatch(3, timeout=10.0)
    assert w.silent(100.0, ALL)[0].size == 0               # before the start: nobody
    w.start(100.0)
    for now in np.arange(100.0, 115.0, 0.01):              # a and c keep talking, b died at 100
        w.heard(np.array([0, 2]), now)
        gone, quiet = w.silent(now, ALL)
        if gone.size:
            break
    assert gone.tolist() == [1] and 110.0 < now < 110.1 and quiet == pytest.approx(now - 100.0)


def test_a_frozen_agent_is_not_silent_and_counts_anew_when_it_resumes():
    w = SilenceWatch(3, timeout=10.0)
    w.start(0.0)
    frozen = np.array([True, False, True])                 # b frozen by a fault from t = 0 to 50
    for now in np.arange(0.0, 50.0, 1.0):
        w.heard(np.array([0, 2]), now)
        assert w.silent(now, frozen)[0].size == 0
    for now in np.arange(50.0, 60.0, 1.0):                 # resumed: a new silence from 50 on
        w.heard(np.array([0, 2]), now)
        assert w.silent(now, ALL)[0].size == 0
    w.heard(np.array([0, 2]), 60.5)
    assert w.silent(60.5, ALL)[0].tolist() == [1]


def test_a_world_that_stood_still_blames_nobody():
    """A world whose own ticks stopped for 30 s (its process starved or stopped) did not hear
    anyone in that time: nobody is lost for it."""
    w = SilenceWatch(3, timeout=10.0)
    w.start(0.0)
    w.heard(np.arange(3), 1.0)
    assert w.silent(1.0, ALL)[0].size == 0
    assert w.silent(31.0, ALL)[0].size == 0                # the gap is not their silence
    for now in np.arange(31.0, 40.95, 0.1):
        assert w.silent(now, ALL)[0].size == 0
    assert w.silent(41.05, ALL)[0].tolist() == [0, 1, 2]   # ... but a silence after it is


def test_lost_agents_get_one_event_each_from_the_step_after_their_newest_state():
    s = RealtimeSchedule(NAMES, FaultTimeline([], NAMES, DT), {})
    last_t = np.array([7.0, 3.0, 7.0])
    acts, since = s.lose(np.array([1]), last_t, DT, 10.2)
    assert acts == [('event', dict(t=3.5, step=7, kind='lost', agent='b', silent_for=10.2))]
    assert since == {1: 7} and s.faults.dead.tolist() == [False, True, False]
    # a lost agent is dead for the faults too: a fault on it later does nothing
    s.add_fault(Fault(0.0, 'kill', 'b'))
    assert s.faults_due(20) == []
    # the last ones: the run cannot go on
    acts, _ = s.lose(np.array([0, 2]), last_t, DT, 11.0)
    assert [a[0] for a in acts] == ['event', 'event', 'fail']
    assert 'no state from a, c for 11.0 s (lost)' in acts[-1][1] and 'no agent is left' in acts[-1][1]


def test_the_view_leaves_the_dead_out():
    heard = NewestStates(3)
    for i in range(3):
        heard.put(i, 1.0, (10.0 * i, 0.0, 0.0, 1.0), 0.0)
    pos, _ = newest_view(heard, np.array([True, False, True]))
    assert pos[:, 0].tolist() == [0.0, 20.0]


def test_a_lost_agents_trajectory_is_not_held_where_it_died():
    rec = TrajectoryRecorder(NAMES, 10, DT, np.zeros(3), realtime=True)
    for k in range(11):
        alive = [0, 2] if k > 3 else [0, 1, 2]
        rec.record_realtime(alive, np.full(len(alive), k), [(k, i, 0.0, 1.0) for i in alive],
                            np.full(len(alive), 0.01), 0.0, np.zeros(3, bool))
    rec.mark_lost(1, 4)
    traj = rec.trajectory()
    assert np.isfinite(traj.r[:4, 1]).all() and np.isnan(traj.r[4:, 1]).all()
    assert np.isnan(traj.theta[4:, 1]).all() and np.isfinite(traj.r[:, [0, 2]]).all()


def test_realtime_takes_the_missing_timeout_of_lockstep():
    assert 'missing_timeout' in MODE_PARAMETERS['realtime'] and 'missing_timeout' in MODE_PARAMETERS['lockstep']
