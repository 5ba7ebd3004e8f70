"""The start-up race of lockstep robot runs, made deterministic: the robot world's readers match
only after every robot agent has sent its command of step 0 (the robot world's report of t_0
can reach the world before its ``cmd_vel`` readers have matched the agents' writers; here the
report of t_0 comes from the test, and the robot world's node is created only after the
commands, in a context of its own as in a process of its own).  Each command is sent once and
the robot world holds a step until it has every one: with a volatile cmd_vel the late reader
never got them, no pose of t_1 came, and the world lost every agent at step 1.  One process,
the test's own ROS_DOMAIN_ID; the robot world on MuJoCo."""
import time

import numpy as np
import rclpy
from std_msgs.msg import Float64MultiArray

from swarm_core.engine.trajectory import Trajectory
from swarm_core.model.frenet import quaternion_from_heading
from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.layouts import RobotStates
from swarm_ros.rosutil import make_executor
from swarm_tools.run.launch import build_nodes, robots_nodes
from swarm_tools.run.params import node_parameters
from swarm_tools.run.robots import (
    add_robot_world,
    apply_robots,
)
from tests.helpers import short_homotopy

ROBOTS = {'length_scale': 0.3, 'cruise_speed': 0.15, 'frame': 'odom'}


def spin_both(executors, cond, timeout):
    """Spin each executor in turn until ``cond()`` or ``timeout`` s; returns cond()."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        for ex in executors:
            ex.spin_once(timeout_sec=0.02)
    return cond()


def test_a_robot_world_matched_after_the_first_commands_still_gets_them(tmp_path, rclpy_context, ros_domain,
                                                                       monkeypatch):
    from rclpy.context import Context

    from swarm_robots import mujoco_world_node
    from swarm_robots.engine import simulate as robot_simulate
    # the test's report of t_0 stands in for the robot world's: the same sender tag (the world
    # binds /lockstep/robot_states to the first it takes)
    monkeypatch.setattr(mujoco_world_node, 'new_sender_tag', lambda: 7.0)
    path = short_homotopy(tmp_path / 'late.yaml', robots=ROBOTS, duration=1, lam='{kind: constant, value: 0}', at=0.5)
    scn = load(str(path))
    out = tmp_path / 'run'
    params = node_parameters(scn, str(path), 'lockstep', output_dir=str(out))
    params['/world']['missing_timeout'] = 4.0           # a stall ends in seconds
    robots = {nm: 'mujoco' for nm in scn.names}
    apply_robots(params, scn, robots, 'lockstep')
    for p in params.values():
        p['run_id'] = 'late0001'                         # as swarm run sets it, before the robot world's
    add_robot_world(params, robots)
    world, commander, agents = build_nodes(params, rclpy_context, log=lambda *a, **k: None)
    nodes = [world, commander, *agents]
    ex = make_executor(rclpy_context)
    for nd in nodes:
        ex.add_node(nd)
    late_ctx = Context()
    rclpy.init(context=late_ctx, domain_id=ros_domain)
    late = []
    helper = rclpy.create_node('report_of_t0', context=rclpy_context)
    nodes.append(helper)
    report = helper.create_publisher(Float64MultiArray, P.LOCK_ROBOT_STATES, P.qos_latched())
    rows = list(range(len(scn.names)))
    report.publish(RobotStates(0, 7.0, rows, np.stack([*scn.pos0.T, *quaternion_from_heading(scn.theta0)]))
                   .to_cdr('late0001'))
    try:
        # the world starts without the robot world (the test reports t_0): each agent sends its
        # command of step 0, and the world waits for the robots' poses of t_1
        assert spin_both([ex], lambda: all(a.step == 1 for a in agents), 60)
        assert world.driver.lock.cur == 1 and not world.driver.lock.complete()
        late = robots_nodes(params, late_ctx)
        late_ex = make_executor(late_ctx)
        late_ex.add_node(late[0])
        assert spin_both([ex, late_ex], lambda: world.done, 120), 'stalled'
        assert world.failed is None, world.failed
        assert late[0].hold.ignored == 0
    finally:
        for nd in nodes + late:
            nd.destroy_node()
        rclpy.shutdown(context=late_ctx)
    # as if the robot world had been there from the start: the robot engine's run, bit for bit
    got = Trajectory.load(out / 'trajectory.npz')
    ref = robot_simulate(scn, 'all')
    np.testing.assert_array_equal(got.r, ref.r)
    np.testing.assert_array_equal(got.u, ref.u)
