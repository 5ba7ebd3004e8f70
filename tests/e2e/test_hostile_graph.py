"""Hostile and faulty inputs on the ROS graph: a second run on the domain, spoofed and future
states, floods of bad values, a huge polygon, live verbs that cannot act, signals to processes
that are not the run's."""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import Point32, PointStamped, PolygonStamped
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64, Float64MultiArray, String

from swarm_agent.agent_node import AgentNode
from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.layouts import ProcessStates, Step
from swarm_ros.rosutil import make_executor
from swarm_ros.runinfo import run_json
from swarm_tools.run.launch import build_nodes
from swarm_tools.run.params import agent_parameters, node_parameters
from swarm_world.world_node import WorldNode
from tests.helpers import odom, overrides, short_homotopy, spin_for, two_agents


def test_hostile_publisher_during_a_realtime_run(tmp_path, rclpy_context):
    """During a short realtime run a probe publishes future and duplicate states, NaN / inf
    states (on /swarm/states, which only the recorder and tools read, and as a process's batch
    on /swarm/agent_states, which the world, commander and agents read), a flood of bad λ and
    steering values, a NaN target and a 10,000-point polygon.
    Every node stays up (a callback exception would end the spin), every recorded state is
    finite, the spoofed states never enter the world's record, and each node logs at most a
    couple of lines per kind of rejection."""
    path = short_homotopy(tmp_path / 'rt.yaml', duration=6.0, lam='{kind: constant, value: 0.0}', at=100.0)
    scn = load(str(path))
    params = node_parameters(scn, str(path), 'realtime', rtf=5.0)
    ctx = rclpy_context
    world, commander, agents = build_nodes(params, ctx, log=lambda *a, **k: None)
    probe = rclpy.create_node('probe', context=ctx)
    states = probe.create_publisher(Odometry, P.STATES, P.qos_latched(10))
    batches = probe.create_publisher(Float64MultiArray, P.AGENT_STATES, P.qos_latched(10))
    lam = probe.create_publisher(Float64, P.LAMBDA, P.qos_reliable(100))
    steer = probe.create_publisher(Float64, P.steering_topic('agent_0'), P.qos_reliable(100))
    target = probe.create_publisher(PointStamped, P.TARGET, P.qos_latched())
    barrier = probe.create_publisher(PolygonStamped, P.BARRIER, P.qos_latched())
    ex = make_executor(ctx)
    nodes = [world, commander, *agents, probe]
    for nd in nodes:
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.started and world.sim_t > 1.0, 90.0)
    now = world.sim_t
    states.publish(odom('agent_4', 900.0, 900.0, 0.0, 500.0))          # far in the future
    states.publish(odom('agent_3', 777.0, 777.0, 0.0, now + 0.5))      # a second agent_3
    states.publish(odom('agent_2', float('nan'), 0.0, 0.0, now))
    states.publish(odom('agent_1', float('inf'), 0.0, 0.0, now))

    def batch(i, x, t):          # a state of agent i from the probe's "process"
        return ProcessStates(31.0, [i], [t], np.array([[x], [x], [0.0], [1.0]]), [0.0]).to_cdr(world.run_id)
    batches.publish(batch(4, 900.0, 500.0))
    batches.publish(batch(3, 777.0, now + 0.5))
    batches.publish(batch(2, float('nan'), now))
    for i in range(2000):
        lam.publish(Float64(data=(float('nan'), float('inf'), 2.0 + i, -1.0 - i)[i % 4]))
        if i % 10 == 0:
            steer.publish(Float64(data=float('nan') if i % 20 else float('-inf')))
    pt = PointStamped()
    pt.point.x = float('nan')
    target.publish(pt)
    poly = PolygonStamped()
    poly.polygon.points = [Point32(x=float(math.cos(a)), y=float(math.sin(a)))
                           for a in np.linspace(0, 2 * np.pi, 10_000, endpoint=False)]
    barrier.publish(poly)
    assert spin_for(ex, lambda: world.done, 120.0)
    assert world.failed is None
    # the spoofs never got in: agent_4's newest is the true one, agent_3 never at 777
    assert world.driver.newest['agent_4'][0] < 100.0
    assert not np.any(world.rec.r == 777.0) and not np.any(world.rec.r == 900.0)
    assert not np.any(np.abs(commander.pos) > 700.0)          # the commander's view neither
    tr = world.trajectory()
    assert np.all(np.isfinite(tr.r)) and np.all(np.isfinite(tr.theta))
    for a in agents:
        assert np.all(np.isfinite(a.core.pos)) and np.isfinite(a.core.theta).all()
        assert a.lam == 0.0 and a.steering == 0.0 and a.target is None
        assert a.barrier is None or len(a.barrier) < 100
    assert {'future-stamp', 'second-publisher', 'non-finite'} <= set(world.reject.kinds), world.reject.lines
    # the flood overruns the readers' KEEP_LAST queues (depth 10-100): many arrive, not all
    assert commander.reject.count >= 20 and set(commander.reject.kinds) >= {'lambda', 'steer'}
    # agents read only the commander's λ and steering (transient-local; docs/commands.md): the raw
    # flood never reaches them, the bad target and barrier do
    assert {'target', 'barrier-size'} <= set(agents[0].reject.kinds), agents[0].reject.lines
    for nd in [world, commander, *agents]:
        # one line per kind, one more per kind per 10 s of rejections (a 2,000-message flood included)
        assert len(nd.reject.lines) <= 2 * len(nd.reject.kinds), (nd.get_name(), nd.reject.lines)
    for nd in nodes:
        nd.destroy_node()


def test_a_second_run_on_the_domain_is_refused_and_lockstep_messages_of_another_run_rejected(rclpy_context):
    """A world that hears another run's /swarm/run refuses to start with one line naming it; an
    agent and a commander with a run id reject lockstep messages of another run (and take
    their own run's)."""
    ctx = rclpy_context
    ex = make_executor(ctx)
    other = rclpy.create_node('other_world', context=ctx)
    pub = other.create_publisher(String, P.RUN, P.qos_latched())
    pub.publish(String(data=run_json('aaaa1111', 'homotopy_global', 'lockstep', ['agent_0'], 1.0)))
    world = WorldNode(context=ctx, parameter_overrides=overrides(dict(scenario='homotopy_global', duration=1.0,
                                                                      run_id='bbbb2222')),
                      log=lambda *a, **k: None)
    scn = load('homotopy_global')
    agent = AgentNode('agent', namespace='agent_0', context=ctx, parameter_overrides=overrides(
        dict(agent_parameters(scn, 0, 'lockstep'), run_id='bbbb2222', use_sim_time=False)))
    for nd in (other, world, agent):
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.done, 30.0)
    assert not world.started
    assert 'another swarm run' in world.failed and 'aaaa1111' in world.failed and 'ROS_DOMAIN_ID' in world.failed
    # an agent of run bbbb2222 is handed a step of run aaaa1111: rejected, it does not move
    n = len(scn.names)
    quat = [np.sin(scn.theta0 / 2), np.cos(scn.theta0 / 2)]
    data = Step(0, 0.0, 0.0, np.zeros(n, bool), np.zeros(n), scn.pos0[:, 0], scn.pos0[:, 1],
                quat[0], quat[1], np.zeros(n), np.ones(n, bool), None, None, None)
    agent.driver.on_input(data.to_cdr('aaaa1111'))
    assert agent.step == 0 and agent.reject.kinds.get('other-run')
    agent.driver.on_input(data.to_cdr('bbbb2222'))
    assert agent.step == 1
    from homotopy_commander.commander_node import CommanderNode
    cmd = CommanderNode(context=ctx, parameter_overrides=overrides(dict(scenario='homotopy_global',
                                                                        run_id='bbbb2222')))
    cmd._on_step(data.to_cdr('aaaa1111'))              # the commander takes the record from the steps
    assert cmd.decisions == 0 and 'other-run' in cmd.reject.kinds
    cmd._on_step(data.to_cdr('bbbb2222'))
    assert cmd.decisions == 1
    for nd in (other, world, agent, cmd):
        nd.destroy_node()


def test_world_signals_only_its_launchers_agent_children(tmp_path, rclpy_context):
    """A pid file naming a process that is not a child of the world's launcher (here: a child
    of the test) gets no signal: the world logs one line and the process lives on."""
    victim = subprocess.Popen(['sleep', '60'])
    try:
        pids = tmp_path / 'pids.json'
        pids.write_text(json.dumps({'agent_1': victim.pid}))
        world = WorldNode(context=rclpy_context, parameter_overrides=overrides(dict(
            scenario='homotopy_global', duration=1.0, pid_file=str(pids))), log=lambda *a, **k: None)
        world.signal_agent(1, signal.SIGKILL)
        world.signal_agent(1, signal.SIGSTOP)
        time.sleep(0.2)
        assert victim.poll() is None
        with open(f'/proc/{victim.pid}/stat') as f:
            assert f.read().split(') ')[1][0] != 'T'             # not stopped either
        assert world.reject.kinds.get('signal') and 'not a child' in world.reject.lines[-1]
        world.destroy_node()
    finally:
        victim.kill()
        victim.wait()


class Spinner:
    """Spins nodes in a thread until stopped (a swarm for a CLI subprocess to find)."""

    def __init__(self, ctx, nodes):
        self.ex = make_executor(ctx)
        for nd in nodes:
            self.ex.add_node(nd)
        self.stop = False
        self.t = threading.Thread(target=lambda: spin_for(self.ex, lambda: self.stop, 300.0), daemon=True)
        self.t.start()

    def close(self):
        self.stop = True
        self.t.join(10)


def test_live_verbs_that_cannot_act_exit_nonzero_and_name_the_run(rclpy_context, swarm_cmd, processes):
    """`swarm kill ghost` / `swarm kill agent_99` exit 2 with the reason (they exited 0 and the
    refusal was only in the world's log); a good name says which run was reached; with a
    second run announced on the domain every verb refuses alike (exit 1) naming both, and the
    world does not stop for it."""
    from homotopy_commander.commander_node import CommanderNode
    ps = overrides(dict(scenario='homotopy_global', duration=1.0, run_id='c0ffee00'))
    world = WorldNode(context=rclpy_context, parameter_overrides=ps, log=lambda *a, **k: None)
    commander = CommanderNode(context=rclpy_context, parameter_overrides=ps)
    sp = Spinner(rclpy_context, [world, commander])
    env = dict(os.environ)

    def run(*verbs):
        """The verbs as CLI processes side by side (each its own participant, as from several
        shells); [(exit code, output)] in order."""
        ps = [processes.start([swarm_cmd, *args, '--wait', '60'], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, env=env) for args in verbs]
        return [(p, processes.communicate(p, 120)) for p in ps]
    try:
        *kills, (p, out) = run(('kill', 'ghost'), ('kill', 'agent_99'), ('pause', 'agent_1', '1.5'))
        for name, (k, said) in zip(('ghost', 'agent_99'), kills):
            assert k.returncode == 2, said
            assert f"unknown agent '{name}'" in said and 'run c0ffee00' in said, said
        assert p.returncode == 0, out
        assert 'reached run c0ffee00 (homotopy_global, lockstep, 6 agents)' in out, out
        other = rclpy.create_node('other_world', context=rclpy_context)
        pub = other.create_publisher(String, P.RUN, P.qos_latched())
        # a younger run (an older one would make this world, not yet started, give way)
        pub.publish(String(data=run_json('deadbeef', 'x', 'realtime', ['agent_1'], time.time() + 1e6)))
        sp.close()
        sp = Spinner(rclpy_context, [world, commander, other])
        verbs = (('kill', 'agent_1'), ('pause', 'agent_1', '1'), ('lambda', '0.5'), ('steer', 'agent_0', '0.01'))
        for verb, (p, out) in zip(verbs, run(*verbs)):
            assert p.returncode == 1, (verb, out)
            assert '2 runs share this ROS_DOMAIN_ID' in out and 'c0ffee00' in out and 'deadbeef' in out, out
        assert not world.done and world.failed is None
        # a fake announcer as `ros2 topic pub -r 1` (volatile: a transient-local reader never
        # hears it): the verbs still refuse, alike
        other.destroy_publisher(pub)
        vol = other.create_publisher(String, P.RUN, 10)
        other.create_timer(1.0, lambda: vol.publish(String(data=run_json('deadbeef', 'x', 'realtime', ['agent_1'],
                                                                          1.0))))
        # one at a time: a verb decides once every writer it has discovered is heard, and
        # several participants discovering at once on a loaded machine widen that race
        for verb in (('kill', 'agent_1'), ('lambda', '0.5'), ('steer', 'agent_0', '0.01')):
            [(p, out)] = run(verb)
            assert p.returncode == 1 and '2 writers announce runs' in out, (verb, out)
        assert not world.done
    finally:
        sp.close()


@pytest.mark.refuses_inputs      # two runs on one domain: each refuses the other's messages (other-run)
def test_a_second_swarm_run_on_the_domain_refuses_and_the_first_is_not_mixed(tmp_path, ros_domain, processes,
                                                                             swarm_cmd, monkeypatch):
    """Run A (in one process) is going; run B (processes) on the same ROS_DOMAIN_ID refuses to
    start with one line naming A (it used to follow A's world and fail with "discovery timed
    out"); A goes on, equal to `swarm simulate` bit for bit, so nothing of B got in."""
    from swarm_core.engine.reference import Trajectory, simulate
    from swarm_ros.runinfo import SETTLE_ENV
    from tests.helpers import Lines
    # the worlds listen for another run, as by default, but longer: under a loaded suite B's world
    # once heard no sign of A within the default 3 s (B stops as soon as it hears A)
    monkeypatch.setenv(SETTLE_ENV, '12')
    a = processes.start([swarm_cmd, 'run', 'homotopy_global', '--in-process', '--out', tmp_path / 'a',
                         '--no-figure', '--progress-every', '5'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(a)
    assert lines.wait_for('[world] t=    5.00', 180), ''.join(lines.lines)
    run_a = next(ln.split()[3].rstrip(':') for ln in lines.lines if ln.startswith('swarm run: run '))
    two_agents(tmp_path / 'two.yaml', 20)
    b = processes.start([swarm_cmd, 'run', tmp_path / 'two.yaml', '--out', tmp_path / 'b', '--no-figure'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out = processes.communicate(b, 180)
    assert b.returncode == 1, out
    assert f'another swarm run is on ROS_DOMAIN_ID={ros_domain} (run {run_a} (homotopy_global' in out, out
    assert 'discovery timed out' not in out
    n_seen = len(lines.lines)                    # A goes on: one more progress line
    assert a.poll() is None
    end = time.monotonic() + 120
    while len([ln for ln in lines.lines[n_seen:] if ln.startswith('[world] t=')]) < 1 and time.monotonic() < end:
        time.sleep(0.2)
    os.kill(a.pid, signal.SIGINT)
    assert a.wait(timeout=60) == 130, ''.join(lines.lines[-20:])
    got = Trajectory.load(tmp_path / 'a' / 'trajectory.npz')
    n = len(got.t)
    ref = simulate(load('homotopy_global', duration=(n - 1) * load('homotopy_global').dt))
    assert np.abs(got.r - ref.r[:n]).max() <= 1e-9 and np.abs(got.u - ref.u[:n]).max() <= 1e-9


def test_world_rejects_future_and_second_publisher_states(rclpy_context):
    """The two reproduced take-overs, at the world (realtime, the processes' batches of states
    fed as raw bytes): a state stamped far in the future made every true state after it
    "older" (rejected for 30 s); a second process sending agent_3 with a slightly later stamp
    replaced its true position."""
    world = WorldNode(context=rclpy_context, parameter_overrides=overrides(dict(
        scenario='homotopy_global', duration=5.0, mode='realtime')), log=lambda *a, **k: None)

    def batch(tag, i, t, x, y):
        return ProcessStates(tag, [i], [t], np.array([[x], [y], [0.0], [1.0]]), [0.0]).to_cdr(world.run_id)
    world.driver.on_states(batch(1234.0, 3, 0.0, 1.0, 2.0))
    world.driver.on_states(batch(77.0, 4, 500.0, 9.0, 9.0))                  # t = 500
    world.driver.on_states(batch(99.0, 3, 0.05, 777.0, 777.0))               # a second process for agent_3
    world.driver.on_states(batch(5.0, 4, 0.1, 3.0, 4.0))
    assert world.driver.newest['agent_3'][:3] == (0.0, 1.0, 2.0)
    assert world.driver.newest['agent_4'][:3] == (0.1, 3.0, 4.0)
    assert {'future-stamp', 'second-publisher'} <= set(world.reject.kinds), world.reject.lines
    world.destroy_node()
