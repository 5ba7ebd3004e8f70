"""Robot agents against a stand-in for diff_drive_controller (tests/diff_drive_standin.py):
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

pytestmark = pytest.mark.ros

HERE = Path(__file__).resolve().parent
NAMES = ['agent_0', 'agent_1', 'agent_2']
L = V0 = 0.2          # L / v0 = 1: a model second is a robot second (and, here, a wall second)


def _scenario(tmp_path):
    from swarm_core.scenario import parse
    return parse({'name': 'robots3', 'dt': 0.1, 'duration': 1000.0,
                  'agents': {'positions': [[0, 0], [1.5, 0], [0.75, 1.3]],
                             'headings': {'rule': 'cone', 'half_width': 0.5}},
                  'law': {'kind': 'global', 'alpha': 0.5, 'eta': 0.5, 'r0': 1.5},
                  'robots': {'length_scale': L, 'cruise_speed': V0, 'odom_timeout': 0.5}})


def _start_agents(processes, scn, tmp_path):
    """Agent processes on the wall clock (no world: the sim clock is the system clock)."""
    from swarm_tools.node_params import node_parameters, write_params_file
    from swarm_tools.robot_plan import apply_robots
    params = node_parameters(scn, 'robots3', 'realtime')
    apply_robots(params, scn, {nm: 'external' for nm in NAMES}, 'realtime')
    agents = {k: dict(v, use_sim_time=False, robot_clock='wall') for k, v in params.items() if k.endswith('/agent')}
    pfile = write_params_file(agents, tmp_path / 'params.yaml')
    exe = Path(sys.executable).parent / 'swarm_agent'
    return [processes.start([exe, '--ros-args', '--params-file', pfile, '-r', '__node:=agent', '-r', f'__ns:=/{nm}'],
                            stdout=open(tmp_path / f'{nm}.log', 'w'), stderr=open(tmp_path / f'{nm}.err', 'w'))
            for nm in NAMES]


def _probe(ctx):
    """A node that hears the agents' states, events and agent_0's commands."""
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    from rclpy.qos import qos_profile_system_default
    from std_msgs.msg import String

    from swarm_ros import protocol as P
    node = rclpy.create_node('probe', context=ctx)
    seen = {'states': {nm: [] for nm in NAMES}, 'events': [], 'cmd': [], 'odom': []}
    node.create_subscription(Odometry, P.STATES, lambda m: seen['states'][m.child_frame_id].append(
        (time.monotonic(), m.pose.pose.position.x, m.pose.pose.position.y)), P.qos_latched(100))
    node.create_subscription(String, P.EVENTS, lambda m: seen['events'].append(json.loads(m.data)),
                             P.qos_latched(100))
    node.create_subscription(TwistStamped, '/agent_0/cmd_vel', lambda m: seen['cmd'].append(
        (time.monotonic(), m.twist.linear.x, m.twist.angular.z, m.header.frame_id)), qos_profile_system_default)
    node.create_subscription(Odometry, '/agent_0/odom', lambda m: seen['odom'].append(
        (time.monotonic(), m.header.frame_id, m.child_frame_id, m.pose.pose.position.x)), qos_profile_system_default)
    return node, seen


def test_three_agents_drive_standin_robots_and_stop_without_odometry(tmp_path, processes, rclpy_context):
    from swarm_ros.rosutil import make_executor
    from conftest import spin_for
    scn = _scenario(tmp_path)
    robots = {nm: processes.start([sys.executable, HERE / 'diff_drive_standin.py', nm],
                                  stdout=open(tmp_path / f'{nm}-robot.log', 'w'), stderr=open(tmp_path / f'{nm}-robot.err', 'w'))
              for nm in NAMES}
    _start_agents(processes, scn, tmp_path)
    probe, seen = _probe(rclpy_context)
    ex = make_executor(rclpy_context)
    ex.add_node(probe)

    def resumed(nm, after=0):
        return any(e.get('kind') == 'robot_resumed' and e.get('agent') == nm for e in seen['events'][after:])

    assert spin_for(ex, lambda: all(resumed(nm) for nm in NAMES), 60.0), (
        [(e['agent'], e['kind']) for e in seen['events']], len(seen['odom']), _logs(tmp_path))
    t_go = time.monotonic()
    spin_for(ex, lambda: False, 12.0)
    # the robots moved at v0 (0.2 m/s = 1 unit/s) and kept together: one swarm
    last = {nm: seen['states'][nm][-1] for nm in NAMES}
    first = {nm: next(s for s in seen['states'][nm] if s[0] >= t_go) for nm in NAMES}
    for nm in NAMES:
        moved = math.hypot(last[nm][1] - first[nm][1], last[nm][2] - first[nm][2])
        assert 4.0 < moved < 13.0, (nm, moved)           # 12 s at ≤ 1 unit/s, on curves
    pos = np.array([last[nm][1:] for nm in NAMES])
    gaps = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
    assert gaps.max() < 4.0, gaps                        # within w = 4 of each other
    # the commands: v0 forward, stamped, frame <agent>/base_link; odometry in the controller's frames
    cmds = [c for c in seen['cmd'] if c[0] >= t_go]
    assert cmds and all(c[1] == pytest.approx(V0) and abs(c[2]) <= 2.84 and c[3] == 'agent_0/base_link' for c in cmds)
    assert seen['odom'][-1][1:3] == ('agent_0/odom', 'agent_0/base_link')

    # cut agent_0's odometry: its controller stands still (SIGSTOP)
    n_events = len(seen['events'])
    os.killpg(robots['agent_0'].pid, signal.SIGSTOP)
    t_cut = time.monotonic()
    try:
        stopped = lambda: [e for e in seen['events'][n_events:]  # noqa: E731
                           if e.get('kind') == 'robot_stopped' and e.get('agent') == 'agent_0']
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
    assert spin_for(ex, lambda: resumed('agent_0', n_events), 10.0), seen['events'][n_events:]
    t_back = time.monotonic()
    spin_for(ex, lambda: False, 1.0)
    assert any(c[1] == pytest.approx(V0) for c in seen['cmd'] if c[0] > t_back)
    probe.destroy_node()


def _logs(tmp_path):
    return '\n'.join(f'--- {p.name}\n{p.read_text()[-2000:]}' for p in sorted(tmp_path.glob('*.err')))
