"""Node tests with rclpy executors: several nodes in one executor, each test on its own
ROS_DOMAIN_ID and rclpy Context (fixtures in conftest.py)."""
import math
import os
import signal

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Float64, Float64MultiArray  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402

from swarm_agent.agent_node import AgentNode  # noqa: E402
from swarm_core.engine import simulate
from swarm_core.trajectory import Trajectory  # noqa: E402
from swarm_core.laws import swarm_control  # noqa: E402
from swarm_core.frenet import frame_from_quaternion, quaternion_from_heading  # noqa: E402
from swarm_core.scenario import load  # noqa: E402
from swarm_tools.launch import run_in_process  # noqa: E402
from swarm_tools.node_params import agent_parameters, node_parameters  # noqa: E402
from swarm_ros import protocol as P  # noqa: E402
from swarm_ros.layouts import AgentStates, Step  # noqa: E402
from swarm_ros.rosutil import ParameterError, make_executor  # noqa: E402
from swarm_world.world_node import WorldNode  # noqa: E402

from conftest import overrides, run_nodes, short_homotopy, spin_for  # noqa: E402


def short_scenario(tmp_path, seed=0, duration=40.0, rise=10.0, fall=30.0, tau=3.0, at=5.0):
    """homotopy_global's law and agents with the λ window and leader choice brought forward."""
    lam = f'{{kind: tanh_window, rise_at: {rise}, fall_at: {fall}, tau: {tau}}}'
    return str(short_homotopy(tmp_path / 'homotopy_short.yaml', seed=seed, duration=duration, lam=lam, at=at))


def step_message(scn, pos, theta, lam, flags, steering, target=None, barrier=None, n=0):
    qz, qw = quaternion_from_heading(theta)
    n_agents = len(pos)
    return Step(n, n * scn.dt, lam, flags, steering, pos[:, 0], pos[:, 1], qz, qw, np.zeros(n_agents),
                np.ones(n_agents, bool), target, barrier, None).to_cdr()


def test_agent_u_equals_core_law_in_lockstep(rclpy_context):
    """An agent given a step's table answers with the u of swarm_control on the same inputs;
    λ, leader flags, steering, target and barrier each change that u."""
    scn = load('target_barrier')
    scn6 = load('homotopy_global')
    n = 6
    rng = np.random.default_rng(3)
    pos = rng.uniform(-3, 3, size=(n, 2))
    theta = rng.uniform(-np.pi, np.pi, size=n)
    cases = {
        'a0': dict(lam=0.0, flags=np.zeros(n, bool), steer=np.zeros(n), target=None, barrier=None, law=scn6.law),
        'a1': dict(lam=1.0, flags=np.eye(n, dtype=bool)[2] | np.eye(n, dtype=bool)[0], steer=np.full(n, 0.05),
                   target=None, barrier=None, law=scn6.law),
        'a2': dict(lam=0.4, flags=np.eye(n, dtype=bool)[5], steer=np.full(n, -0.02), target=None, barrier=None,
                   law=scn6.law),
        'a3': dict(lam=0.0, flags=np.zeros(n, bool), steer=np.zeros(n), target=np.array([30.0, -4.0]),
                   barrier=pos[[1, 3, 4]] + 0.5, law=scn.law),
    }
    ctx = rclpy_context
    ex = make_executor(ctx)
    agents = {}
    for name, c in cases.items():
        s = scn6 if c['law'] is scn6.law else scn
        prm = agent_parameters(s, 0, 'lockstep')
        prm.update(agent_name='agent_0', agent_names=[f'agent_{i}' for i in range(n)], agent_index=0,
                   x=float(pos[0, 0]), y=float(pos[0, 1]), theta=float(theta[0]), use_sim_time=False)
        node = AgentNode('agent', namespace=name, context=ctx, parameter_overrides=overrides(prm))
        # the agent publishes on /swarm/states and reads /lockstep/step: give each its own
        # step topic by remapping in the test is not needed, we publish raw to the node directly
        agents[name] = node
        ex.add_node(node)
    expected = {}
    for name, c in cases.items():
        cos_t, sin_t = frame_from_quaternion(*quaternion_from_heading(theta))
        expected[name] = float(swarm_control(pos, cos_t, sin_t, [0], c['law'], lambda_=c['lam'],
                                             is_leader=c['flags'], steering=c['steer'][:1],
                                             target=c['target'], barrier=c['barrier'])[0])
        node = agents[name]
        node.driver.on_input(step_message(scn6, pos, theta, c['lam'], c['flags'], c['steer'], c['target'], c['barrier']))
        assert node.step == 1
        assert node.u_history[-1] == (0, expected[name])
        assert node.own[6] == expected[name]         # the u of the state it published (angular.z)
    assert len({round(v, 12) for v in expected.values()}) == 4       # every input mattered
    # λ = 1 and a leader: u is exactly the steering program
    assert expected['a1'] == 0.05
    # a repeated step message is answered again, not applied twice
    node = agents['a0']
    node.driver.on_input(step_message(scn6, pos, theta, 0.0, np.zeros(n, bool), np.zeros(n)))
    assert node.step == 1 and len(node.u_history) == 1


def test_lockstep_reaches_agents_over_dds(rclpy_context):
    """The same through DDS: a test node publishes /lockstep/step, the agent answers on /swarm/states."""
    scn = load('homotopy_global')
    ctx = rclpy_context
    ex = make_executor(ctx)
    agent = AgentNode('agent', namespace='agent_2', context=ctx,
                      parameter_overrides=overrides(dict(agent_parameters(scn, 2, 'lockstep'), use_sim_time=False)))
    probe = rclpy.create_node('probe', context=ctx)
    got = []
    probe.create_subscription(Odometry, P.STATES, got.append, P.qos_latched(50))
    pub = probe.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
    ex.add_node(agent)
    ex.add_node(probe)
    assert spin_for(ex, lambda: pub.get_subscription_count() >= 1 and got)
    assert got[0].child_frame_id == 'agent_2' and got[0].header.stamp.sec == 0
    lam, flags, steer = 0.7, np.array([0, 0, 1, 0, 0, 0], bool), np.full(6, 0.03)
    pub.publish(step_message(scn, scn.pos0, scn.theta0, lam, flags, steer))
    stamp = P.time_to_stamp(scn.dt)                      # the state of step 1
    assert spin_for(ex, lambda: any((m.header.stamp.sec, m.header.stamp.nanosec) == stamp for m in got))
    m = [m for m in got if (m.header.stamp.sec, m.header.stamp.nanosec) == stamp][0]
    cos_t, sin_t = frame_from_quaternion(*quaternion_from_heading(scn.theta0))
    u = swarm_control(scn.pos0, cos_t, sin_t, [2], scn.law, lambda_=lam, is_leader=flags, steering=[0.03])[0]
    assert m.twist.twist.angular.z == u
    assert u == pytest.approx(0.3 * float(swarm_control(scn.pos0, cos_t, sin_t, [2], scn.law, lambda_=0.0,
                                                         is_leader=flags, steering=[0.0])[0]) + 0.7 * 0.03)
    probe.destroy_node()


def test_realtime_lambda_and_steering_change_what_an_agent_does(rclpy_context):
    """A realtime leader agent: with λ = 1 from /swarm/lambda its u is its /agent_0/steering
    value; λ = 0 gives the pair law; bad λ and steering values are rejected (logged).  The
    probe publishes as the commander does (transient-local): agents read only those."""
    scn = load('homotopy_global')
    ctx = rclpy_context
    ex = make_executor(ctx)
    prm = dict(agent_parameters(scn, 0, 'realtime'), leader=True)
    agent = AgentNode('agent', namespace='agent_0', context=ctx, parameter_overrides=overrides(prm))
    probe = rclpy.create_node('probe', context=ctx)
    clock = probe.create_publisher(Clock, '/clock', 10)
    lam = probe.create_publisher(Float64, '/swarm/lambda', P.qos_latched(10))
    steer = probe.create_publisher(Float64, '/agent_0/steering', P.qos_latched(10))
    for nd in (agent, probe):
        ex.add_node(nd)
    assert spin_for(ex, lambda: lam.get_subscription_count() and steer.get_subscription_count()
                    and clock.get_subscription_count())
    t = [0.0]

    def tick(k=3):
        n0 = len(agent.u_history)
        for _ in range(k * 4):
            t[0] += scn.dt
            sec, ns = P.time_to_stamp(t[0])
            c = Clock()
            c.clock.sec, c.clock.nanosec = sec, ns
            clock.publish(c)
            spin_for(ex, lambda: False, 0.05)
            if len(agent.u_history) >= n0 + k:
                break
        return [u for _, u in agent.u_history[n0:]]

    lam.publish(Float64(data=1.0))
    steer.publish(Float64(data=0.042))
    assert spin_for(ex, lambda: agent.lam == 1.0 and agent.steering == 0.042)
    us = tick()
    assert us and us[-1] == 0.042
    for bad in (float('nan'), 1.5, -0.1, float('inf')):
        lam.publish(Float64(data=bad))
    steer.publish(Float64(data=float('inf')))
    spin_for(ex, lambda: agent.reject.count >= 5, 5.0)
    assert agent.lam == 1.0 and agent.steering == 0.042
    assert agent.reject.count == 5          # four bad λ, one bad steering value ...
    assert sum('λ=' in ln for ln in agent.reject.lines) == 1      # ... one line per kind
    assert any('steering' in ln and 'agent_0' in ln for ln in agent.reject.lines)
    lam.publish(Float64(data=0.0))
    assert spin_for(ex, lambda: agent.lam == 0.0)
    us = tick()
    assert us and us[-1] != 0.042 and all(math.isfinite(u) for u in us)
    assert np.all(np.isfinite(agent.core.pos)) and np.isfinite(agent.core.theta).all()
    probe.destroy_node()


def test_realtime_agent_moves_with_the_sim_clock(rclpy_context):
    """The realtime agent's timer against a hand-driven /clock: a jump of two periods moves it
    two periods (it moved one per timer call, so agents flew at 0.55-0.7 of unit speed in
    `swarm run --mode realtime`), the same time again publishes no second state with that
    stamp, a late tick flies every period that passed, and a long gap after the process was
    stopped (SIGCONT) moves it `catch_up_limit` periods."""
    scn = load('homotopy_global')
    ctx = rclpy_context
    ex = make_executor(ctx)
    agent = AgentNode('agent', namespace='agent_1', context=ctx,
                      parameter_overrides=overrides(agent_parameters(scn, 1, 'realtime')))
    probe = rclpy.create_node('probe', context=ctx)
    clock = probe.create_publisher(Clock, '/clock', 10)
    states = []
    probe.create_subscription(Odometry, P.STATES, states.append, P.qos_latched(100))
    for nd in (agent, probe):
        ex.add_node(nd)
    assert spin_for(ex, lambda: clock.get_subscription_count() and states)
    limit = agent.driver.catch_up_limit

    def at(t, steps):
        c = Clock()
        c.clock.sec, c.clock.nanosec = P.time_to_stamp(t)
        clock.publish(c)
        assert spin_for(ex, lambda: agent.step >= steps, 5.0), (t, agent.step)
        spin_for(ex, lambda: False, 0.3)         # any further timer call for this time
        return agent.step

    start = agent.core.pos.copy()
    assert at(2 * scn.dt, 2) == 2 and agent.t == pytest.approx(2 * scn.dt)
    moved = float(np.hypot(*(agent.core.pos - start)[0]))
    assert moved == pytest.approx(2 * scn.dt, rel=1e-3)        # unit speed: an arc of 2 dt
    assert at(2 * scn.dt, 2) == 2                                 # the same time: nothing
    assert at(12 * scn.dt, 12) == 12                              # a late tick (starved): every period
    os.kill(os.getpid(), signal.SIGCONT)                          # as after SIGSTOP ... SIGCONT
    assert at(112 * scn.dt, 12 + limit) == 12 + limit
    stamps = [(m.header.stamp.sec, m.header.stamp.nanosec) for m in states]
    assert len(stamps) == len(set(stamps)) == 4, stamps         # t = 0, 2 dt, 12 dt, 112 dt
    probe.destroy_node()

def test_target_and_barrier_updates_reach_agents(rclpy_context):
    scn = load('target_barrier')
    ctx = rclpy_context
    ex = make_executor(ctx)
    world = WorldNode(context=ctx, parameter_overrides=overrides(dict(scenario='target_barrier', duration=1.0)),
                      log=lambda *a, **k: None)
    agent = AgentNode('agent', namespace='agent_1', context=ctx,
                      parameter_overrides=overrides(agent_parameters(scn, 1, 'realtime')))
    ex.add_node(world)
    ex.add_node(agent)
    assert spin_for(ex, lambda: agent.target is not None and agent.barrier is not None)
    assert np.array_equal(agent.target, scn.target) and np.array_equal(agent.barrier, scn.barrier)
    res = world.set_parameters([Parameter('target', value='12.5,-3'),
                                Parameter('barrier', value='5,1;6,0;5,-1')])
    assert all(r.successful for r in res)
    assert spin_for(ex, lambda: agent.target is not None and agent.target[0] == 12.5)
    assert spin_for(ex, lambda: agent.barrier is not None and len(agent.barrier) == 3)
    assert np.array_equal(agent.barrier, [[5, 1], [6, 0], [5, -1]])
    # a bad target is refused and changes nothing
    res = world.set_parameters([Parameter('target', value='nan,1')])
    assert not res[0].successful
    assert np.array_equal(world.target, [12.5, -3.0])


def test_lockstep_in_process_equals_simulate(tmp_path, ros_domain):
    """World, commander and six agents in ONE executor equal `swarm simulate` (positions and u exactly) over a
    run with the leader choice and a full λ window (800 steps)."""
    path = short_scenario(tmp_path)
    scn = load(path)
    out = tmp_path / 'run'
    params = node_parameters(scn, path, 'lockstep', output_dir=str(out))
    assert run_in_process(params, domain_id=ros_domain) == 0
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(scn)
    assert ref.leader.any() and ref.lam.max() > 0.99
    np.testing.assert_array_equal(got.r, ref.r)                # exact: the same law, the same order
    np.testing.assert_array_equal(got.u, ref.u)
    assert np.abs(got.theta - ref.theta).max() <= 1e-9         # θ comes back through the quaternion
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)


def test_bad_startup_parameters_are_named(rclpy_context):
    scn = load('homotopy_global')
    cases = {'cutoff_radius': -1.0, 'dt': 0.0, 'law': 'nonsense', 'x': float('nan'), 'q0': 2.0,
             'agent_name': 'ghost', 'leader_gain': 0.5}
    for name, value in cases.items():
        prm = agent_parameters(scn, 0, 'lockstep')
        prm[name] = value
        with pytest.raises(ParameterError) as err:
            AgentNode('agent', namespace=f'bad_{name}', context=rclpy_context, parameter_overrides=overrides(prm))
        assert str(err.value).startswith(f'parameter {name}') and '\n' not in str(err.value)
    with pytest.raises(ParameterError, match='parameter scenario'):
        WorldNode(context=rclpy_context, parameter_overrides=overrides(dict(scenario='no_such_scenario')))


def test_agent_declares_each_law_parameter_with_the_tables_description_and_range(rclpy_context):
    """The agent's ROS parameters come from `law_parameters.LAW_TABLE`: the same default,
    description and range (or choices) a scenario is checked against."""
    from swarm_core.law_parameters import LAW_TABLE
    node = AgentNode('agent', namespace='described', context=rclpy_context)
    try:
        for p in LAW_TABLE:
            assert node.get_parameter(p.name).value == p.default, p.name
            d = node.describe_parameter(p.name)
            assert d.description == p.description, p.name
            if p.bound is not None:
                r = d.floating_point_range[0]
                assert (r.from_value, r.to_value) == (p.bound.lo, p.bound.hi), p.name
            if p.choices:
                assert d.additional_constraints == 'one of: ' + ', '.join(p.choices), p.name
    finally:
        node.destroy_node()


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
    assert world.lock.have.tolist() == [False, False, False, True, False, False]
    assert np.all(np.isfinite(world.lock.buf))
    assert world.lock.buf[0, 3] == 1.0 and world.lock.buf[1, 3] == 2.0
    probe.destroy_node()


def test_commander_rejects_bad_lambda_and_takes_setpoints(rclpy_context):
    from homotopy_commander.commander_node import CommanderNode
    ctx = rclpy_context
    ex = make_executor(ctx)
    cmd = CommanderNode(context=ctx, parameter_overrides=overrides(dict(scenario='homotopy_global', mode='lockstep')))
    probe = rclpy.create_node('probe', context=ctx)
    lam = probe.create_publisher(Float64, '/swarm/lambda', 10)
    steer = probe.create_publisher(Float64, '/agent_4/steering', 10)
    ex.add_node(cmd)
    ex.add_node(probe)
    assert spin_for(ex, lambda: lam.get_subscription_count() >= 1 and steer.get_subscription_count() >= 1)
    for bad in (float('nan'), 2.0, -1.0, float('-inf')):
        lam.publish(Float64(data=bad))
    steer.publish(Float64(data=float('nan')))
    assert spin_for(ex, lambda: cmd.reject.count >= 5)
    assert len(cmd.reject.lines) == 2                  # one line per kind (λ, steering)
    assert not cmd.pending
    lam.publish(Float64(data=1.0))
    steer.publish(Float64(data=0.02))
    assert spin_for(ex, lambda: len(cmd.pending) == 2)
    scn = load('homotopy_global')
    c, s = np.cos(scn.theta0), np.sin(scn.theta0)
    lam0, flags, steering = cmd.decide(100.0, scn.pos0, c, s)
    assert lam0 == pytest.approx(0.0, abs=1e-4) and flags[4] and steering[4] == 0.02
    lam_mid, _, _ = cmd.decide(110.0, scn.pos0, c, s)          # ramping to 1 over ramp = 20
    lam_end, _, _ = cmd.decide(125.0, scn.pos0, c, s)
    assert 0.2 < lam_mid < 0.8 and lam_end == 1.0
    probe.destroy_node()


def test_world_gives_up_on_a_step_that_never_completes(rclpy_context):
    """A commander that is there but never decides: the world stops with an error naming what
    it waited for (after max(step_timeout, missing_timeout + 10 stall_timeout) wall s), instead
    of waiting for ever."""
    import time
    scn = load('homotopy_global')
    ctx = rclpy_context
    ex = make_executor(ctx)
    params = node_parameters(scn, 'homotopy_global', 'lockstep', duration=1.0,
                             extra_world=dict(step_timeout=1.0, missing_timeout=0.5, stall_timeout=0.1))
    world = WorldNode(context=ctx, parameter_overrides=overrides(params['/world']))
    agents = [AgentNode('agent', namespace=nm, context=ctx, parameter_overrides=overrides(
        dict(params[f'/{nm}/agent'], use_sim_time=False))) for nm in scn.names]
    mute = rclpy.create_node('mute_commander', context=ctx)
    mute.create_publisher(Float64MultiArray, P.LOCK_DECISION, P.qos_latched())
    mute.create_subscription(Float64MultiArray, P.LOCK_STATES, lambda m: None, P.qos_latched())
    for nd in (world, mute, *agents):
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.started, timeout=30)
    t0 = time.monotonic()
    assert spin_for(ex, lambda: world.done, timeout=30)
    assert time.monotonic() - t0 >= 1.4                 # not before its time ...
    assert world.failed and 'step 0' in world.failed and 'commander' in world.failed, world.failed
    for nd in (world, mute, *agents):
        nd.destroy_node()


def test_world_ends_the_run_once_every_agent_is_lost(tmp_path, rclpy_context):
    """Every agent goes silent: the world drops them all after missing_timeout and ends the run
    there with an error (it used to wait at the next step for nobody until step_timeout), and
    keeps the steps done."""
    import time

    from swarm_tools.launch import build_nodes
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
        assert 1 <= len(saved.t) <= world.lock.cur
    finally:
        for nd in (world, commander, *agents):
            nd.destroy_node()


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


def test_string_parameters_that_look_like_numbers_stay_strings(tmp_path, rclpy_context):
    """A run id such as ``7710e017`` written by `write_params_file` reaches the node as a string
    (ROS's parameter-file parser reads it as a double unless it is quoted)."""
    from swarm_tools.node_params import write_params_file
    path = write_params_file({'/probe_node': {'run_id': '7710e017', 'other': '1e5', 'n': 3}}, tmp_path / 'p.yaml')
    node = rclpy.create_node('probe_node', context=rclpy_context,
                             cli_args=['--ros-args', '--params-file', str(path)])
    try:
        assert node.declare_parameter('run_id', '').value == '7710e017'
        assert node.declare_parameter('other', '').value == '1e5'
        assert node.declare_parameter('n', 0).value == 3
    finally:
        node.destroy_node()
