"""Agents as ``ros2 node info`` shows them (the faithful stand-in of tests/fakes/ros2cli_verbs.py,
a fresh DDS participant): every input topic of a lone agent and of an agent container's host
node is in the graph from its start, before any other node writes anything.  None is
/swarm/lambda, /swarm/leaders or the agent's /<agent>/steering: λ, the leaders and s_k come
with the commander's decision (the step relay in lockstep, /swarm/decision in realtime), and a
user's command on those topics is the commander's alone (docs/ros-graph.md)."""
import time

import pytest

from swarm_agent.agent_node import AgentNode
from swarm_agent.container_node import AgentContainer
from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_tools.run.params import agent_parameters
from tests.fakes.ros2cli_verbs import NodeNotFound, node_info
from tests.helpers import node_inputs, overrides

#: what an agent process reads (docs/ros-graph.md): in every mode, and the mode's own
COMMON = {P.TARGET, P.BARRIER, P.EVENTS}
INPUTS = {'lockstep': COMMON | {P.LOCK_STEP},
          'lockstep-clock': COMMON | {P.LOCK_STEP, P.CLOCK},        # lockstep_clock:=topic
          'realtime': COMMON | {P.AGENT_STATES, P.DECISION, P.CLOCK},
          'realtime-run': COMMON | {P.AGENT_STATES, P.DECISION, P.RUN_CLOCK}}     # a run's: its clock, no /clock
COMMANDS = {P.LAMBDA, P.LEADERS, P.steering_topic('agent_0'), P.steering_topic('agent_1')}


def _parameters(case, k):
    prm = agent_parameters(load('homotopy_global'), k, case.split('-')[0])
    if case == 'lockstep-clock':
        prm['lockstep_clock'] = 'topic'
    if case == 'realtime-run':
        prm['run_id'] = 'run42'
    return prm


@pytest.mark.parametrize('case', sorted(INPUTS))
def test_every_input_of_a_lone_agent_is_in_the_graph_from_its_start(case, rclpy_context):
    agent = AgentNode('agent', namespace='agent_0', context=rclpy_context,
                      parameter_overrides=overrides(_parameters(case, 0)))
    seen = node_inputs('/agent_0/agent', INPUTS[case])
    assert seen == INPUTS[case]
    assert not seen & COMMANDS
    agent.destroy_node()


@pytest.mark.parametrize('case', ['lockstep', 'realtime', 'realtime-run'])
def test_every_input_of_an_agent_container_is_in_the_graph_from_its_start(case, rclpy_context):
    """The host node ``/agent_container_0`` reads what its agents share; each agent node
    ``/agent_k/agent`` in it reads nothing of its own (its writer of /swarm/states is there)."""
    names = ['agent_0', 'agent_1']
    box = AgentContainer(names, context=rclpy_context,
                         agent_overrides={nm: overrides(_parameters(case, k)) for k, nm in enumerate(names)},
                         parameter_overrides=overrides({'lockstep_clock': 'step'}))
    want = INPUTS[case]
    seen = node_inputs('/agent_container_0', want)
    assert seen == want and not seen & COMMANDS
    end, info = time.monotonic() + 30, None
    while time.monotonic() < end and not (info and P.STATES in info['publishers']):
        try:
            info = node_info('/agent_1/agent')
        except NodeNotFound:
            info = None
    assert info and P.STATES in info['publishers'], info
    assert set(info['subscribers']) == set(), info
    box.destroy_node()
