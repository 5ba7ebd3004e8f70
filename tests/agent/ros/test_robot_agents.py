"""Robot agents against a stand-in for diff_drive_controller (tests/fakes/diff_drive_standin.py):
three agent processes drive three stand-in robots in realtime and form one swarm; cut one
robot's odometry (its controller process stopped) and its agent stops it (zero cmd_vel, a
``robot_stopped`` event) and lets it go when the odometry comes back."""
from __future__ import annotations

import json
import math
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import FAKES

NAMES = ['agent_0', 'agent_1', 'agent_2']
L = V0 = 0.2          # L / v0 = 1: a model second is a robot second (and, here, a wall second)


def _scenario_file(path, dt, duration, length_scale, cruise_speed):
    """Three agents in a triangle under the global law (they flock), with a robots: section;
    returns (path, the scenario loaded from it)."""
    import yaml

    from swarm_core.scenario.loader import load
    path.write_text(yaml.safe_dump({
        'name': path.stem, 'dt': dt, 'duration': duration,
        'agents': {'positions': [[0, 0], [1.5, 0], [0.75, 1.3]], 'headings': {'rule': 'cone', 'half_width': 0.5}},
        'law': {'kind': 'global', 'alpha': 0.5, 'eta': 0.5, 'r0': 1.5},
        'robots': {'length_scale': length_scale, 'cruise_speed': cruise_speed}}))
    return path, load(str(path))


def _start_agents(processes, scn, tmp_path):
    """Agent processes on the wall clock (no world: the sim clock is the system clock)."""
    from swarm_tools.run.params import node_parameters, write_params_file
    from swarm_tools.run.robots import apply_robots
    params = node_parameters(scn, 'robots3', 'realtime')
    apply_robots(params, scn, {nm: 'external' for nm in NAMES}, 'realtime')
    agents = {k: dict(v, use_sim_time=False) for k, v in params.items() if k.endswith('/agent')}
    assert all(p['robot_clock'] == 'wall' for p in agents.values())
    pfile = write_params_file(agents, tmp_path / 'params.yaml')
    exe = Path(sys.executable).parent / 'swarm_agent'
    return [processes.start([exe, '--ros-args', '--params-file', pfile, '-r', '__node:=agent', '-r', f'__ns:=/{nm}'],
                            stdout=open(tmp_path / f'{nm}.log', 'w'), stderr=open(tmp_path / f'{nm}.err', 'w'))
            for nm in NAMES]


def _probe(ctx):
    """A node that hears the agents' states, events, agent_0's commands and the robots' odometry."""
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    from rclpy.qos import qos_profile_system_default
    from std_msgs.msg import String

    from swarm_ros import protocol as P
    node = rclpy.create_node('probe', context=ctx)
    seen = {'states': {nm: [] for nm in NAMES}, 'events': [], 'cmd': [], 'odom': {nm: [] for nm in NAMES}}
    node.create_subscription(Odometry, P.STATES, lambda m: seen['states'].setdefault(m.child_frame_id, []).append(
        (time.monotonic(), m.pose.pose.position.x, m.pose.pose.position.y)), P.qos_latched(100))
    node.create_subscription(String, P.EVENTS, lambda m: seen['events'].append(json.loads(m.data)),
                             P.qos_latched(100))
    node.create_subscription(TwistStamped, '/agent_0/cmd_vel', lambda m: seen['cmd'].append(
        (time.monotonic(), m.twist.linear.x, m.twist.angular.z, m.header.frame_id)), qos_profile_system_default)
    for nm in NAMES:
        node.create_subscription(Odometry, f'/{nm}/odom', lambda m, nm=nm: seen['odom'][nm].append(
            (time.monotonic(), m.header.frame_id, m.child_frame_id, m.pose.pose.position.x)),
            qos_profile_system_default)
    return node, seen


def _said(seen, kind, nm, after=0):
    """The events ``kind`` of agent ``nm`` heard since event number ``after``."""
    return [e for e in seen['events'][after:] if e.get('kind') == kind and e.get('agent') == nm]


def _start_together(ex, probe, seen, start_robots, tmp_path):
    """Let the three robots go at once: each agent is paused (a freeze event, latched) before its
    robot's controller starts, and all are resumed together once every robot publishes odometry.
    Without a world there is no common clock start (`swarm run` starts the agents together on
    the world's clock); a lone agent process drives as soon as its robot's odometry comes, and
    at load ~10 the agent and controller processes come up 0 to 3 s apart.  The flock does not
    close such a lead in the 12 s watched: the law's batch model of this scenario (dt 0.1,
    |u| clipped at ω_max) has the agents 2.0 apart 12 s after a common start and at most 2.5
    with starts up to 0.5 s apart, but 4.3 with agent_1 1 s ahead of the others, 6.0 with it
    3 s ahead, and farther than w = 4 in one run of five with starts drawn within 3 s.
    Returns the wall time each agent said robot_resumed."""
    from std_msgs.msg import String

    from swarm_ros import protocol as P
    from tests.helpers import spin_for
    gate = probe.create_publisher(String, P.EVENTS, P.qos_latched(100))
    readers = gate.get_subscription_count()

    def fault(kind):
        for nm in NAMES:
            gate.publish(String(data=json.dumps({'t': 0.0, 'kind': kind, 'agent': nm})))
    fault('freeze')
    def up():                                           # each agent ticks
        return all(_said(seen, 'robot_stopped', nm) for nm in NAMES)
    assert spin_for(ex, lambda: up() and gate.get_subscription_count() >= readers + len(NAMES), 60.0), (
        [(e.get('agent'), e['kind']) for e in seen['events']], _logs(tmp_path))
    spin_for(ex, lambda: False, 0.5)                    # the latched freezes delivered
    robots = start_robots()
    assert spin_for(ex, lambda: all(seen['odom'].values()), 60.0), {nm: len(o) for nm, o in seen['odom'].items()}
    spin_for(ex, lambda: False, 1.0)                    # each agent has its robot's odometry, paused
    assert not any(_said(seen, 'robot_resumed', nm) for nm in NAMES), seen['events']   # the freeze held
    n_events = len(seen['events'])
    fault('resume')
    assert spin_for(ex, lambda: all(_said(seen, 'robot_resumed', nm, n_events) for nm in NAMES), 30.0), (
        seen['events'][n_events:], _logs(tmp_path))
    return robots, {nm: _said(seen, 'robot_resumed', nm, n_events)[0]['t'] for nm in NAMES}


def test_three_agents_drive_standin_robots_and_stop_without_odometry(tmp_path, processes, rclpy_context):
    from swarm_ros.rosutil import make_executor
    from tests.helpers import spin_for
    _, scn = _scenario_file(tmp_path / 'robots3.yaml', 0.1, 1000.0, L, V0)
    probe, seen = _probe(rclpy_context)
    ex = make_executor(rclpy_context)
    ex.add_node(probe)
    _start_agents(processes, scn, tmp_path)
    robots, went = _start_together(ex, probe, seen, lambda: {
        nm: processes.start([sys.executable, FAKES / 'diff_drive_standin.py', nm],
                            stdout=open(tmp_path / f'{nm}-robot.log', 'w'),
                            stderr=open(tmp_path / f'{nm}-robot.err', 'w'))
        for nm in NAMES}, tmp_path)

    t_go = time.monotonic()
    spin_for(ex, lambda: False, 12.0)
    # the robots drove at v0 (0.2 m/s = 1 unit/s: about 12 units of path in 12 s) and kept together
    last = {nm: seen['states'][nm][-1] for nm in NAMES}
    for nm in NAMES:
        path = np.array([s[1:] for s in seen['states'][nm] if s[0] >= t_go])
        length = float(np.sum(np.hypot(*np.diff(path, axis=0).T)))
        assert 8.0 < length < 13.0, (nm, length, [(e['agent'], e['kind'], e.get('reason')) for e in seen['events']])
    pos = np.array([last[nm][1:] for nm in NAMES])
    gaps = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
    assert gaps.max() < 4.0, (gaps, went)                # within w = 4 of each other
    # the commands: v0 forward, stamped, frame <agent>/base_link; odometry in the controller's frames
    cmds = [c for c in seen['cmd'] if c[0] >= t_go]
    assert cmds and all(c[1] == pytest.approx(V0) and abs(c[2]) <= 2.84 and c[3] == 'agent_0/base_link' for c in cmds)
    assert seen['odom']['agent_0'][-1][1:3] == ('agent_0/odom', 'agent_0/base_link')

    # cut agent_0's odometry: its controller stands still (SIGSTOP)
    n_events = len(seen['events'])
    os.killpg(robots['agent_0'].pid, signal.SIGSTOP)
    t_cut = time.monotonic()
    try:
        def stopped():
            return _said(seen, 'robot_stopped', 'agent_0', n_events)
        assert spin_for(ex, lambda: bool(stopped()), 10.0), seen['events'][n_events:]
        assert 'odometry' in stopped()[0]['reason'] and 'old' in stopped()[0]['reason']
        spin_for(ex, lambda: False, 1.0)
        t_stop = time.monotonic()
        spin_for(ex, lambda: False, 1.0)
        zero = [c for c in seen['cmd'] if c[0] > t_stop]
        assert zero and all(c[1] == 0.0 and c[2] == 0.0 for c in zero), zero[:5]
        assert time.monotonic() - t_cut < 10.0
    finally:
        os.killpg(robots['agent_0'].pid, signal.SIGCONT)
    n_events = len(seen['events'])
    assert spin_for(ex, lambda: bool(_said(seen, 'robot_resumed', 'agent_0', n_events)), 10.0), (
        seen['events'][n_events:])
    t_back = time.monotonic()
    spin_for(ex, lambda: False, 1.0)
    assert any(c[1] == pytest.approx(V0) for c in seen['cmd'] if c[0] > t_back)
    probe.destroy_node()


def _logs(tmp_path):
    return '\n'.join(f'--- {p.name}\n{p.read_text()[-2000:]}' for p in sorted(tmp_path.glob('*.err')))


class LockstepRobot:
    """A perfect unicycle that follows the lockstep contract: on a cmd_vel stamped t_n it
    drives (v, ω) for dt·L/v0 robot seconds and publishes its odometry (own odom frame from
    (0, 0, 0)) stamped t_(n+1)."""

    def __init__(self, node, name, dt, seconds):
        from geometry_msgs.msg import TwistStamped
        from nav_msgs.msg import Odometry
        from rclpy.qos import qos_profile_system_default
        self.dt, self.seconds = dt, seconds
        self.x = self.y = self.yaw = 0.0
        self.pub = node.create_publisher(Odometry, f'/{name}/odom', qos_profile_system_default)
        node.create_subscription(TwistStamped, f'/{name}/cmd_vel', self.on_cmd, qos_profile_system_default)
        self.commands = []

    def on_cmd(self, m):
        from nav_msgs.msg import Odometry

        from swarm_ros import protocol as P
        v, w, d = m.twist.linear.x, m.twist.angular.z, self.seconds
        self.commands.append((P.stamp_to_time(m.header.stamp), v, w))
        if abs(w) > 0:
            self.x += v / w * (math.sin(self.yaw + w * d) - math.sin(self.yaw))
            self.y -= v / w * (math.cos(self.yaw + w * d) - math.cos(self.yaw))
        else:
            self.x += v * d * math.cos(self.yaw)
            self.y += v * d * math.sin(self.yaw)
        self.yaw += w * d
        o = Odometry()
        n = P.step_of(P.stamp_to_time(m.header.stamp), self.dt)
        o.header.stamp.sec, o.header.stamp.nanosec = P.time_to_stamp((n + 1) * self.dt)
        o.pose.pose.position.x, o.pose.pose.position.y = self.x, self.y
        o.pose.pose.orientation.z, o.pose.pose.orientation.w = math.sin(self.yaw / 2), math.cos(self.yaw / 2)
        self.pub.publish(o)


def test_lockstep_mixed_swarm_with_perfect_robots_follows_the_kinematic_run(tmp_path, rclpy_context):
    """Lockstep, two robot agents (the contract's steps 2-4 against perfect unicycles in their
    own odom frames) beside a kinematic agent: the run is the batch engine's up to the
    rounding of metres and back (x·L/L), and each robot got one command per step, stamped t_n."""
    import rclpy

    from swarm_core.engine.reference import simulate
    from swarm_core.engine.trajectory import Trajectory
    from swarm_ros.rosutil import make_executor
    from swarm_tools.run.launch import build_nodes
    from swarm_tools.run.params import node_parameters
    from swarm_tools.run.robots import apply_robots
    from tests.helpers import spin_for
    path, scn = _scenario_file(tmp_path / 'mixed3.yaml', 0.05, 3.0, 0.3, 0.15)
    out = tmp_path / 'run'
    params = node_parameters(scn, str(path), 'lockstep', output_dir=str(out))
    apply_robots(params, scn, {'agent_0': 'external', 'agent_2': 'external'}, 'lockstep')
    world, commander, agents = build_nodes(params, rclpy_context, log=lambda *a, **k: None)
    host = rclpy.create_node('robots', context=rclpy_context)
    robots = [LockstepRobot(host, nm, scn.dt, scn.dt * 0.3 / 0.15) for nm in ('agent_0', 'agent_2')]
    ex = make_executor(rclpy_context)
    for nd in (world, commander, *agents, host):
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.done, 120.0) and world.failed is None
    ref = simulate(scn)
    got = Trajectory.load(out / 'trajectory.npz')
    np.testing.assert_allclose(got.r, ref.r, rtol=0, atol=1e-9)
    for rb in robots:
        stamps = [c[0] for c in rb.commands]
        assert stamps == pytest.approx([n * scn.dt for n in range(scn.steps + 1)])   # t_0 ... t_N
        assert all(c[1] == 0.15 for c in rb.commands)
    for nd in (world, commander, *agents, host):
        nd.destroy_node()


def test_a_robot_agent_needs_its_scale(rclpy_context):
    from swarm_agent.agent_node import AgentNode
    from swarm_core.scenario.loader import load
    from swarm_ros.rosutil import ParameterError
    from swarm_tools.run.params import agent_parameters
    from tests.helpers import overrides
    prm = dict(agent_parameters(load('homotopy_global'), 0, 'lockstep'), robot='external')
    with pytest.raises(ParameterError, match='length_scale and cruise_speed'):
        AgentNode('agent', namespace='agent_0', context=rclpy_context, parameter_overrides=overrides(prm))


@pytest.mark.parametrize('per, robots', [(1, NAMES), (3, NAMES[:2])])
def test_swarm_run_robots_external_drives_standins(per, robots, tmp_path, processes, ros_domain, swarm_cmd):
    """``swarm run --mode realtime --robots external``: the launcher starts no physics; the
    agents drive whatever serves their cmd_vel and odom (here the stand-ins), the sim clock
    runs at v0/L, and the run ends as one swarm with the robots' events in metrics.json.
    Also two robot agents and a kinematic one in one agent container (``per`` 3)."""
    import subprocess

    from swarm_core.engine.trajectory import Trajectory
    path, _ = _scenario_file(tmp_path / 'robots3.yaml', 0.1, 8.0, 0.3, 0.15)
    processes.start([sys.executable, FAKES / 'diff_drive_standin.py', *NAMES], stdout=subprocess.DEVNULL)
    out = tmp_path / 'run'
    run = processes.start([swarm_cmd, 'run', path, '--mode', 'realtime', '--robots', 'external:' + ','.join(robots),
                           '--agents-per-process', str(per), '--out', out, '--no-figure'],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    text = processes.communicate(run, 150)
    assert run.returncode == 0, text[-3000:]
    assert 'sim clock at 0.5 model s per wall s' in text and 'r0 = 0.45 m, w = 1.2 m' in text
    metrics = json.loads((out / 'metrics.json').read_text())['summary']
    assert metrics['final_clusters'] == 1
    resumed = {e['agent'] for e in metrics['events'] if e['kind'] == 'robot_resumed'}
    assert resumed == set(robots)
    assert f'{len(robots)} of 3 agents on robots' in text and (per == 1 or '3 agents per process' in text)
    r = Trajectory.load(out / 'trajectory.npz').r
    length = np.nansum(np.hypot(*np.diff(r, axis=0).transpose(2, 0, 1)), axis=0)
    assert np.all(length > 0.6 * 8.0) and np.all(length < 1.1 * 8.0), length    # about unit speed


def test_pause_event_stops_the_robot_and_bad_odometry_never_moves_the_agent(tmp_path, rclpy_context):
    """In one process: a lone realtime robot agent (no neighbour needed) fed odometry by hand.
    A jump and a NaN are rejected (its state stays at the last good pose); a pause event for it
    on /swarm/events stops its robot (zero cmd_vel, robot_stopped 'paused'), resume lets it go."""
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    from std_msgs.msg import String

    from swarm_agent.agent_node import AgentNode
    from swarm_ros import protocol as P
    from swarm_ros.rosutil import make_executor
    from swarm_tools.run.params import agent_parameters
    from swarm_tools.run.robots import robot_parameters
    from tests.helpers import overrides, spin_for
    _, scn = _scenario_file(tmp_path / 'one.yaml', 0.1, 100.0, L, V0)
    prm = dict(agent_parameters(scn, 0, 'realtime'), agent_names=['agent_0'], use_sim_time=False,
               **robot_parameters(scn.spec.robots, 'external', 'realtime'))
    agent = AgentNode('agent', namespace='agent_0', context=rclpy_context, parameter_overrides=overrides(prm))
    probe = rclpy.create_node('probe', context=rclpy_context)
    odom = probe.create_publisher(Odometry, '/agent_0/odom', 10)
    events = probe.create_publisher(String, P.EVENTS, P.qos_latched(100))
    cmds, evs = [], []
    probe.create_subscription(TwistStamped, '/agent_0/cmd_vel', cmds.append, 10)
    probe.create_subscription(String, P.EVENTS, lambda m: evs.append(json.loads(m.data)), P.qos_latched(100))
    ex = make_executor(rclpy_context)
    for nd in (agent, probe):
        ex.add_node(nd)

    def feed(x, y=0.0, seconds=0.5):
        m = Odometry()
        m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.orientation.w = x, y, 1.0
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            odom.publish(m)
            ex.spin_once(timeout_sec=0.02)

    def said():
        return [e for e in evs if e.get('node') == 'agent']       # the agent's events, not ours

    def kinds():
        return [e['kind'] for e in said()]

    assert spin_for(ex, lambda: odom.get_subscription_count() > 0)
    feed(0.02, seconds=1.0)
    assert 'robot_resumed' in kinds() and cmds[-1].twist.linear.x == pytest.approx(V0)
    th0 = scn.theta0[0]                 # the odom frame sits at the start pose: 0.02 m ahead, / L
    good = [0.1 * math.cos(th0), 0.1 * math.sin(th0)]
    assert agent.core.pos[0] == pytest.approx(good)
    feed(5.0, seconds=0.5)                                              # 5 m at once: a jump
    feed(float('nan'), seconds=0.5)
    assert agent.driver.link.guard.rejected > 0 and agent.core.pos[0] == pytest.approx(good)
    # only rejected odometry for 1 s: as good as none, the robot stands
    assert kinds()[-1] == 'robot_stopped' and 'odometry' in said()[-1]['reason']
    assert cmds[-1].twist.linear.x == 0.0
    feed(0.025, seconds=1.0)
    assert kinds()[-1] == 'robot_resumed'
    events.publish(String(data=json.dumps({'t': 0.0, 'kind': 'freeze', 'agent': 'agent_0', 'for': 5.0})))
    feed(0.03, seconds=1.0)
    assert kinds()[-1] == 'robot_stopped' and said()[-1]['reason'] == 'paused'
    assert cmds[-1].twist.linear.x == 0.0 and cmds[-1].twist.angular.z == 0.0
    events.publish(String(data=json.dumps({'t': 0.0, 'kind': 'resume', 'agent': 'agent_0'})))
    feed(0.04, seconds=1.0)
    assert kinds()[-1] == 'robot_resumed' and cmds[-1].twist.linear.x == pytest.approx(V0)
    for nd in (agent, probe):
        nd.destroy_node()


def test_standin_rate_limiter_bounds_acceleration_then_velocity():
    from tests.fakes.diff_drive_standin import limited
    assert limited(1.0, 0.0, 0.1, 0.22, 0.5) == pytest.approx(0.05)      # 0.5 m/s² over 0.1 s
    assert limited(1.0, 0.2, 0.1, 0.22, 0.5) == pytest.approx(0.22)      # then the velocity bound
    assert limited(-3.0, 0.0, 0.1, math.nan, math.nan) == -3.0            # NaN: no limit
