"""No message ends a node (`msg_checks.guarded`, `guard_subscriptions`), and a peer that
announces run after run does not grow a `runinfo.RunWatch` without end (no ROS graph)."""
from __future__ import annotations

import inspect
import json
from types import SimpleNamespace

import pytest

from swarm_ros.msg_checks import RejectLog, guard_subscriptions, guarded
from swarm_ros.runinfo import MAX_RUNS, RunWatch


class Lines:
    def __init__(self):
        self.lines = []

    def warning(self, line):
        self.lines.append(line)


class Fatal(ValueError):
    pass


def test_a_callback_that_raises_is_counted_logged_once_and_the_node_goes_on():
    log = Lines()
    reject = RejectLog(log, clock=lambda: 0.0)
    got = []

    def on_message(msg):
        got.append(1 / msg)          # 0: ZeroDivisionError, 'x': TypeError, as a malformed message would
        if msg == 7:
            raise Fatal('a law that failed')
    cb = guarded(on_message, reject, '/t')
    for msg in (0, 'x', 0, 2):
        assert cb(msg) is None
    assert got == [0.5]
    assert reject.count == 3 and set(reject.kinds) == {'unreadable:/t'}
    assert len(log.lines) == 1 and log.lines[0].startswith('rejected /t: a message this node cannot read, '
                                                           'dropped (ZeroDivisionError')
    assert log.lines[0].endswith('raised at test_guard.py:33 in on_message)')     # where to look
    with pytest.raises(Fatal):                          # an error of the run itself goes on to the executor
        guarded(on_message, reject, '/t', passes=(Fatal,))(7)


def test_the_guard_keeps_the_signature_rclpy_reads():
    """rclpy passes the message info only to a callback that takes two arguments (read from
    its signature, `__signature__` included, as the recorder's callback sets it)."""
    reject = RejectLog(Lines())

    class Node:
        def on_msg(self, msg):
            return msg
    one = guarded(Node().on_msg, reject, '/a')
    two = guarded(lambda data, info: (data, info), reject, '/b')
    sig = inspect.Signature([inspect.Parameter(n, inspect.Parameter.POSITIONAL_ONLY) for n in ('data', 'info')])
    raw = lambda *args: args
    raw.__signature__ = sig
    three = guarded(raw, reject, '/c')
    inspect.signature(one).bind(object())
    with pytest.raises(TypeError):
        inspect.signature(one).bind(object(), object())
    inspect.signature(two).bind(object(), object())
    assert inspect.signature(three) == sig
    assert one(5) == 5 and two(1, 2) == (1, 2) and three(1, 2) == (1, 2)
    assert guarded(one, reject, '/a') is one                   # guarded once


def test_guard_subscriptions_guards_each_reader_once():
    reject = RejectLog(Lines())
    subs = [SimpleNamespace(topic_name='/clock', callback=lambda m: 1 / m),
            SimpleNamespace(topic_name='/swarm/events', callback=lambda m: json.loads(m))]
    after_sets = []
    node = SimpleNamespace(subscriptions=subs, add_post_set_parameters_callback=after_sets.append)
    assert guard_subscriptions(node, reject) == 2
    assert guard_subscriptions(node, reject) == 0
    subs[0].callback(0)
    subs[1].callback('[' * 100_000)        # RecursionError: no ValueError, yet no end either
    assert reject.kinds.keys() == {'unreadable:/clock', 'unreadable:/swarm/events'}
    # a reader made by a parameter set (rclpy's /clock reader after use_sim_time := true) is
    # guarded by the post-set callback hooked once
    assert len(after_sets) == 1
    subs.append(SimpleNamespace(topic_name='/late', callback=lambda m: 1 / m))
    after_sets[0]([])
    subs[2].callback(0)
    assert 'unreadable:/late' in reject.kinds


def test_run_watch_keeps_at_most_max_runs():
    node = SimpleNamespace(create_subscription=lambda *a, **k: None)
    said = []
    watch = RunWatch(node, log=said.append)

    def announce(rid):
        watch._on_run(SimpleNamespace(data=json.dumps(dict(run_id=rid, agents=['agent_0'], since=1.0))))
    for i in range(MAX_RUNS + 50):
        announce(f'r{i}')
    announce('r0')                                     # a run kept is still updated
    assert len(watch.runs) == MAX_RUNS and watch.ignored == 50
    assert len(said) == 1 and f'more than {MAX_RUNS} runs announced' in said[0]       # rate-limited
