"""The pure input checks (swarm_ros.msg_checks, swarm_ros.runinfo): future and stale stamps,
publisher binding, the rate-limited rejection log, who may be signalled, the run id on the
lockstep messages."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from swarm_ros import protocol as P
from swarm_ros.layouts import AgentStates, BadMessage, NotFinite
from swarm_ros.msg_checks import (
    MAX_BARRIER_POINTS,
    RejectLog,
    Senders,
    check_barrier,
    check_values,
    may_signal,
    new_sender_tag,
)
from swarm_ros.runinfo import describe, one_run, parse_run, run_json, unknown_agent

ROW = {'agent_0': 0, 'agent_1': 1}
POSE = (1.0, 2.0, 0.0, 0.0, 0.0, 1.0)


def test_a_stamp_from_the_future_is_rejected_and_does_not_block_true_states():
    newest = {}
    why = check_values('agent_1', 500.0, POSE, 0.0, ROW, newest, now=10.0, tolerance=2.0)
    assert why is not None and why.kind == 'future-stamp' and 'future' in why
    assert check_values('agent_1', 11.5, POSE, 0.0, ROW, newest, now=10.0, tolerance=2.0) is None
    # without a clock (lockstep: the world checks the step instead) the old behaviour
    assert check_values('agent_1', 500.0, POSE, 0.0, ROW, newest) is None


def test_kinds_carry_no_values():
    newest = {'agent_0': (5.0, 1.0, 2.0, 0.0, 1.0)}
    cases = [check_values('ghost', 0.0, POSE, 0.0, ROW, newest),
             check_values('agent_0', 1.0, POSE, 0.0, ROW, newest),
             check_values('agent_0', 5.0, (9.0, 2.0, 0.0, 0.0, 0.0, 1.0), 0.0, ROW, newest),
             check_values('agent_1', float('nan'), POSE, 0.0, ROW, newest),
             check_values('agent_1', 1.0, (float('inf'), 2.0, 0.0, 0.0, 0.0, 1.0), 0.0, ROW, newest)]
    assert [c.kind for c in cases] == ['unknown-agent', 'past-stamp', 'duplicate', 'non-finite', 'non-finite']
    assert check_values('agent_0', 5.0, POSE, 0.0, ROW, newest) == 'repeat'


def test_a_name_is_bound_to_its_first_publisher():
    s = Senders()
    assert s.check('agent_3', 17.0) is None          # nothing bound yet
    s.accept('agent_3', 17.0)
    why = s.check('agent_3', 99.0)
    assert why.kind == 'second-publisher' and "'agent_3'" in why and '17' in why
    assert s.check('agent_3', 17.0) is None
    assert s.check('agent_3', None) is None          # unknown sender: not checked
    s.accept('agent_3', 99.0)                        # binding stays with the first
    assert s.check('agent_3', 99.0).kind == 'second-publisher'
    assert s.check('agent_4', 99.0) is None
    s.accept('agent_5', bytes(16))                   # gids (rclpy >= 9.1) work the same
    assert s.check('agent_5', bytes([1] * 16)).kind == 'second-publisher'
    tags = {new_sender_tag() for _ in range(100)}
    assert len(tags) > 95 and all(t >= 1 and t.is_integer() for t in tags)


class Logger:
    def __init__(self):
        self.lines = []

    def warning(self, line):
        self.lines.append(line)


def test_one_line_per_kind_rate_limited_and_bounded():
    clock = [0.0]
    log = Logger()
    r = RejectLog(log, interval=10.0, max_kinds=5, clock=lambda: clock[0])
    for i in range(10000):                       # a flood of different bad values within 10 s
        r('lambda', f'λ={i + 2.0} must be in [0, 1]')
        clock[0] += 0.0005
    assert r.count == 10000 and len(log.lines) == 1 and 'λ=2.0' in log.lines[0]
    clock[0] += 10.0
    r('lambda', 'λ=7.0 must be in [0, 1]')                 # the next one after 10 s: with the count
    assert len(log.lines) == 2 and '(9999 more of this kind in the last' in log.lines[1]
    r('steer', 's=nan not finite')                         # another kind: its own first line
    assert len(log.lines) == 3
    for i in range(1000):                    # ever new kinds: the table stays bounded
        r(f'kind{i}', 'x')
    assert len(r.kinds) <= 6                 # 5 + 'other'
    assert 'lambda 10001' in r.summary()


def test_barrier_polygons_are_bounded():
    assert check_barrier([(0.0, 0.0)] * (MAX_BARRIER_POINTS + 1)).kind == 'barrier-size'
    assert check_barrier([(0.0, float('nan'))]).kind == 'barrier-finite'
    assert check_barrier([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]) is None


def test_only_the_launchers_live_agent_child_may_be_signalled(tmp_path):
    """A live child of ours (we play the launcher) with the agent's command line may be signalled;
    a pid of another process, a dead pid, the wrong agent, a non-number: refused."""
    exe = tmp_path / 'swarm_agent'
    exe.write_text('import time\ntime.sleep(60)\n')
    p = subprocess.Popen([sys.executable, str(exe), '--ros-args', '-r', '__node:=agent', '-r', '__ns:=/agent_2'])
    try:
        me = os.getpid()
        deadline = time.monotonic() + 10       # the child's command line exists once it has exec'd
        while (b'__ns:=/agent_2' not in Path(f'/proc/{p.pid}/cmdline').read_bytes()
               and time.monotonic() < deadline):
            time.sleep(0.01)
        assert may_signal(p.pid, 'agent_2', me) is None
        assert 'not the agent process of agent_3' in may_signal(p.pid, 'agent_3', me)
        assert 'not a child' in may_signal(p.pid, 'agent_2', me + 1)
        assert 'not a child' in may_signal(os.getppid(), 'agent_2', me) or 'not the agent' in may_signal(
            os.getppid(), 'agent_2', me)
        assert 'not a number' in may_signal('x', 'agent_2', me)
        assert may_signal(1, 'agent_2', me) is not None
    finally:
        p.kill()
        p.wait()
    assert 'not running' in may_signal(p.pid, 'agent_2', os.getpid())


def test_sender_tag_rides_in_the_odometry():
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message, serialize_message
    raw = P.OdometryWriter('agent_2', tag=12345.0)(3, 0, 1.0, 2.0, 0.0, 1.0, 0.1)
    m = deserialize_message(raw, Odometry)
    assert m.pose.covariance[P.SENDER_TAG_INDEX] == 12345.0
    assert P.cdr_to_odometry_tagged(serialize_message(m))[-1] == 12345.0


def test_run_announcements():
    a = parse_run(run_json('aaaa', 'homotopy_global', 'lockstep', ['agent_0', 'agent_1'], 5.0))
    b = parse_run(run_json('bbbb', 'other', 'realtime', ['agent_0'], 6.0))
    assert parse_run('not json') is None and parse_run('{"run_id": 3}') is None
    assert describe(a) == 'run aaaa (homotopy_global, lockstep, 2 agents)'
    assert one_run({'aaaa': a}, 'swarm kill') == (a, None)
    run, err = one_run({'aaaa': a, 'bbbb': b}, 'swarm kill')
    assert run is None and 'aaaa' in err and 'bbbb' in err
    assert "unknown agent 'ghost'" in unknown_agent(a, 'ghost', 'swarm kill')
    assert unknown_agent(a, 'agent_1', 'swarm kill') is None


GOOD = {'run_id': 'a1', 'scenario': 's', 'mode': 'lockstep', 'agents': ['x'], 'since': 10.0}


@pytest.mark.parametrize('change, why', [
    (dict(since=None), 'since'), (dict(since='10'), 'since'), (dict(since=True), 'since'),
    (dict(run_id='x' * 33), 'run_id'), (dict(run_id='a b'), 'run_id'), (dict(run_id=7), 'run_id'),
    (dict(agents='x'), 'agents'), (dict(agents=[1]), 'agents'),
])
def test_an_announcement_without_what_the_give_way_rule_needs_is_ignored(change, why):
    """since (a finite number), run_id and the agents list: without one of them the
    announcement is not one (the world ignores it with one line: RunWatch.log)."""
    from swarm_ros.runinfo import run_error
    doc = {k: v for k, v in {**GOOD, **change}.items() if v is not None}
    assert why in run_error(json.dumps(doc)) and parse_run(json.dumps(doc)) is None
    assert 'not a finite number' in run_error(json.dumps(GOOD).replace('10.0', '1e999'))
    assert 'nested deeper' in run_error('[' * 100000)
    assert run_error(json.dumps(GOOD)) is None


def test_the_younger_of_two_runs_gives_way_before_its_start_only():
    """runinfo.give_way: an older run heard makes this one refuse to start; a younger one does
    not; before the start a second /world node alone is enough.  Once started a run never
    stops for an announcement, whatever it says."""
    from swarm_ros.runinfo import give_way
    old = dict(GOOD)
    young = dict(old, run_id='b2', since=30.0)
    assert give_way({}, 'me', 20.0, 1, False, '7') is None
    assert give_way({'b2': young}, 'me', 20.0, 1, True, '7') is None
    line = give_way({'a1': old}, 'me', 20.0, 1, False, '7')
    assert line.startswith('another swarm run is on ROS_DOMAIN_ID=7 (run a1 (s, lockstep, 1 agents))')
    assert 'refusing to start' in line
    assert give_way({'a1': old}, 'me', 20.0, 1, True, '7') is None
    assert give_way({'a1': dict(old, since=-1e300)}, 'me', 20.0, 2, True, '7') is None
    assert 'a second /world node' in give_way({}, 'me', 20.0, 2, False, '7')
    assert give_way({}, 'me', 20.0, 2, True, '7') is None
    assert give_way({'me': dict(old, run_id='me')}, 'me', 20.0, 1, False, '7') is None


def test_every_live_verb_decides_once_every_announcer_is_heard():
    """runinfo.heard_every_writer: the verbs wait until each /swarm/run writer in the graph
    has been heard (kept or ignored), then refuse alike where two runs are announced."""
    from swarm_ros.runinfo import heard_every_writer, verb_refusal
    a = parse_run(run_json('aaaa', 's', 'lockstep', ['agent_0'], 5.0))
    assert not heard_every_writer({'aaaa': a}, 0, 2)
    assert heard_every_writer({'aaaa': a}, 1, 2) and heard_every_writer({'aaaa': a}, 0, 1)
    b = dict(a, run_id='bbbb')
    for prog in ('swarm lambda', 'swarm steer', 'swarm kill', 'swarm pause', 'swarm drop', 'swarm partition'):
        assert verb_refusal({'aaaa': a, 'bbbb': b}, 0, 2, prog)[1].startswith(f'{prog}: 2 runs share')
        # a second writer never heard (a QoS the verb cannot read): refused too
        assert '2 writers announce runs' in verb_refusal({'aaaa': a}, 0, 2, prog)[1]
        assert verb_refusal({'aaaa': a}, 0, 1, prog) == (a, None)
        assert verb_refusal({'aaaa': a}, 1, 2, prog) == (a, None)         # one writer says garbage
    assert "unknown agent 'ghost'" in verb_refusal({'aaaa': a}, 0, 1, 'swarm kill', 'ghost')[1]


def test_join_refuses_another_scenario_and_agents_the_run_has():
    from swarm_ros.runinfo import join_error
    run = parse_run(run_json('aaaa', 's', 'lockstep', ['agent_0', 'agent_1', 'agent_2'], 5.0, 'h1', ['agent_2']))
    assert join_error(run, ['agent_2'], 'h1') is None
    assert 'another scenario' in join_error(run, ['agent_2'], 'h2')
    assert 'already has agent_0, agent_1' in join_error(run, ['agent_0', 'agent_1', 'agent_2'], 'h1')
    assert 'already has agent_0' in join_error(dict(run, remote=None), ['agent_0'], 'h1')


def batch(tag, index, step, x):
    """A one-agent /lockstep/agent_states, serialized."""
    return AgentStates(tag, [index], [step], np.array([[x], [0.0], [0.0], [1.0]]), [0.0]).to_cdr()


def test_agent_states_batches_are_checked_and_bound_to_their_process():
    from swarm_ros.msg_checks import ProcessSenders, check_agent_states
    good = np.array([[1.0, 2.0], [3.0, 4.0], [0.0, np.sin(0.3)], [1.0, np.cos(0.3)]])
    assert check_agent_states(np.array([0, 3]), good, 4) is None
    assert check_agent_states(np.array([0, 4]), good, 4).kind == 'unknown-agent'
    assert check_agent_states(np.array([1, 1]), good, 4).kind == 'duplicate'
    bad = good.copy()
    bad[2, 0] = 0.5
    assert check_agent_states(np.array([0, 3]), bad, 4).kind == 'not-planar'
    with pytest.raises(NotFinite, match='not finite'):
        AgentStates.from_cdr(batch(1.0, 0, 0, np.inf))
    with pytest.raises(NotFinite, match='not finite'):
        AgentStates.from_cdr(batch(np.nan, 0, 0, 0.0))
    with pytest.raises(BadMessage, match='whole number'):
        AgentStates.from_cdr(batch(1.0, -1, 0, 0.0))
    with pytest.raises(BadMessage, match='whole number'):
        AgentStates.from_cdr(batch(1.0, 0.5, 0, 0.0))
    s = ProcessSenders(4)
    ok, why = s.check(np.array([0, 3]), 5.0)
    assert ok.all() and why is None
    s.accept(np.array([0, 3]), 5.0)
    ok, why = s.check(np.array([2, 3]), 6.0)          # agent 3 is bound to process 5
    assert ok.tolist() == [True, False] and why.kind == 'second-publisher'
    s.accept(np.array([2]), 6.0)
    assert s.tag[[0, 2, 3]].tolist() == [5.0, 6.0, 5.0] and np.isnan(s.tag[1])


def test_refused_logs_reasons_and_drops_repeats_silently():
    from swarm_ros.msg_checks import reason, refused
    lines = []
    log = RejectLog(type('L', (), {'warning': staticmethod(lines.append)})())
    assert refused(log, None) is False and log.count == 0
    assert refused(log, 'repeat') is True and log.count == 0
    assert refused(log, reason('future-stamp', 'state of x from the future')) is True
    assert log.count == 1 and lines == ['rejected state of x from the future']


def test_a_step_time_no_stamp_can_hold_is_refused():
    """`check_step_time`, which the agents and the commander apply to each /lockstep/step."""
    from types import SimpleNamespace

    from swarm_ros.msg_checks import MAX_SIM_TIME, check_step_time
    for t in (0.0, 12.5, MAX_SIM_TIME - 1.0):
        assert check_step_time(SimpleNamespace(n=3, t=t)) is None
    for t in (float('nan'), -0.1, MAX_SIM_TIME, float('inf')):
        why = check_step_time(SimpleNamespace(n=3, t=t))
        assert why is not None and why.kind == 'step-time' and 'step 3' in why


def test_a_decision_from_the_future_or_of_no_sim_time_is_refused():
    """`check_decision_time`, which the realtime agents, containers and world apply to each
    /swarm/decision: a peer that copied the run id still cannot stamp one far ahead."""
    from types import SimpleNamespace

    from swarm_ros.msg_checks import MAX_SIM_TIME, check_decision_time
    for t in (0.0, 10.0, 12.0):
        assert check_decision_time(SimpleNamespace(n=7, t=t), 10.0, 2.0) is None
    why = check_decision_time(SimpleNamespace(n=7, t=1.0e6), 10.0, 2.0)
    assert why.kind == 'decision-future' and 't=1000000.000' in why and 'by more than 2 s' in why
    assert check_decision_time(SimpleNamespace(n=7, t=12.5), 10.0, 2.0).kind == 'decision-future'
    for t in (float('nan'), -0.1, MAX_SIM_TIME, float('inf')):
        why = check_decision_time(SimpleNamespace(n=7, t=t), 10.0, 2.0)
        assert why is not None and why.kind == 'decision-time' and 'step 7' in why


@pytest.mark.parametrize('k', [1, 3])
def test_a_3d_state_whose_frame_is_not_orthonormal_is_refused(k):
    """`check_natural_pose`: a frame [x y z] off by more than 1e-6 (a longer x, a tilted y), an
    index outside the roster or twice, is refused; a rotated frame passes (one state, or several)."""
    from swarm_core.model.natural import initial_frames
    from swarm_ros.msg_checks import check_natural_pose
    rng = np.random.default_rng(k)
    x, y, z = initial_frames(rng.normal(size=(k, 3)))
    pose = np.concatenate([rng.normal(size=(k, 3)).T, x.T, y.T, z.T])        # (12, K)
    index = np.arange(k)
    assert check_natural_pose(index, pose, 6) is None
    for row, by in ((3, 1e-5), (7, 2e-6), (11, -1e-4)):
        bad = pose.copy()
        bad[row, k - 1] += by
        assert check_natural_pose(index, bad, 6).kind == 'not-a-frame'
    assert check_natural_pose(index, pose + np.r_[np.zeros(3), np.full(9, 1e-9)][:, None], 6) is None
    assert check_natural_pose(index + 6, pose, 6).kind == 'unknown-agent'
    if k > 1:
        assert check_natural_pose(np.zeros(k, int), pose, 6).kind == 'duplicate'
