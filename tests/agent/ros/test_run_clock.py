"""The realtime nodes of a run (a lone agent, a container, the commander) set their clock from
the run's clock (/swarm/clock) alone: they read no /clock, and the run clock's guard refuses
another run's clock, a second writer, a time that goes back and a jump, each with one line
(`swarm_ros.run_clock`).  A whole run with a peer's /clock: tests/e2e/test_foreign_clock.py."""
from __future__ import annotations

import pytest
import rclpy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.layouts import RunClock
from swarm_ros.rosutil import make_executor
from swarm_tools.run.params import agent_parameters, node_parameters
from tests.helpers import overrides, spin_for

RUN = 'run42'
TAG = 777.0

pytestmark = pytest.mark.refuses_inputs


def agent(ctx, scn):
    from swarm_agent.agent_node import AgentNode
    node = AgentNode('agent', namespace='agent_0', context=ctx,
                     parameter_overrides=overrides(dict(agent_parameters(scn, 0, 'realtime'), run_id=RUN)))
    return node, node, node._now


def container(ctx, scn):
    from swarm_agent.container_node import AgentContainer
    names = scn.names[:2]
    box = AgentContainer(names, context=ctx, agent_overrides={
        nm: overrides(dict(agent_parameters(scn, k, 'realtime'), run_id=RUN)) for k, nm in enumerate(names)})
    return box, box, box.agents[1]._now


def commander(ctx, scn):
    from homotopy_commander.commander_node import CommanderNode
    params = node_parameters(scn, 'homotopy_global', 'realtime')['/commander']
    node = CommanderNode(context=ctx, parameter_overrides=overrides(dict(params, run_id=RUN)))
    return node, node, lambda: node.get_clock().now().nanoseconds * 1e-9


@pytest.mark.parametrize('make', [agent, container, commander], ids=lambda f: f.__name__)
def test_a_realtime_node_of_a_run_follows_its_runs_clock_alone(make, rclpy_context):
    scn = load('homotopy_global')
    node, logs, now = make(rclpy_context, scn)
    probe = rclpy.create_node('probe', context=rclpy_context)
    run_clock = probe.create_publisher(Float64MultiArray, P.RUN_CLOCK, P.qos_reliable(10))
    clock = probe.create_publisher(Clock, P.CLOCK, P.qos_reliable(10))
    ex = make_executor(rclpy_context)
    for nd in ([node, *getattr(node, 'agents', [])] + [probe]):
        ex.add_node(nd)
    try:
        assert spin_for(ex, lambda: run_clock.get_subscription_count() >= 1)
        assert not [r for r in probe.get_subscriptions_info_by_topic(P.CLOCK)], 'a node of the run reads /clock'

        def send(t, tag=TAG, run=RUN):
            n = logs.reject.count
            run_clock.publish(RunClock(tag, 2.0, t).to_cdr(run))
            return n

        send(5.0)
        assert spin_for(ex, lambda: now() == 5.0)
        sec, ns = P.time_to_stamp(1000.0)
        foreign = Clock()
        foreign.clock.sec, foreign.clock.nanosec = sec, ns
        clock.publish(foreign)                                   # a peer's /clock: not read
        spin_for(ex, lambda: False, 0.3)
        assert now() == 5.0
        for t, tag, run, kind in ((1005.0, TAG, RUN, 'clock-jump'), (5.1, TAG + 1, RUN, 'clock-writer'),
                                  (1.0, TAG, RUN, 'clock-past'), (5.1, TAG, 'other', 'other-run')):
            n = send(t, tag, run)
            assert spin_for(ex, lambda n=n: logs.reject.count > n, 5.0), kind
            assert now() == 5.0, kind
            assert kind in logs.reject.kinds, (kind, logs.reject.lines)
        send(5.2)
        assert spin_for(ex, lambda: now() == 5.2)
    finally:
        probe.destroy_node()
        node.destroy_node()
