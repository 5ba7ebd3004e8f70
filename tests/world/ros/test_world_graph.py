"""The world as ``ros2 node info /world`` shows it (the faithful stand-in of
tests/fakes/ros2cli_verbs.py, a fresh DDS participant): every input topic is in the graph from
its start, before any other node writes anything; in realtime the commander's decision
(/swarm/decision), never /swarm/lambda or /swarm/leaders (a user's command on /swarm/lambda is
the commander's alone; docs/ros-graph.md)."""
import pytest

from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_tools.run.params import node_parameters
from swarm_world.world_node import WorldNode
from tests.helpers import node_inputs, overrides

#: what the world reads in every mode, and in each mode (docs/ros-graph.md)
COMMON = {P.EVENTS, P.FAULT_REQUEST, P.RUN}
INPUTS = {'lockstep': COMMON | {P.LOCK_AGENT_STATES, P.LOCK_COMMAND},
          'lockstep-robots': COMMON | {P.LOCK_AGENT_STATES, P.LOCK_COMMAND, P.LOCK_ROBOT_STATES},
          'realtime': COMMON | {P.AGENT_STATES, P.DECISION}}


@pytest.mark.parametrize('case', sorted(INPUTS))
def test_every_input_of_the_world_is_in_the_graph_from_its_start(case, rclpy_context):
    mode = case.split('-')[0]
    prm = node_parameters(load('homotopy_global'), 'homotopy_global', mode)['/world']
    if case.endswith('robots'):
        prm['robot_poses'] = 'agent_1'
    world = WorldNode(context=rclpy_context, parameter_overrides=overrides(prm), log=lambda *a, **k: None)
    seen = node_inputs('/world', INPUTS[case])
    assert seen == INPUTS[case]
    assert not seen & {P.LAMBDA, P.LEADERS}
    world.destroy_node()
