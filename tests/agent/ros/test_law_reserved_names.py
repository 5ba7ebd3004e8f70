"""An agent node started by hand with a law whose parameter takes a reserved name refuses it in
one line (a `ParameterError`: exit 2), not with rclpy's traceback of a parameter declared twice;
and the reserved names (`swarm_core.reserved.AGENT_PARAMETERS`) are the agent node's own."""
from __future__ import annotations

import pytest

from swarm_agent.agent_node import AgentNode
from swarm_core.laws import parameter_specs
from swarm_core.reserved import AGENT_PARAMETERS
from swarm_core.scenario.loader import load
from swarm_ros.rosutil import ParameterError
from swarm_tools.run.params import agent_parameters
from tests.core.test_law_reserved_names import law_file
from tests.helpers import overrides


@pytest.mark.parametrize('name', ['x', 'dt', 'run_id', 'parameters'])
def test_an_agent_refuses_a_law_parameter_of_a_reserved_name(tmp_path, rclpy_context, name):
    kind = str(tmp_path / law_file(tmp_path, name))
    prm = dict(agent_parameters(load('homotopy_global'), 0, 'lockstep'), law=kind)
    with pytest.raises(ParameterError, match=rf"^parameter law: law .*with_{name}\.py:L: parameter '{name}' "
                                             'takes a reserved name; .*agent node'):
        AgentNode('agent', namespace='agent_0', context=rclpy_context, parameter_overrides=overrides(prm))


@pytest.mark.parametrize('robot', ['none', 'external'])
def test_the_reserved_names_are_the_agent_nodes_own_parameters(rclpy_context, robot):
    scn = load('homotopy_global')
    prm = dict(agent_parameters(scn, 0, 'realtime'), robot=robot)
    if robot != 'none':
        prm.update(length_scale=0.3, cruise_speed=0.2)
    agent = AgentNode('agent', namespace='agent_0', context=rclpy_context, parameter_overrides=overrides(prm))
    try:
        own = set(agent._parameters) - set(parameter_specs(agent.law)) | {'law'}
        robot_only = {'cmd_type', 'cruise_speed', 'length_scale', 'max_angular', 'max_jump', 'neighbour_timeout',
                      'odom_reliability', 'odom_timeout', 'robot_clock', 'robot_frame'}
        assert own == set(AGENT_PARAMETERS) - (robot_only if robot == 'none' else set())
    finally:
        agent.destroy_node()
