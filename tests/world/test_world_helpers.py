"""The world's pure helpers, without ROS: parsing its inputs (swarm_world.parsing), the
realtime schedule (swarm_world.realtime), per-step checks and progress
(swarm_world.observe) and the wall-clock decisions (swarm_world.wallclock)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from swarm_core.analysis import metrics as M
from swarm_core.faults.agents import Fault, FaultTimeline
from swarm_core.model.frenet import quaternion_from_heading
from swarm_ros.msg_checks import NewestStates
from swarm_world.markers import markers_every
from swarm_world.observe import Observer
from swarm_world.parsing import fault_request, format_points, leader_flags, parse_geometry, parse_point, parse_points
from swarm_world.realtime import (
    CLOCK_TICK_MAX,
    CLOCK_TICK_MIN,
    RealtimeSchedule,
    clock_tick,
    decision_valid,
    newest_view,
)
from swarm_world.wallclock import StallWatch, StartWatch

NAMES = ['a', 'b', 'c']
DT = 0.5


# ---------------------------------------------------------------- inputs
def test_points_parse_and_format_round_trip_exactly():
    assert parse_point('  ') is None and parse_points('') is None
    assert parse_point('1.5, -2').tolist() == [1.5, -2.0]
    pts = parse_points('0,0; 1,0;0.1,0.3;')
    assert pts.shape == (3, 2)
    assert np.array_equal(parse_points(format_points(pts)), pts)
    assert format_points(None) == ''
    assert format_points(np.array([0.1, 2.0])) == '0.1,2.0'


@pytest.mark.parametrize('text', ['1', '1,2,3', 'nan,0', '1,inf', 'x,1'])
def test_bad_points_are_refused(text):
    with pytest.raises(ValueError):
        parse_point(text)


def test_leader_flags_mark_known_names_and_report_the_others():
    row = {nm: i for i, nm in enumerate(NAMES)}
    flags, unknown = leader_flags(' c, x ,a,', row)
    assert flags.tolist() == [True, False, True] and unknown == ['x']
    flags, unknown = leader_flags('', row)
    assert flags.tolist() == [False] * 3 and unknown == []


def test_fault_request_builds_a_live_fault_or_says_why_not():
    f = fault_request(json.dumps({'kind': 'freeze', 'agent': 'b', 'for': 2.5}))
    assert (f.kind, f.agent, f.duration, f.source) == ('freeze', 'b', 2.5, 'live')
    assert fault_request('{"kind": "kill", "agent": "leader:0"}').agent == 'leader:0'
    for bad, err in [('{"kind": "melt", "agent": "a"}', ValueError),
                     ('{"kind": "freeze", "agent": "a"}', ValueError),
                     ('{"kind": "freeze", "agent": "a", "for": "nan"}', ValueError),
                     ('{"agent": "a"}', KeyError), ('not json', ValueError), ('[1]', TypeError)]:
        with pytest.raises(err):
            fault_request(bad)


# ---------------------------------------------------------------- realtime
def schedule(faults=(), slots=None, comms=(), view_every=0):
    return RealtimeSchedule(NAMES, FaultTimeline(list(faults), NAMES, DT), slots or {}, comms, view_every)


def test_realtime_sends_each_radio_event_once_when_its_step_is_passed():
    s = schedule(comms=[(2, {'kind': 'drop'}), (2, {'kind': 'x'}), (5, {'kind': 'heal'})])
    assert s.comms_due(1) == []
    assert s.comms_due(3) == [('comms', 3, {'kind': 'drop'}), ('comms', 3, {'kind': 'x'})]
    assert s.comms_due(4) == []
    assert s.comms_due(9) == [('comms', 9, {'kind': 'heal'})]
    assert s.comms_due(10) == []


def test_realtime_applies_the_faults_of_every_step_passed_with_their_signals():
    # freeze b at t=0.5 (step 1) for 1 s (2 steps), kill leader slot 0 at t=1.0 (step 2)
    s = schedule([Fault(0.5, 'freeze', 'b', 1.0), Fault(1.0, 'kill', 'leader:0')], slots={0: 2})
    acts = s.faults_due(0)
    assert acts == []
    acts = s.faults_due(2)                                   # steps 1 and 2 at once
    assert [(a[0], a[1]['kind'], a[1]['agent']) if a[0] == 'event' else a for a in acts] == [
        ('event', 'freeze', 'b'), ('signal', 1, 'stop'), ('event', 'kill', 'c'), ('signal', 2, 'kill')]
    acts = s.faults_due(3)
    assert [a[0] for a in acts] == ['event', 'signal'] and acts[0][1]['kind'] == 'resume'
    assert acts[1] == ('signal', 1, 'cont')
    assert s.faults.alive.tolist() == [True, True, False]


def test_realtime_live_fault_lands_on_the_next_step_and_slots_follow_the_commander():
    s = schedule()
    s.faults_due(4)
    assert s.add_fault(Fault(0.0, 'kill', 'leader:1', source='live')) == 5
    s.on_event({'kind': 'leaders_chosen', 'slots': ['c', 'a']})
    assert s.slots == {0: 2, 1: 0}
    acts = s.faults_due(5)
    assert acts[0][1]['agent'] == 'a' and acts[1] == ('signal', 0, 'kill')


def test_realtime_leader_fault_waits_for_the_commanders_choice_heard_late():
    """Leaders are chosen by rule by step 2; 'leader:1' is killed at step 4, but the
    commander's leaders_chosen event reaches the world after the clock passed step 4 (a loaded
    machine).  The kill waits for it (and the freeze of b after it waits too), then lands on
    the agent in slot 1 at its own step."""
    faults = FaultTimeline([Fault(2.0, 'kill', 'leader:1'), Fault(2.5, 'freeze', 'b', 1.0)], NAMES, DT)
    s = RealtimeSchedule(NAMES, faults, {}, choose_step=2, choice_wait=5.0)
    assert s.faults_due(6, now=10.0) == []                   # held: the choice is in flight
    assert s.faults_due(7, now=12.0) == []
    s.on_event({'kind': 'leaders_chosen', 'slots': ['c', 'a']})
    acts = s.faults_due(7, now=12.5)
    events = [a[1] for a in acts if a[0] == 'event']
    assert [(e['kind'], e['agent'], e['step']) for e in events] == [('kill', 'a', 4), ('freeze', 'b', 5),
                                                                  ('resume', 'b', 7)]
    assert ('signal', 0, 'kill') in acts


def test_realtime_leader_fault_is_skipped_when_the_choice_never_comes_or_has_no_such_slot():
    s = RealtimeSchedule(NAMES, FaultTimeline([Fault(2.0, 'kill', 'leader:1')], NAMES, DT), {},
                         choose_step=2, choice_wait=5.0)
    assert s.faults_due(4, now=0.0) == []
    acts = s.faults_due(5, now=5.0)                         # waited its 5 wall s: skipped
    assert [a[1]['kind'] for a in acts] == ['fault_skipped']
    # heard, with one slot only: skipped at once
    s = RealtimeSchedule(NAMES, FaultTimeline([Fault(2.0, 'kill', 'leader:1')], NAMES, DT), {},
                         choose_step=2, choice_wait=5.0)
    s.on_event({'kind': 'leaders_chosen', 'slots': ['c']})
    assert [a[1]['kind'] for a in s.faults_due(4, now=0.0)] == ['fault_skipped']
    # before the choice step nothing waits (fixed leaders: never)
    s = RealtimeSchedule(NAMES, FaultTimeline([Fault(0.5, 'kill', 'leader:0')], NAMES, DT), {},
                         choose_step=2)
    assert [a[1]['kind'] for a in s.faults_due(1, now=0.0)] == ['fault_skipped']


def test_realtime_view_is_due_once_per_period_and_never_with_zero():
    s = schedule(view_every=10)
    assert [k for k in [0, 3, 9, 10, 15, 31, 32] if s.view_due(k)] == [0, 10, 31]
    assert not any(schedule(view_every=0).view_due(k) for k in range(30))


@pytest.mark.parametrize('dt, rtf', [(0.1, 5), (0.1, 1), (0.1, 3), (0.1, 20), (0.05, 0.5), (0.1, 10)])
def test_realtime_clock_ticks_divide_the_control_period(dt, rtf):
    """Counted from the run's start, the world's ticks fall on every period boundary: a whole
    number of ticks per period's wall time, as few as keep them at most CLOCK_TICK_MAX apart."""
    tick, period = clock_tick(dt, rtf), dt / rtf
    m = period / tick
    assert abs(m - round(m)) < 1e-9 and tick <= CLOCK_TICK_MAX + 1e-12
    assert round(m) == 1 or period / (round(m) - 1) > CLOCK_TICK_MAX


@pytest.mark.parametrize('dt, rtf', [(0.1, 40), (0.1, 30), (0.1, 1000), (0.01, 5)])
def test_realtime_clock_ticks_of_a_short_period_span_whole_periods(dt, rtf):
    """A period shorter than CLOCK_TICK_MIN: a tick every few whole periods, on boundaries."""
    tick, period = clock_tick(dt, rtf), dt / rtf
    k = tick / period
    assert abs(k - round(k)) < 1e-9 and CLOCK_TICK_MIN - 1e-12 <= tick < CLOCK_TICK_MIN + period


def test_realtime_clock_tick_of_the_record_case():
    assert clock_tick(0.1, 5) == pytest.approx(0.01)        # two ticks a 20 ms period
    assert clock_tick(0.1, 20) == pytest.approx(0.005)      # one a period, not one every two


def test_newest_view_samples_in_roster_order():
    qz, qw = quaternion_from_heading(0.5)
    heard = NewestStates(len(NAMES))
    heard.put(NAMES.index('c'), 1.0, (5.0, 6.0, qz, qw), 0.0)
    heard.put(NAMES.index('a'), 0.9, (1.0, 2.0, 0.0, 1.0), 0.0)
    pos, theta = newest_view(heard)
    assert pos.tolist() == [[1.0, 2.0], [5.0, 6.0]]
    assert theta == pytest.approx([0.0, 0.5])


# ---------------------------------------------------------------- observe
def test_observer_counts_collisions_and_intruders():
    obs = Observer(collision_distance=0.5, cutoff_radius=4.0)
    barrier = M.Barrier(np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]]))
    pos = np.array([[1.0, 1.0], [1.2, 1.0], [10.0, 10.0]])        # a and b inside, 0.2 apart
    md, complaints = obs.check(1.5, pos, NAMES, barrier)
    assert md == pytest.approx(0.2)
    assert [k for k, _ in complaints] == ['collision', 'intrusion']
    assert complaints[1][1].endswith('at t=1.50 by a, b')
    assert (obs.collisions, obs.intrusions) == (1, 2)
    md, complaints = obs.check(2.0, pos + [20.0, 0.0] * np.arange(3)[:, None], NAMES, None)
    assert complaints == [] and (obs.collisions, obs.intrusions) == (1, 2)


def test_progress_line_is_paced_in_sim_time():
    obs = Observer(0.01, cutoff_radius=4.0, progress_every=10.0)
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [50.0, 0.0]])
    line = obs.progress(0.0, pos, 1.0, 0.25, rate=123.4)
    assert line == '[world] t=    0.00  clusters=2  λ=0.250  min_dist=1.000  (123 steps/s)'
    assert obs.progress(9.9, pos, 1.0, 0.25) is None
    assert obs.progress(10.0, pos, 1.0, 0.25).endswith('min_dist=1.000')
    assert Observer(0.01, 4.0, progress_every=0.0).progress(0.0, pos, 1.0, 0.0) is None


# ---------------------------------------------------------------- wall clock
def test_start_waits_for_everyone_then_times_out():
    w = StartWatch(100.0, 3, start_timeout=30.0)
    # relay readers: one per agent process and the commander
    everyone = dict(states=True, relay_readers=4, commander_ready=True, clock_readers=4)
    assert w.decide(101.0, **everyone) == 'start'
    for missing in [dict(states=False), dict(relay_readers=3), dict(commander_ready=False)]:
        assert w.decide(101.0, **{**everyone, **missing}) is None
        assert w.decide(131.0, **{**everyone, **missing}) == 'time_out'


def test_start_waits_a_bounded_time_for_the_recorder():
    w = StartWatch(0.0, 3, start_timeout=100.0, wait_for_recorder=True, recorder_wait=5.0)
    everyone = dict(states=True, relay_readers=4, commander_ready=True)
    # /clock readers: the recorder (the lockstep agents and commander take their time from the steps)
    assert w.decide(1.0, **everyone, clock_readers=0) is None          # no recorder yet
    assert w.decide(5.9, **everyone, clock_readers=0) is None
    assert w.decide(6.0, **everyone, clock_readers=0) == 'start_without_recorder'
    w = StartWatch(0.0, 3, start_timeout=100.0, wait_for_recorder=True, recorder_wait=5.0)
    assert w.decide(1.0, **everyone, clock_readers=1) == 'start'


def test_stall_watch_drops_then_gives_up_and_repeats_between():
    w = StallWatch(0.0, missing_timeout=10.0, step_timeout=30.0, stall_timeout=2.0)
    assert w.give_up_after == 30.0
    waiting = dict(complete=False, can_repeat=True)
    assert w.decide(1.0, **waiting) is None
    assert w.decide(2.5, **waiting) == 'repeat'
    assert w.decide(3.0, **waiting) is None                          # the repeat counts as progress
    w.progressed(9.0)
    assert w.decide(10.5, **waiting) == 'drop'
    assert w.decide(10.5, **{**waiting, 'complete': True}) is None    # complete: nothing to drop
    assert w.decide(10.5, complete=True, can_repeat=False) is None
    assert w.decide(30.5, complete=True, can_repeat=True) == 'give_up'
    w.stepped(30.0)
    w.progressed(30.0)
    assert w.decide(31.0, complete=True, can_repeat=True) is None
    assert StallWatch(0.0, missing_timeout=10.0, step_timeout=1.0, stall_timeout=2.0).give_up_after == 30.0


def test_geometry_parameters_change_only_what_is_given():
    t0, b0 = np.array([1.0, 2.0]), None
    t, b = parse_geometry({'barrier': '0,0;1,0;0,1'}, t0, b0)
    assert t is t0 and b.shape == (3, 2)
    t, b = parse_geometry({'target': ''}, t0, b)
    assert t is None and b.shape == (3, 2)
    with pytest.raises(ValueError):
        parse_geometry({'target': '1,2,3'}, t0, b0)


def test_decision_valid_needs_lambda_in_range_finite_steering_and_one_flag_each():
    ok = dict(lam=0.5, flags=[0, 1, 0], steering=[0.0, 0.1, 0.0], n=3)
    assert decision_valid(**ok)
    for bad in [dict(lam=1.5), dict(lam=float('nan')), dict(flags=[0, 1]), dict(steering=[0.0, float('inf'), 0.0])]:
        assert not decision_valid(**{**ok, **bad})


def test_markers_of_a_big_swarm_go_out_less_often():
    assert [markers_every(n) for n in (1, 6, 100, 101, 1000, 1500)] == [1, 1, 1, 2, 10, 15]


def test_markers_bytes_decode_to_the_arrows_trails_target_and_barrier():
    """The serialized /world/markers decode (rclpy) to what they say: an arrow per agent at
    its pose (leaders gold), its trail of the last `trail_length` views, the target and the
    barrier; rclpy writes the decoded message back to as many bytes (the same layout)."""
    from rclpy.serialization import deserialize_message, serialize_message
    from visualization_msgs.msg import Marker, MarkerArray

    from swarm_world.markers import LEADER_COLOUR, PALETTE, Trails, markers_message
    trails = Trails(4, 2)
    rng = np.random.default_rng(3)
    leaders = np.array([False, True, False, False])
    for view in range(3):
        idx = np.array([0, 1, 3]) if view else np.arange(4)      # agent 2 gone after the first view
        pos, theta = rng.normal(size=(len(idx), 2)), rng.normal(size=len(idx))
        raw = markers_message(1.5 * view, pos, theta, np.arange(len(idx)), idx, leaders, trails, (1.0, -2.0),
                              [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)])
        ma = deserialize_message(raw, MarkerArray)
        assert len(serialize_message(ma)) == len(raw)
        arrows, tr = ma.markers[0:-2:2], ma.markers[1:-2:2]
        assert [(m.ns, m.id, m.type) for m in arrows] == [('agents', int(i), Marker.ARROW) for i in idx]
        assert [(m.ns, m.id, m.type) for m in tr] == [('trails', int(i), Marker.LINE_STRIP) for i in idx]
        for row, (a, t) in enumerate(zip(arrows, tr)):
            assert (a.header.frame_id, a.header.stamp.sec, a.header.stamp.nanosec) == ('world', int(1.5 * view),
                                                                                       (view % 2) * 500_000_000)
            assert (a.pose.position.x, a.pose.position.y) == tuple(pos[row])
            assert a.pose.orientation.z == pytest.approx(np.sin(theta[row] / 2))
            assert a.pose.orientation.w == pytest.approx(np.cos(theta[row] / 2))
            want = LEADER_COLOUR if leaders[idx[row]] else PALETTE[row]
            assert (a.color.r, a.color.g, a.color.b, a.color.a) == pytest.approx((*want, 1.0))
            assert (t.points[-1].x, t.points[-1].y, t.color.a) == (pos[row, 0], pos[row, 1], pytest.approx(0.6))
            assert len(t.points) == min(view + 1, 2)          # the trail keeps the last 2
        target, barrier = ma.markers[-2:]
        assert (target.type, target.pose.position.x, target.pose.position.y) == (Marker.SPHERE, 1.0, -2.0)
        assert [(p.x, p.y) for p in barrier.points] == [(0, 0), (1, 0), (0, 1), (0, 0)]
    assert [(p.x, p.y) for p in tr[0].points] == [tuple(trails.trail(0)[k, :2]) for k in range(2)]
