"""The messages of a lockstep step, counted on every topic of a short run against the protocol's
declared count (`protocol.lockstep_messages`): a step that sends more than it declares fails here.
The critical path must match exactly (up to the steps around the start and the end); every other
topic may carry at most its declared rate, or, for topics that change only now and then, a few."""
from __future__ import annotations

import importlib
import threading
from collections import Counter

import rclpy

from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.rosutil import make_executor
from swarm_tools.run.launch import build_nodes
from swarm_tools.run.params import node_parameters
from tests.helpers import short_homotopy, spin_for

#: topics with no per-step messages by design: logs, parameter changes, the run's announcement,
#: the target and barrier (latched, sent when they change)
NOT_PER_STEP = {'/rosout', '/parameter_events', P.RUN, P.TARGET, P.BARRIER, P.EVENTS, P.LEADERS}


def _msg_class(type_name: str):
    pkg, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def test_lockstep_step_sends_what_the_protocol_declares(tmp_path, rclpy_context):
    path = short_homotopy(tmp_path / 'count.yaml', duration=40.0, lam='{kind: constant, value: 0.0}', at=5.0)
    scn = load(str(path))
    params = node_parameters(scn, str(path), 'lockstep')
    ctx = rclpy_context
    world, commander, agents = build_nodes(params, ctx, log=lambda *a, **k: None)
    probe = rclpy.create_node('message_counter', context=ctx)
    counts, lock = Counter(), threading.Lock()
    seen = set()

    def count(topic):
        def on(_raw):
            with lock:
                counts[topic] += 1
        return on

    def subscribe_all():
        for topic, types in probe.get_topic_names_and_types():
            if topic in seen or topic in NOT_PER_STEP:
                continue
            seen.add(topic)
            probe.create_subscription(_msg_class(types[0]), topic, count(topic), P.qos_reliable(1000), raw=True)

    ex = make_executor(ctx)
    for nd in (world, commander, *agents, probe):
        ex.add_node(nd)
    # every input and output topic exists from the nodes' start: subscribe before the first step
    assert spin_for(ex, lambda: subscribe_all() or {P.LOCK_STEP, P.LOCK_AGENT_STATES} <= seen, 60.0), sorted(seen)
    assert spin_for(ex, lambda: world.done, 240.0), 'the run did not finish'
    spin_for(ex, lambda: False, 0.5)                        # the last messages in flight
    steps = counts[P.LOCK_STEP]
    assert steps >= 600, counts                              # 801 steps; the probe may match a few late
    slack = 3 + steps // 50
    declared = P.lockstep_messages(len(scn.names), len(agents),
                                   clock_every=int(world.get_parameter('clock_every').value),
                                   publish_every=int(commander.get_parameter('publish_every').value),
                                   view_every=int(world.get_parameter('view_every').value))
    for topic in P.CRITICAL_PATH:
        assert abs(counts[topic] - declared[topic] * steps) <= slack * declared[topic], (topic, counts[topic], steps)
    steering = {P.steering_topic(nm) for nm in scn.names}
    for topic, got in counts.items():
        if topic in steering:        # the leaders' s_k: on a change and every publish_every steps
            assert got <= steps * declared[P.LAMBDA] + slack, (topic, got, steps)
        else:
            assert got <= declared.get(topic, 0.0) * steps + slack, (topic, got, steps, declared.get(topic))
    assert set(P.CRITICAL_PATH) <= set(counts)
