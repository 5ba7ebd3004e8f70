"""The world node (`swarm_world.world_node`) with rclpy executors, each test on its own
ROS_DOMAIN_ID and rclpy Context (fixtures in tests/conftest.py): bad states rejected, a step
that never completes, a run whose agents are all lost, and the leader slots of the
commander's events in realtime."""
import math

import numpy as np
import rclpy
from std_msgs.msg import Float64MultiArray, String

from swarm_agent.agent_node import AgentNode
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.layouts import AgentStates
from swarm_ros.rosutil import make_executor
from swarm_tools.run.params import node_parameters
from swarm_world.world_node import WorldNode
from tests.helpers import overrides, run_nodes, short_homotopy, spin_for


def test_bad_states_are_rejected_by_the_world(rclpy_context):
    """Lockstep: the world reads its agents' states from /lockstep/agent_states (one message per
    agent process).  An unknown agent, a NaN state, a second process claiming an agent, a state
    of a later step: one log line each; the record holds no NaN and the valid state is kept."""
    ctx = rclpy_context
    ex = make_executor(ctx)
    world = WorldNode(context=ctx, parameter_overrides=overrides(dict(scenario='homotopy_global', duration=1.0)),
                      log=lambda *a, **k: None)
    probe = rclpy.create_node('probe', context=ctx)
    pub = probe.create_publisher(Float64MultiArray, P.LOCK_AGENT_STATES, P.qos_latched())
    ex.add_node(world)
    ex.add_node(probe)
    assert spin_for(ex, lambda: pub.get_subscription_count() >= 1)
    qz, qw = math.sin(0.25), math.cos(0.25)

    def batch(tag, idx, step, x, y, u=0.0):
        return AgentStates(tag, [idx], [step], np.array([[x], [y], [qz], [qw]]), [u]).to_cdr()
    sent = [batch(1.0, 3, 0, 1.0, 2.0),                  # valid
            batch(1.0, 9, 0, 0.0, 0.0),                  # no agent 9 in a roster of 6
            batch(1.0, 4, 0, float('nan'), 0.0),         # NaN
            batch(2.0, 3, 0, 5.0, 5.0),                  # agent_3 from a second process
            batch(1.0, 5, 3, 0.0, 0.0),                  # a step the world is not at
            b'\x00\x01\x00\x00' + bytes(8)]            # a message with 0 values
    for m in sent:
        pub.publish(m)
        spin_for(ex, lambda: False, 0.2)
    assert spin_for(ex, lambda: len(world.reject.lines) >= 5)
    kinds = set(world.reject.kinds)
    assert {'unknown-agent', 'non-finite', 'second-publisher', 'step', 'state-decode'} <= kinds, world.reject.lines
    assert world.driver.lock.have.tolist() == [False, False, False, True, False, False]
    assert np.all(np.isfinite(world.driver.lock.buf))
    assert world.driver.lock.buf[0, 3] == 1.0 and world.driver.lock.buf[1, 3] == 2.0
    probe.destroy_node()


def test_world_does_not_start_without_the_commander_and_says_so(rclpy_context):
    """A commander node that reads the steps but never says it takes part (on /lockstep/command):
    the world does not start, and after start_timeout it stops with an error naming it."""
    scn = load('homotopy_global')
    ctx = rclpy_context
    ex = make_executor(ctx)
    params = node_parameters(scn, 'homotopy_global', 'lockstep', duration=1.0, extra_world=dict(start_timeout=2.0))
    world = WorldNode(context=ctx, parameter_overrides=overrides(params['/world']))
    agents = [AgentNode('agent', namespace=nm, context=ctx, parameter_overrides=overrides(
        dict(params[f'/{nm}/agent'], use_sim_time=False))) for nm in scn.names]
    mute = rclpy.create_node('mute_commander', context=ctx)
    mute.create_publisher(String, P.LOCK_COMMAND, P.qos_latched(100))
    mute.create_subscription(Float64MultiArray, P.LOCK_STEP, lambda m: None, P.qos_latched())
    for nd in (world, mute, *agents):
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.done, timeout=30)
    assert not world.started
    assert world.failed and 'commander not ready' in world.failed, world.failed
    for nd in (world, mute, *agents):
        nd.destroy_node()


def test_world_ends_the_run_once_every_agent_is_lost(tmp_path, rclpy_context):
    """Every agent goes silent: the world drops them all after missing_timeout and ends the run
    there with an error (it used to wait at the next step for nobody until step_timeout), and
    keeps the steps done."""
    import time

    from swarm_tools.run.launch import build_nodes
    scn = load('homotopy_global')
    ctx = rclpy_context
    params = node_parameters(scn, 'homotopy_global', 'lockstep', duration=5.0, output_dir=str(tmp_path),
                             extra_world=dict(step_timeout=100.0, missing_timeout=0.5, stall_timeout=0.1))
    world, commander, agents = build_nodes(params, ctx, log=lambda *a, **k: None)
    ex = make_executor(ctx)
    for nd in (world, commander, *agents):
        ex.add_node(nd)
    try:
        assert spin_for(ex, lambda: world.started, timeout=30)
        for nd in agents:
            ex.remove_node(nd)
        t0 = time.monotonic()
        assert spin_for(ex, lambda: world.done, timeout=20)
        assert time.monotonic() - t0 < 10
        assert world.failed and 'every agent is lost or killed' in world.failed, world.failed
        assert sum(e['kind'] == 'lost' for e in world.events) == len(scn.names)
        saved = Trajectory.load(tmp_path / 'trajectory.npz')
        assert 1 <= len(saved.t) <= world.driver.lock.cur
    finally:
        for nd in (world, commander, *agents):
            nd.destroy_node()


def test_a_fault_in_the_metrics_does_not_stop_the_step(tmp_path, rclpy_context):
    """Lockstep: the metrics of a step (progress, markers) raise once; the world logs it and still
    sends that step, so the run ends whole and equal to the batch engine (a fault there once
    stalled the step and lost every agent)."""
    from swarm_core.engine.reference import simulate
    from swarm_tools.run.launch import build_nodes
    scn = load('homotopy_global', duration=2.0)
    params = node_parameters(scn, 'homotopy_global', 'lockstep', duration=2.0, output_dir=str(tmp_path))
    world, commander, agents = build_nodes(params, rclpy_context, log=lambda *a, **k: None)
    observe = world.driver.observe

    def faulty(k, rows):
        if k == 5:
            raise ValueError('data must be finite, check for nan or inf values')
        return observe(k, rows)
    world.driver.observe = faulty
    ex = make_executor(rclpy_context)
    for nd in (world, commander, *agents):
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.done, timeout=120)
    assert not world.failed and world.reject.kinds['observe'][2] == 1, world.reject.kinds
    got, ref = Trajectory.load(tmp_path / 'trajectory.npz'), simulate(scn)
    assert np.array_equal(got.r, ref.r)


def test_realtime_world_resolves_leader_i_from_the_commanders_events(tmp_path, rclpy_context):
    """Realtime (nodes in one executor, rtf 10): leaders are chosen by rule at t = 1; the
    scenario kills 'leader:1' at t = 2; the world names the agent the commander put in slot 1."""
    import yaml
    path = short_homotopy(tmp_path / 'rt_leader.yaml', duration=3.0, lam='{kind: constant, value: 0.0}', at=1.0)
    data = yaml.safe_load(path.read_text())
    data['faults'] = [{'at': 2.0, 'kill': 'leader:1'}]
    path.write_text(yaml.safe_dump(data))
    scn = load(str(path))
    params = node_parameters(scn, str(path), 'realtime', rtf=10.0)
    done, world, nodes = run_nodes(params, rclpy_context, 60.0)
    assert done
    chosen = [e for e in world.events if e['kind'] == 'leaders_chosen']
    kills = [e for e in world.events if e['kind'] == 'kill']
    assert chosen and len(chosen[0]['slots']) == 2, world.events
    assert len(kills) == 1 and kills[0]['slot'] == 1 and kills[0]['agent'] == chosen[0]['slots'][1], world.events
    for nd in nodes:
        nd.destroy_node()
