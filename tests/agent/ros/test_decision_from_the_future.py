"""A forged /swarm/decision: a peer that copied the run id stamps one far in the future.  The
realtime agents (alone and in a container) and the world refuse it with one line and keep the
decision they hold; one of the run's own, stamped now, is taken (`msg_checks.check_decision_time`)."""
from __future__ import annotations

import numpy as np
import pytest

from swarm_core.scenario.loader import load
from swarm_ros.layouts import RealtimeDecision
from swarm_tools.run.params import agent_parameters, node_parameters
from tests.helpers import overrides

RUN = 'run42'

pytestmark = pytest.mark.refuses_inputs


def decision(scn, t, lam, leader=0):
    """The bytes of a decision of ``RUN`` at sim time ``t``: λ, ``leader`` the one leader, s = 0.01."""
    n = len(scn.names)
    flags = np.zeros(n, bool)
    flags[leader] = True
    return RealtimeDecision(int(t / scn.dt), t, lam, flags, np.full(n, 0.01), np.full(n, -1), None).to_cdr(RUN)


def refuses_the_future(take, held, reject, scn):
    """``take(raw)`` a decision of now (taken: ``held()`` is its λ), then a forged one of
    t = 1000 (refused with one line: ``held()`` is still the first λ)."""
    take(decision(scn, 0.5, 0.25))
    assert held() == 0.25
    n = reject.count
    take(decision(scn, 1000.0, 1.0, leader=1))
    assert held() == 0.25, 'the decision from the future was taken'
    assert reject.count == n + 1
    assert 'decision from the future' in reject.lines[-1] and 't=1000.000' in reject.lines[-1], reject.lines


def test_a_realtime_agent_refuses_a_decision_from_the_future(rclpy_context):
    from swarm_agent.agent_node import AgentNode
    scn = load('homotopy_global')
    agent = AgentNode('agent', namespace='agent_0', context=rclpy_context,
                      parameter_overrides=overrides(dict(agent_parameters(scn, 0, 'realtime'), run_id=RUN)))
    try:
        refuses_the_future(agent._on_decision, lambda: agent.lam, agent.reject, scn)
        assert agent.leaders == {'agent_0'} and agent.steering == 0.01
    finally:
        agent.destroy_node()


def test_a_container_refuses_a_decision_from_the_future(rclpy_context):
    from swarm_agent.container_node import AgentContainer
    scn = load('homotopy_global')
    names = scn.names[:2]
    box = AgentContainer(names, context=rclpy_context, agent_overrides={
        nm: overrides(dict(agent_parameters(scn, k, 'realtime'), run_id=RUN)) for k, nm in enumerate(names)})
    try:
        refuses_the_future(box._on_decision, lambda: box.agents[1].lam, box.reject, scn)
        assert [a.lam for a in box.agents] == [0.25, 0.25] and box.agents[1].leaders == {'agent_0'}
    finally:
        box.destroy_node()


def test_the_realtime_world_refuses_a_decision_from_the_future(rclpy_context):
    from swarm_world.world_node import WorldNode
    scn = load('homotopy_global')
    params = node_parameters(scn, 'homotopy_global', 'realtime', rtf=1.0)['/world']
    world = WorldNode(context=rclpy_context, parameter_overrides=overrides(dict(params, run_id=RUN)),
                      log=lambda *a, **k: None)
    try:
        refuses_the_future(world.driver.on_decision, lambda: world.lam_now, world.reject, scn)
        assert list(np.flatnonzero(world.leaders_now)) == [0]
    finally:
        world.destroy_node()
