"""`run_clock.ClockGuard`: which values of its run's clock (/swarm/clock) a node takes.  The
first value binds the writer (its tag) and the rate (rtf); then a second writer, a time that
goes back and a jump ahead of what the run can do are refused, each with its own kind."""
from __future__ import annotations

import math

import pytest

from swarm_ros.layouts import RunClock
from swarm_ros.run_clock import AHEAD, ClockGuard

TAG = 1234.0


def taken(guard, t, wall, tag=TAG, rtf=2.0):
    """Whether ``guard`` takes the value ``t`` received at ``wall`` (and takes it)."""
    c = RunClock(tag, rtf, t)
    why = guard.check(c, wall)
    if why is None:
        guard.take(c, wall)
    return why.kind if why is not None else True


def test_the_run_clock_goes_at_the_runs_rate_and_no_faster():
    g = ClockGuard()
    assert taken(g, 100.0, 50.0) is True                   # the first value: any time (a node that joins late)
    assert taken(g, 100.05, 50.02) is True
    assert taken(g, 100.05, 50.03) is True                 # the same time again
    assert taken(g, 120.0, 60.0) is True                   # 10 wall s at rtf 2
    assert taken(g, 120.0 + 2.0 * AHEAD, 60.0) is True     # as late as its first value could have come
    assert taken(g, 1120.0, 60.1) == 'clock-jump'          # 1000 s ahead
    assert taken(g, 0.5, 60.2) == 'clock-past'             # stuck in the past
    assert taken(g, 119.0, 60.2) == 'clock-past'
    assert g.t == 120.0 + 2.0 * AHEAD


def test_a_second_writer_and_times_of_no_run_are_refused():
    g = ClockGuard()
    assert taken(g, 1.0, 0.0) is True
    assert taken(g, 1.1, 0.05, tag=TAG + 1) == 'clock-writer'
    assert taken(g, 1.1, 0.05, rtf=1000.0) is True         # the rate is the first value's
    assert taken(g, 1.0 + 2.0 * (10.0 + AHEAD) + 0.1, 10.0, rtf=1000.0) == 'clock-jump'
    for t, rtf in ((math.nan, 2.0), (-1.0, 2.0), (math.inf, 2.0), (2.0 ** 31, 2.0), (5.0, 0.0), (5.0, -1.0)):
        assert ClockGuard().check(RunClock(TAG, rtf, t), 0.0).kind == 'clock-time', (t, rtf)


@pytest.mark.parametrize('t', [0.0, 3.5])
def test_the_reasons_say_what_was_refused(t):
    g = ClockGuard()
    g.take(RunClock(TAG, 4.0, t), 10.0)
    jump = g.check(RunClock(TAG, 4.0, t + 1000.0), 10.1)
    assert f't={t + 1000.0:.3f}' in jump and 'ahead of what the run can do' in jump and 'rtf 4' in jump
    assert 'second writer' in g.check(RunClock(TAG + 1, 4.0, t), 10.1)
    if t:
        assert 'never goes back' in g.check(RunClock(TAG, 4.0, t - 0.5), 10.1)
