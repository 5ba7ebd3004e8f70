"""Control paths belong to the run (`swarm_ros.run_control`, docs/security.md), on real
messages: a peer on the domain that does not carry the run's id and sender tags neither stops a
robot agent or an agent of a container, nor gets its event into events.jsonl, nor drives a
robot of the MuJoCo world in lockstep, nor replaces the robot world's poses; garbage on a
robot's cmd_vel or odom is counted and the node goes on."""
import json

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64MultiArray, String

from swarm_core.scenario.loader import load
from swarm_robots import mujoco_world_node as M
from swarm_ros import protocol as P
from swarm_ros.layouts import RobotStates, Step
from swarm_ros.rosutil import make_executor
from swarm_ros.run_control import command_frame, event_text
from tests.helpers import overrides, short_homotopy, spin_for
from tests.robots.ros.test_robot_world_node import ROBOTS, FakeWorld

RUN = 'run0042'
#: what a peer on the domain sends without the run id (`ros2 topic pub /swarm/events ...`)
FORGED = {'t': 0.0, 'kind': 'kill', 'agent': 'agent_0'}
#: a message that is not a serialized TwistStamped nor Odometry (one line of garbage)
GARBAGE = b'\x00\x01\x00\x00garbage'


def _scenario(tmp_path):
    return short_homotopy(tmp_path / 'six.yaml', duration=10, lam='{kind: constant, value: 0}', at=1, robots=ROBOTS)


def _command(t, v, frame=''):
    m = TwistStamped()
    m.header.stamp.sec, m.header.stamp.nanosec = P.time_to_stamp(t)
    m.header.frame_id = frame
    m.twist.linear.x = v
    return m


def test_the_mujoco_world_takes_commands_and_kills_of_its_run_only(tmp_path, rclpy_context, monkeypatch):
    """Lockstep, the robot of agent_1: a peer's commands stamped for the coming steps (from the
    public /clock) and garbage on cmd_vel are refused with a count; the step waits for and
    applies the agent's own command; a kill without the run id is ignored."""
    monkeypatch.setattr(M.RobotsNode, '_make_world', lambda self, desc: FakeWorld(
        M.start_poses(self.scn, self.rows, self.units)))
    path = _scenario(tmp_path)
    scn = load(str(path))
    ctx = rclpy_context
    node = M.RobotsNode(context=ctx, parameter_overrides=overrides(dict(
        scenario=str(path), mode='lockstep', robots='agent_1', run_id=RUN)))
    peer = rclpy.create_node('peer', context=ctx)
    cmd = peer.create_publisher(TwistStamped, M.cmd_vel_topic('agent_1'), P.qos_cmd_vel(True))
    steps = peer.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
    events = peer.create_publisher(String, P.EVENTS, P.qos_latched(100))
    ex = make_executor(ctx, events=False)
    ex.add_node(node)
    ex.add_node(peer)
    try:
        assert spin_for(ex, lambda: cmd.get_subscription_count() == 1 and events.get_subscription_count() >= 1, 10)
        for n in range(5):                                   # the peer's, for steps 0-4
            cmd.publish(_command(n * scn.dt, 0.22))
        cmd.publish(_command(0.0, 0.22, command_frame('agent_1', 'other', 5)))      # another run's
        cmd.publish(GARBAGE)
        events.publish(String(data=json.dumps(dict(FORGED, agent='agent_1'))))
        z = np.zeros(6)
        steps.publish(Step(0, 0.0, 0.0, np.zeros(6, bool), z, z, z, z, z + 1, z, np.ones(6, bool),
                           None, None, None).to_cdr(RUN))
        assert spin_for(ex, lambda: node.reject.count >= 8, 10), node.reject.lines
        assert node.hold.n == 0 and node.hold.waiting_for() == [0] and not node.hold.dead
        assert node.world.commands == []                     # the peer moved nothing
        assert {'other-run', 'cmd-decode'} <= set(node.reject.kinds), node.reject.lines
        cmd.publish(_command(0.0, 0.15, command_frame('agent_1', RUN, 77)))          # the agent's own
        assert spin_for(ex, lambda: node.hold.n == 1, 10)
        assert node.world.commands == [(0.0, 0, 0.15, 0.0)]
        cmd.publish(_command(scn.dt, 0.22, command_frame('agent_1', RUN, 78)))       # a second writer
        assert spin_for(ex, lambda: 'second-publisher' in node.reject.kinds, 10)
        events.publish(String(data=event_text(dict(FORGED, agent='agent_1', node='world'), RUN)))
        assert spin_for(ex, lambda: node.hold.dead == {0}, 10)   # the run's own kill
    finally:
        peer.destroy_node()
        node.destroy_node()


def _robot_agent(ctx, tmp_path):
    """A lone realtime robot agent of run `RUN` on an external robot (its odometry by hand)."""
    from swarm_agent.agent_node import AgentNode
    from swarm_tools.run.params import agent_parameters
    from swarm_tools.run.robots import robot_parameters
    scn = load(str(_scenario(tmp_path)))
    prm = dict(agent_parameters(scn, 0, 'realtime'), use_sim_time=False, run_id=RUN,
               **robot_parameters(scn.spec.robots, 'external', 'realtime'))
    return AgentNode('agent', namespace='agent_0', context=ctx, parameter_overrides=overrides(prm))


def test_a_robot_agent_obeys_only_its_runs_events_and_survives_garbage_odometry(tmp_path, rclpy_context):
    agent = _robot_agent(rclpy_context, tmp_path)
    probe = rclpy.create_node('probe', context=rclpy_context)
    events = probe.create_publisher(String, P.EVENTS, P.qos_latched(100))
    odom = probe.create_publisher(Odometry, '/agent_0/odom', 10)
    ex = make_executor(rclpy_context)
    for nd in (agent, probe):
        ex.add_node(nd)
    try:
        assert spin_for(ex, lambda: odom.get_subscription_count() and events.get_subscription_count() >= 1, 10)
        events.publish(String(data=json.dumps(FORGED)))
        odom.publish(GARBAGE)
        assert spin_for(ex, lambda: {'other-run', 'odom-decode'} <= set(agent.reject.kinds), 10), agent.reject.lines
        assert agent.halted is None                          # the forged kill stopped nothing
        events.publish(String(data=event_text(dict(FORGED, node='world'), RUN)))
        assert spin_for(ex, lambda: agent.halted == 'kill', 10)
    finally:
        for nd in (agent, probe):
            nd.destroy_node()


def test_an_agent_of_a_container_obeys_only_its_runs_events(rclpy_context):
    from swarm_agent.container_node import AgentContainer
    from swarm_tools.run.params import agent_parameters
    names = ['agent_0', 'agent_1']
    scn = load('homotopy_global')
    box = AgentContainer(names, context=rclpy_context, agent_overrides={
        nm: overrides(dict(agent_parameters(scn, k, 'lockstep'), run_id=RUN)) for k, nm in enumerate(names)})
    probe = rclpy.create_node('probe', context=rclpy_context)
    events = probe.create_publisher(String, P.EVENTS, P.qos_latched(100))
    ex = make_executor(rclpy_context)
    for nd in (box, probe):
        ex.add_node(nd)
    try:
        assert spin_for(ex, lambda: events.get_subscription_count() >= 1, 10)
        events.publish(String(data=json.dumps(FORGED)))
        events.publish(String(data=event_text(FORGED, 'other')))
        assert spin_for(ex, lambda: box.agents[0].reject.count >= 2, 10)
        assert [a.halted for a in box.agents] == [None, None] and not any(box.lock.dead)
        events.publish(String(data=event_text(dict(FORGED, node='world'), RUN)))
        assert spin_for(ex, lambda: box.agents[0].halted == 'kill', 10)
        assert box.agents[1].halted is None
    finally:
        box.destroy_node()                                   # and its agents' nodes
        probe.destroy_node()


def test_the_world_records_its_runs_events_only_and_binds_the_robot_poses(tmp_path, rclpy_context):
    """A forged event (no run id, or another run's) is counted, not written to events.jsonl;
    the run's own is written without its run id.  /lockstep/robot_states from a second sender
    (another tag than the first taken) is refused."""
    from swarm_world.world_node import WorldNode
    path = _scenario(tmp_path)
    scn = load(str(path))
    world = WorldNode(context=rclpy_context, log=lambda *a, **k: None, parameter_overrides=overrides(dict(
        scenario=str(path), run_id=RUN, output_dir=str(tmp_path / 'out'), robot_poses='agent_1')))
    probe = rclpy.create_node('probe', context=rclpy_context)
    events = probe.create_publisher(String, P.EVENTS, P.qos_latched(100))
    robots = probe.create_publisher(Float64MultiArray, P.LOCK_ROBOT_STATES, P.qos_latched())
    ex = make_executor(rclpy_context)
    for nd in (world, probe):
        ex.add_node(nd)
    pose = np.array([[scn.pos0[1, 0]], [scn.pos0[1, 1]], [0.0], [1.0]])
    try:
        assert spin_for(ex, lambda: events.get_subscription_count() and robots.get_subscription_count(), 10)
        events.publish(String(data=json.dumps(dict(FORGED, node='agent'))))
        events.publish(String(data=event_text(dict(FORGED, node='agent'), 'other')))
        robots.publish(RobotStates(0, 11.0, [1], pose).to_cdr(RUN))
        assert spin_for(ex, lambda: world.driver.robot_sender.tag == 11.0, 10)
        robots.publish(RobotStates(0, 12.0, [1], pose + 1.0).to_cdr(RUN))
        assert spin_for(ex, lambda: {'other-run', 'second-publisher'} <= set(world.reject.kinds), 10), \
            world.reject.lines
        events.publish(String(data=event_text(dict(FORGED, kind='robot_stopped', node='agent'), RUN)))
        assert spin_for(ex, lambda: world.events, 10)
    finally:
        for nd in (world, probe):
            nd.destroy_node()
    lines = [json.loads(ln) for ln in (tmp_path / 'out' / 'events.jsonl').read_text().splitlines()]
    assert lines == [dict(FORGED, kind='robot_stopped', node='agent')], lines


@pytest.mark.parametrize('stamped', [True, False])
def test_garbage_commands_are_refused_by_the_decoder(stamped):
    """The one decoder of the robot world's commands: bytes that are not a command are a
    ValueError (the node counts it), never a struct.error or IndexError."""
    from swarm_ros.run_control import decode_command
    for raw in (b'', b'\x00', GARBAGE, b'\x00\x01\x00\x00' + b'\xff' * 12):
        with pytest.raises(ValueError, match='not a serialized Twist'):
            decode_command(raw, stamped)
