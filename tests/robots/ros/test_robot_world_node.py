"""The robot world node (`swarm_robots.mujoco_world_node`) over a fake of the physics API: its
topics, frames and QoS, the lockstep hold on real messages (a dead agent's robot is not waited
for, a stale command changes nothing) and the summary it leaves for metrics.json."""
import json
import time

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64MultiArray

from swarm_core.scenario.loader import load
from swarm_robots import mujoco_world_node as M
from swarm_robots.world_setup import SUMMARY_FILE
from swarm_ros import protocol as P
from swarm_ros.layouts import Step
from swarm_ros.rosutil import make_executor
from tests.helpers import overrides, short_homotopy, spin_for


class FakeWorld:
    """`swarm_robots.physics.RobotWorld`'s API: robot k drives along x at its commanded v."""

    def __init__(self, poses):
        self.poses = np.array(poses, dtype=float)
        self.start = self.poses.copy()
        self.n, self.time, self.contacts = len(poses), 0.0, 1
        self.v = np.zeros(self.n)
        self.saturated_time = np.full(self.n, 0.25)
        self.commands = []

    def command(self, i, v, omega):
        self.commands.append((self.time, i, v, omega))
        self.v[i] = v

    def advance(self, seconds):
        self.poses[:, 0] += self.v * seconds
        self.time += seconds

    def ground_truth(self):
        return np.column_stack([self.poses, self.v, np.zeros(self.n)])

    def odometry(self):
        return np.column_stack([self.poses - self.start, self.v, np.zeros(self.n)])

    def odometry_pose(self):
        return self.poses - self.start


ROBOTS = {'length_scale': 0.3, 'cruise_speed': 0.15}


def lockstep_robots(tmp_path, ctx, monkeypatch, **params):
    """(the robot world node in lockstep on `FakeWorld`, with ``params``; its six-agent scenario)."""
    monkeypatch.setattr(M.RobotsNode, '_make_world', lambda self, desc: FakeWorld(
        M.start_poses(self.scn, self.rows, self.units)))
    path = short_homotopy(tmp_path / 'six.yaml', duration=10, lam='{kind: constant, value: 0}', at=1, robots=ROBOTS)
    node = M.RobotsNode(context=ctx, parameter_overrides=overrides(dict(scenario=str(path), mode='lockstep',
                                                                          **params)))
    return node, load(str(path))


@pytest.fixture
def robots_node(tmp_path, rclpy_context, monkeypatch):
    node, scn = lockstep_robots(tmp_path, rclpy_context, monkeypatch, robots='agent_1,agent_3',
                                output_dir=str(tmp_path))
    yield node, scn
    node.destroy_node()


def step(scn, n, alive, run_id=''):
    k = len(scn.names)
    z = np.zeros(k)
    return Step(n, n * scn.dt, 0.0, np.zeros(k, bool), z, z, z, z, z + 1, z, np.asarray(alive, bool),
                None, None, None).to_cdr(run_id)


def command(t, v):
    m = TwistStamped()
    m.header.stamp.sec, m.header.stamp.nanosec = P.time_to_stamp(t)
    m.twist.linear.x = v
    return m


def test_lockstep_hold_on_messages(robots_node, rclpy_context, tmp_path):
    node, scn = robots_node
    ctx = rclpy_context
    peer = rclpy.create_node('peer', context=ctx)
    got = {}
    for nm in ('agent_1', 'agent_3'):
        for topic in (M.odom_topic(nm), M.ground_truth_topic(nm)):
            peer.create_subscription(Odometry, topic, lambda m, topic=topic: got.setdefault(topic, []).append(m),
                                     P.qos_reliable(10))
    cmd = {nm: peer.create_publisher(TwistStamped, M.cmd_vel_topic(nm), P.qos_cmd_vel(True))
           for nm in ('agent_1', 'agent_3')}
    steps = peer.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
    ex = make_executor(ctx, events=False)
    ex.add_node(node)
    ex.add_node(peer)
    odom1 = M.odom_topic('agent_1')
    # before any step: the start pose again and again (a late agent gets it), stamped 0
    assert spin_for(ex, lambda: len(got) == 4 and cmd['agent_3'].get_subscription_count() == 1, 10)
    first = got[odom1][-1]
    assert (first.header.stamp.sec, first.header.stamp.nanosec) == (0, 0)
    assert first.header.frame_id == 'agent_1/odom' and first.child_frame_id == 'agent_1/base_link'
    truth = got[M.ground_truth_topic('agent_1')][-1]
    assert truth.header.frame_id == 'world' and truth.pose.pose.position.x == pytest.approx(scn.pos0[1, 0] * 0.3)
    # step 0 with agent_3 dead: agent_1's command alone moves the world by dt·L/v0
    alive = np.ones(6, bool)
    alive[3] = False
    steps.publish(_raw(step(scn, 0, alive)))
    cmd['agent_1'].publish(command(0.0, 0.15))
    def stamped(topic, t):
        return [m for m in got.get(topic, []) if abs(P.stamp_to_time(m.header.stamp) - t) < 1e-9]
    assert spin_for(ex, lambda: stamped(odom1, scn.dt) and stamped(M.odom_topic('agent_3'), scn.dt), 10)
    assert node.world.time == pytest.approx(scn.dt * 2.0)
    assert node.world.commands == [(0.0, 0, 0.15, 0.0)]
    # wheel odometry from (0, 0) in the robot's own odom frame; ground truth in the world frame
    moved = stamped(odom1, scn.dt)[0]
    assert moved.pose.pose.position.x == pytest.approx(0.15 * scn.dt * 2.0) and moved.twist.twist.linear.x == 0.15
    assert (moved.pose.pose.orientation.z, moved.pose.pose.orientation.w) == (0.0, 1.0)
    truth = stamped(M.ground_truth_topic('agent_1'), scn.dt)[0].pose.pose.position.x
    assert truth == pytest.approx(scn.pos0[1, 0] * 0.3 + 0.15 * scn.dt * 2.0)
    # a stale command (step 0 again) changes nothing; step 1 waits for both robots
    cmd['agent_1'].publish(command(0.0, 0.2))
    steps.publish(_raw(step(scn, 1, np.ones(6, bool))))
    cmd['agent_1'].publish(command(scn.dt, 0.15))
    spin_for(ex, lambda: False, 1.0)
    assert node.hold.n == 1 and node.hold.waiting_for() == [1]
    cmd['agent_3'].publish(command(scn.dt, 0.15))
    assert spin_for(ex, lambda: stamped(odom1, 2 * scn.dt), 10)
    node.finish()
    summary = json.loads((tmp_path / SUMMARY_FILE).read_text())
    assert summary['contacts'] == 1 and summary['limit_seconds'] == {'agent_1': 0.25, 'agent_3': 0.25}
    assert summary['turn_limit_seconds'] == {'agent_1': 0.0, 'agent_3': 0.0}
    peer.destroy_node()


def test_a_step_goes_on_without_a_silent_robot_hold_timeout_after_its_message(tmp_path, rclpy_context, monkeypatch):
    """The hold's time-out counts from the step's message, not from the newest odometry (which
    goes out again every half second while nothing moves), and the world's repeat of the step
    does not bring the released robot back."""
    import time
    ctx = rclpy_context
    node, scn = lockstep_robots(tmp_path, ctx, monkeypatch, robots='agent_1,agent_3', hold_timeout=1.5)
    peer = rclpy.create_node('peer', context=ctx)
    got = []
    peer.create_subscription(Odometry, M.odom_topic('agent_1'), got.append, P.qos_reliable(10))
    cmd = peer.create_publisher(TwistStamped, M.cmd_vel_topic('agent_1'), P.qos_cmd_vel(True))
    steps = peer.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
    ex = make_executor(ctx, events=False)
    ex.add_node(node)
    ex.add_node(peer)
    try:
        assert spin_for(ex, lambda: got and cmd.get_subscription_count() == 1, 10)
        steps.publish(_raw(step(scn, 0, np.ones(6, bool))))        # agent_3 alive, but it never answers
        cmd.publish(command(0.0, 0.15))
        start = time.monotonic()
        spin_for(ex, lambda: False, 1.0)
        steps.publish(_raw(step(scn, 0, np.ones(6, bool))))        # the world's repeat while it stalls
        assert node.hold.n == 0 and len(got) >= 2                   # odometry of t_0 again meanwhile
        assert spin_for(ex, lambda: node.hold.n == 1, 10)
        assert 1.5 <= time.monotonic() - start < 5.0
        assert node.world.commands == [(0.0, 0, 0.15, 0.0)]         # agent_3's robot got none
        assert spin_for(ex, lambda: P.stamp_to_time(got[-1].header.stamp) == pytest.approx(scn.dt), 5)
    finally:
        peer.destroy_node()
        node.destroy_node()


def _raw(cdr):
    """A serialized Float64MultiArray as a message to publish."""
    from rclpy.serialization import deserialize_message
    return deserialize_message(cdr, Float64MultiArray)


def test_realtime_follows_the_sim_clock(tmp_path, rclpy_context, monkeypatch):
    from rosgraph_msgs.msg import Clock
    monkeypatch.setattr(M.RobotsNode, '_make_world', lambda self, desc: FakeWorld(
        M.start_poses(self.scn, self.rows, self.units)))
    path = short_homotopy(tmp_path / 'six.yaml', duration=10, lam='{kind: constant, value: 0}', at=1, robots=ROBOTS)
    ctx = rclpy_context
    node = M.RobotsNode(context=ctx, parameter_overrides=overrides(dict(
        scenario=str(path), mode='realtime', robots='agent_0', use_sim_time=True)))
    peer = rclpy.create_node('peer', context=ctx)
    got = []
    peer.create_subscription(Odometry, M.odom_topic('agent_0'), got.append, P.qos_reliable(10))
    clock = peer.create_publisher(Clock, P.CLOCK, P.qos_reliable(P.STEP_DEPTH))
    cmd = peer.create_publisher(TwistStamped, M.cmd_vel_topic('agent_0'), P.qos_reliable(10))
    ex = make_executor(ctx, events=False)
    ex.add_node(node)
    ex.add_node(peer)
    try:
        # the clock stands still at 0: odometry anyway (the world starts its clock only once
        # every agent has published a state, and a robot agent needs a pose for that)
        assert spin_for(ex, lambda: got and cmd.get_subscription_count() == 1, 10)
        assert node.world.time == 0.0 and P.stamp_to_time(got[-1].header.stamp) == 0.0
        cmd.publish(command(0.0, 0.15))
        assert spin_for(ex, lambda: node.world.commands, 5)
        clock.publish(Clock(clock=command(1.5, 0).header.stamp))
        assert spin_for(ex, lambda: node.world.time >= 3.0, 5)
        assert node.world.time == pytest.approx(3.0)         # sim 1.5 s = 3 robot s (L / v0 = 2)
        assert spin_for(ex, lambda: P.stamp_to_time(got[-1].header.stamp) == pytest.approx(1.5), 5)
        assert got[-1].pose.pose.position.x == pytest.approx(0.15 * 3.0)
    finally:
        peer.destroy_node()
        node.destroy_node()


def drive(ctx, path, steps, tag):
    """A robot world of agents 0 and 1 on MuJoCo, driven `steps` lockstep steps by commands of
    the peer; the odometry of each step (x, y, qz, qw of both robots) and the world's summary."""
    node = M.RobotsNode(context=ctx, parameter_overrides=overrides(dict(
        scenario=str(path), mode='lockstep', robots='agent_0,agent_1')))
    peer = rclpy.create_node(f'peer_{tag}', context=ctx)
    got = {}

    def on_odom(k):
        return lambda m: got.setdefault(round(P.stamp_to_time(m.header.stamp), 9), {}).__setitem__(
            k, (m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.orientation.z, m.pose.pose.orientation.w))
    cmd = []
    for k, nm in enumerate(('agent_0', 'agent_1')):
        peer.create_subscription(Odometry, M.odom_topic(nm), on_odom(k), P.qos_reliable(10))
        cmd.append(peer.create_publisher(TwistStamped, M.cmd_vel_topic(nm), P.qos_cmd_vel(True)))
    ex = make_executor(ctx, events=False)
    ex.add_node(node)
    ex.add_node(peer)
    dt = node.scn.dt
    try:
        assert spin_for(ex, lambda: len(got.get(0.0, {})) == 2 and all(c.get_subscription_count() for c in cmd), 10)
        for n in range(steps):
            for k in (1, 0):
                m = command(n * dt, 0.15)
                m.twist.angular.z = 2.84 if k == 1 else 0.5 * np.sin(0.1 * n)     # robot 1 at ω_max
                cmd[k].publish(m)
            t = round((n + 1) * dt, 9)
            assert spin_for(ex, lambda t=t: len(got.get(t, {})) == 2, 10), n
        return [got[round((n + 1) * dt, 9)] for n in range(steps)], node.summary(), node.world.time
    finally:
        peer.destroy_node()
        node.destroy_node()


def test_mujoco_robots_in_lockstep_repeat_bit_for_bit(tmp_path, rclpy_context):
    path = short_homotopy(tmp_path / 'six.yaml', duration=10, lam='{kind: constant, value: 0}', at=1, robots=ROBOTS)
    a, summary, robot_time = drive(rclpy_context, path, 40, 'a')
    b, _, _ = drive(rclpy_context, path, 40, 'b')
    assert a == b
    assert robot_time == pytest.approx(40 * 0.05 * 2.0)            # dt·L/v0 a step
    # wheel odometry from (0, 0): about v0 · 4 robot s along the way (the start accelerates)
    x, y = a[-1][0][:2]
    assert 0.5 < np.hypot(x, y) <= 0.15 * 4.0 + 1e-9
    assert set(summary['limit_seconds']) == {'agent_0', 'agent_1'}
    assert summary['turn_limit_seconds'] == {'agent_0': 0.0, 'agent_1': pytest.approx(4.0)}


def test_a_flood_of_refused_commands_does_not_push_out_the_agents_own(tmp_path, rclpy_context, monkeypatch):
    """Lockstep: a peer floods a robot's cmd_vel with commands of another run, right after the
    agent's own command of the step and before the robot world reads it.  Each is refused, and
    the agent's command is still taken: the step goes on with it, at once, not after the hold's
    time-out without it (a reader history of depth 10 lost it under the flood).  A step that does
    go on without a command is recorded (robots.json: not deterministic)."""
    from swarm_ros.run_control import command_frame
    ctx = rclpy_context
    node, scn = lockstep_robots(tmp_path, ctx, monkeypatch, robots='agent_1', hold_timeout=3.0, run_id='ours',
                                output_dir=str(tmp_path))
    peer = rclpy.create_node('peer', context=ctx)
    cmd = peer.create_publisher(TwistStamped, M.cmd_vel_topic('agent_1'), P.qos_cmd_vel(True))
    flood = peer.create_publisher(TwistStamped, M.cmd_vel_topic('agent_1'), P.qos_latched(1000))
    steps = peer.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
    ex = make_executor(ctx, events=False)
    ex.add_node(node)
    ex.add_node(peer)
    try:
        assert spin_for(ex, lambda: cmd.get_subscription_count() == 1 and flood.get_subscription_count() == 1, 10)
        steps.publish(_raw(step(scn, 0, np.ones(6, bool), 'ours')))
        assert spin_for(ex, lambda: 0 in node.hold.known, 10)
        own = command(0.0, 0.15)
        own.header.frame_id = command_frame('agent_1', 'ours', 7)
        cmd.publish(own)
        other = command(0.0, 0.0)
        other.header.frame_id = command_frame('agent_1', 'theirs', 9)
        for _ in range(200):
            flood.publish(other)
        time.sleep(0.5)                       # all delivered into the reader's history, none taken yet
        assert spin_for(ex, lambda: node.hold.n == 1, 2.0), node.reject.summary()
        assert node.world.commands == [(0.0, 0, 0.15, 0.0)] and node.missed == {}
        assert spin_for(ex, lambda: node.reject.kinds.get('other-run', [0, 0, 0])[2] == 200, 5)
        # the agent's resend of a step already advanced (the world repeated it) changes nothing
        cmd.publish(own)
        spin_for(ex, lambda: node.hold.repeated == 1, 5)
        assert node.hold.repeated == 1 and 'cmd-stale' not in node.reject.kinds
        # step 1 without the command: after the hold's time-out it goes on, and that is recorded
        steps.publish(_raw(step(scn, 1, np.ones(6, bool), 'ours')))
        assert spin_for(ex, lambda: node.hold.n == 2, 10)
        node.finish()
        summary = json.loads((tmp_path / SUMMARY_FILE).read_text())
        assert summary['commands_missed'] == {'agent_1': [1]} and summary['deterministic'] is False
    finally:
        peer.destroy_node()
        node.destroy_node()
