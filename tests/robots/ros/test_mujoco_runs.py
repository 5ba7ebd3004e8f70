"""End-to-end: `swarm run --robots mujoco`: the agents drive differential-drive robots of the
run's MuJoCo world through cmd_vel and odometry, in lockstep (deterministic: the same run twice
gives the same trajectories), with λ raised mid-run (the swarm splits), mixed with kinematic
agents (one swarm), with a frozen and a killed robot agent, and equal to the study engine on
robots (`swarm_robots.engine`) bit for bit.  Every process a test starts is gone after it
(`processes`)."""
import json
import subprocess

import numpy as np
import pytest

from swarm_core.analysis.metrics import cluster_labels
from swarm_core.engine.trajectory import Trajectory
from tests.helpers import Lines, short_homotopy

#: L = 0.3 m per model unit at v0 = 0.15 m/s (a TurtleBot3 Burger's top speed is 0.22 m/s):
#: r0 = 0.45 m, w = 1.2 m; one model second is 2 robot seconds
ROBOTS = {'length_scale': 0.3, 'cruise_speed': 0.15, 'frame': 'odom'}
#: leaders at t = 5 steering ±0.05, λ up from t = 15: measured with the batch engine, the six
#: agents are one swarm until t ≈ 20 and two from t ≈ 30 on
SPLIT = dict(duration=60, lam='{kind: tanh_window, rise_at: 15, fall_at: 1000, tau: 3}', at=5, curvature=0.05)


def run(processes, swarm_cmd, path, out, *args, timeout=400):
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--progress-every', '20', *args],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, timeout) == 0, ''.join(lines.lines[-40:])
    return Trajectory.load(out / 'trajectory.npz'), json.loads((out / 'metrics.json').read_text()), lines


def clusters(traj, t, w=4.0):
    return cluster_labels(traj.r[int(round(t / (traj.t[1] - traj.t[0])))], w)[0]


def test_lockstep_six_robots_repeatable_and_split_by_lambda(tmp_path, ros_domain, processes, swarm_cmd):
    """Two short ROS runs (12 s) are equal, and equal the robot engine of studies
    (`swarm_robots.engine`) bit for bit; the split by λ is then checked on the engine's run of
    the same scenario to t = 60 (600 robot steps, a few CPU seconds instead of two ROS runs)."""
    from swarm_core.scenario import loader as scenario
    from swarm_robots.engine import simulate as robot_simulate
    path = short_homotopy(tmp_path / 'robots.yaml', robots=ROBOTS, **dict(SPLIT, duration=12))
    a, metrics, lines = run(processes, swarm_cmd, path, tmp_path / 'a', '--robots', 'mujoco')
    assert any('6 of 6 agents on robots (mujoco)' in ln for ln in lines.lines)
    b, _, _ = run(processes, swarm_cmd, path, tmp_path / 'b', '--robots', 'mujoco')
    # the same commands at the same robot times: the same physics, bit for bit
    np.testing.assert_array_equal(a.r, b.r)
    np.testing.assert_array_equal(a.theta, b.theta)
    np.testing.assert_array_equal(a.u, b.u)
    ours = robot_simulate(scenario.load(str(path)), 'all')
    np.testing.assert_array_equal(a.r, ours.r)
    np.testing.assert_array_equal(a.u, ours.u)
    # robots, not kinematic points: they start from rest and accelerate to v0
    speed = np.linalg.norm(np.diff(a.r, axis=0), axis=2) / (a.t[1] - a.t[0])
    assert speed[0].max() < 0.5 and np.abs(speed[20:] - 1.0).max() < 0.05
    robots = metrics['summary']['robots']
    assert sorted(robots['limit_seconds']) == sorted(robots['turn_limit_seconds']) == [f'agent_{i}' for i in range(6)]
    full = robot_simulate(scenario.load(str(short_homotopy(tmp_path / 'long.yaml', robots=ROBOTS, **SPLIT))), 'all')
    assert clusters(full, 10) == 1 and clusters(full, 60) >= 2


def test_swarm_run_starts_the_robot_world_and_keeps_its_summary(tmp_path, ros_domain, processes, swarm_cmd):
    path = short_homotopy(tmp_path / 'short.yaml', robots=ROBOTS, duration=2, lam='{kind: constant, value: 0}', at=1)
    traj, metrics, lines = run(processes, swarm_cmd, path, tmp_path / 'r', '--robots', 'mujoco:agent_4', timeout=200)
    assert any('9 processes' in ln for ln in lines.lines), ''.join(lines.lines)     # + the robot world
    assert any('[robots]: 1 robots (lockstep)' in ln for ln in lines.lines)
    robots = metrics['summary']['robots']
    assert robots['robots'] == ['agent_4'] and robots['contacts'] == 0
    assert json.loads((tmp_path / 'r' / 'robots.json').read_text()) == robots
    assert len(traj.t) == 41


def test_mixed_run_three_robots_three_kinematic_one_swarm(tmp_path, ros_domain, processes, swarm_cmd):
    path = short_homotopy(tmp_path / 'mixed.yaml', robots=ROBOTS, duration=40, lam='{kind: constant, value: 0}', at=5)
    traj, metrics, lines = run(processes, swarm_cmd, path, tmp_path / 'm', '--robots', 'mujoco:agent_0-agent_2')
    assert any('3 of 6 agents on robots (mujoco)' in ln for ln in lines.lines)
    assert sorted(metrics['summary']['robots']['limit_seconds']) == ['agent_0', 'agent_1', 'agent_2']
    dt = traj.t[1] - traj.t[0]
    speed = np.linalg.norm(np.diff(traj.r, axis=0), axis=2) / dt
    # the kinematic agents fly at unit speed (a chord of the arc: within 1e-5 at |u| < 0.2); the
    # robots start from rest and accelerate to v0
    assert np.abs(speed[:, 3:] - 1.0).max() < 1e-5
    assert speed[0, :3].max() < 0.5 and np.abs(speed[20:, :3] - 1.0).max() < 0.05
    assert all(clusters(traj, t) == 1 for t in (10, 20, 30, 40))
    heading = np.exp(1j * traj.theta[-1])
    assert abs(heading.mean()) > 0.9                       # one swarm, aligned
    assert metrics['summary']['robots']['contacts'] == 0


def test_robot_agents_in_one_container_equal_lone_processes(tmp_path, ros_domain, processes, swarm_cmd):
    """``--agents-per-process 6``: four robot agents and two kinematic ones in ONE agent
    container (its answer to the world waits for the robots' odometry) give the same run, bit
    for bit, as each agent a process of its own."""
    path = short_homotopy(tmp_path / 'contained.yaml', robots=ROBOTS, duration=8,
                          lam='{kind: tanh_window, rise_at: 3, fall_at: 1000, tau: 1}', at=2, curvature=0.05)
    robots = ('--robots', 'mujoco:agent_0-agent_3')
    one, _, lines = run(processes, swarm_cmd, path, tmp_path / 'one', *robots, '--agents-per-process', '6',
                        timeout=300)
    # one container, the world, the commander, the robot world
    assert any('4 processes' in ln for ln in lines.lines), ''.join(lines.lines)
    lone, _, _ = run(processes, swarm_cmd, path, tmp_path / 'lone', *robots, '--agents-per-process', '1', timeout=300)
    np.testing.assert_array_equal(one.r, lone.r)
    np.testing.assert_array_equal(one.theta, lone.theta)
    np.testing.assert_array_equal(one.u, lone.u)
    speed = np.linalg.norm(np.diff(one.r, axis=0), axis=2) / (one.t[1] - one.t[0])
    assert speed[0, :4].max() < 0.5 and np.abs(speed[:, 4:] - 1.0).max() < 1e-5   # robots and points
    assert np.abs(one.u).max() > 0.01                                              # the law steered



def test_a_lockstep_robot_run_with_a_freeze_and_a_kill(tmp_path, ros_domain, processes, swarm_cmd):
    """`swarm run --robots mujoco` with a frozen and a killed robot agent: the run goes on
    through both; the robot world learns of the kill from its event, so it does not wait the
    hold's time-out for the killed agent's command (the world kills right after a step went
    out); the frozen agent's rows hold its state, the killed agent's are NaN from its step."""
    path = short_homotopy(tmp_path / 'faults.yaml', robots=ROBOTS, duration=8, lam='{kind: constant, value: 0}',
                          at=1, faults=[{'at': 2, 'freeze': 'agent_1', 'for': 2.0}, {'at': 5, 'kill': 'agent_4'}])
    out = tmp_path / 'r'
    p = processes.start([swarm_cmd, 'run', str(path), '--out', str(out), '--no-figure', '--robots', 'mujoco'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    text = ''.join(lines.lines)
    assert 'agent_4 killed' in text and 'no command from' not in text, text[-3000:]
    tr = Trajectory.load(out / 'trajectory.npz')
    dt = tr.t[1] - tr.t[0]
    kill, freeze = round(5 / dt), round(2 / dt)
    assert np.isnan(tr.r[kill:, 4]).all() and np.isfinite(tr.r[:kill, 4]).all()
    held = tr.r[freeze:2 * freeze, 1]
    assert (held == tr.r[freeze, 1]).all() and (tr.r[2 * freeze + 2, 1] != tr.r[freeze, 1]).all()
    assert np.isfinite(tr.r[:, [0, 1, 2, 3, 5]]).all()


# ------------------------------------------------------------------ the study engine against the run
@pytest.mark.parametrize('per', [[], ['--agents-per-process', '3']], ids=['processes', 'containers'])
def test_the_robot_engine_equals_the_lockstep_run(per, tmp_path, ros_domain, processes, swarm_cmd):
    """`swarm run --robots mujoco:agent_0-agent_2` (lockstep: the robot world reports the robot
    agents' poses) and the engine, bit for bit; the three robot agents alone in their own
    processes, or sharing one container (the kinematic three in another)."""
    from swarm_core.engine.trajectory import unwrap_headings
    from swarm_core.model.frenet import quaternion_from_heading, yaw_from_quaternion
    from swarm_core.scenario import loader as scenario
    from swarm_robots.engine import simulate as robot_simulate
    path = short_homotopy(tmp_path / 'robots.yaml', robots=ROBOTS, duration=10,
                          lam='{kind: tanh_window, rise_at: 4, fall_at: 1000, tau: 2}', at=2, curvature=0.05)
    p = processes.start([swarm_cmd, 'run', str(path), '--out', str(tmp_path / 'r'), '--no-figure',
                         '--robots', 'mujoco:agent_0-agent_2', *per],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    ros = Trajectory.load(tmp_path / 'r' / 'trajectory.npz')
    scn = scenario.load(str(path))
    ours = robot_simulate(scn, 'half')
    np.testing.assert_array_equal(ros.r, ours.r)
    np.testing.assert_array_equal(ros.u, ours.u)
    np.testing.assert_array_equal(ros.lam, ours.lam)
    # the ROS run records headings as its messages carry them (a quaternion), unwrapped in time
    np.testing.assert_array_equal(ros.theta, unwrap_headings(
        yaw_from_quaternion(*quaternion_from_heading(ours.theta)), scn.theta0))
    robots = json.loads((tmp_path / 'r' / 'metrics.json').read_text())['summary']['robots']
    for k in ('robots', 'contacts', 'turn_limit_seconds', 'limit_seconds'):
        assert robots[k] == ours.meta['robots'][k]
