"""The agent node (`swarm_agent.agent_node`) with rclpy executors, each test on its own
ROS_DOMAIN_ID and rclpy Context (fixtures in tests/conftest.py): its u against the core law in
lockstep, over DDS, the commander's decision (λ, leaders, steering), target and barrier in
realtime, the sim clock, and its parameters (bad ones named, each law parameter declared from the table)."""
import math
import os
import signal

import numpy as np
import pytest
import rclpy
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

from swarm_agent.agent_node import AgentNode
from swarm_core.laws import swarm_control
from swarm_core.model.frenet import frame_from_quaternion, quaternion_from_heading
from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.layouts import RealtimeDecision, Step
from swarm_ros.rosutil import ParameterError, make_executor
from swarm_tools.run.params import agent_parameters
from swarm_world.world_node import WorldNode
from tests.helpers import overrides, spin_for


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
        node.driver.on_input(step_message(scn6, pos, theta, c['lam'], c['flags'], c['steer'], c['target'],
                                          c['barrier']))
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


def test_realtime_decision_sets_what_an_agent_does(rclpy_context):
    """A realtime agent takes λ, the leaders and its s_k from the commander's decision on
    /swarm/decision (as the commander publishes it: transient-local): with λ = 1 and itself a
    leader its u is its s_k; λ = 0 gives the pair law; bad λ and steering values in a decision
    are rejected (logged) and the rest of it taken.  It reads neither /swarm/lambda nor its
    /agent_0/steering topic: what a user publishes there is a command for the commander."""
    scn = load('homotopy_global')
    ctx = rclpy_context
    ex = make_executor(ctx)
    prm = dict(agent_parameters(scn, 0, 'realtime'), leader=False)
    agent = AgentNode('agent', namespace='agent_0', context=ctx, parameter_overrides=overrides(prm))
    probe = rclpy.create_node('probe', context=ctx)
    clock = probe.create_publisher(Clock, '/clock', 10)
    decisions = probe.create_publisher(Float64MultiArray, P.DECISION, P.qos_latched())
    for nd in (agent, probe):
        ex.add_node(nd)
    assert spin_for(ex, lambda: decisions.get_subscription_count() and clock.get_subscription_count())
    assert not probe.get_subscriptions_info_by_topic(P.LAMBDA)
    assert not probe.get_subscriptions_info_by_topic('/agent_0/steering')
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

    def decide(lam, s0, leader=True):
        flags = np.zeros(len(scn.names), bool)
        flags[0] = leader
        steering = np.zeros(len(scn.names))
        steering[0] = s0
        n = agent.reject.count
        slots = np.full(len(scn.names), -1)
        decisions.publish(RealtimeDecision(P.step_of(t[0], scn.dt), t[0], lam, flags, steering, slots,
                                           None).to_cdr(agent.run_id))
        return n

    decide(1.0, 0.042)
    assert spin_for(ex, lambda: agent.lam == 1.0 and agent.steering == 0.042 and agent.leaders == {'agent_0'})
    us = tick()
    assert us and us[-1] == 0.042
    for bad in (float('nan'), 1.5, -0.1, float('inf')):
        n = decide(bad, 0.042)
        assert spin_for(ex, lambda n=n: agent.reject.count > n, 5.0), bad
    n = decide(1.0, float('inf'))
    assert spin_for(ex, lambda: agent.reject.count > n, 5.0)
    assert agent.lam == 1.0 and agent.steering == 0.042
    assert agent.reject.count == 5          # four bad λ, one bad steering value ...
    assert sum('λ=' in ln for ln in agent.reject.lines) == 1      # ... one line per kind
    assert any('steering' in ln and 'agent_0' in ln for ln in agent.reject.lines)
    decide(0.0, 0.042, leader=False)
    assert spin_for(ex, lambda: agent.lam == 0.0 and not agent.leaders)
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
    """The agent's ROS parameters come from `laws.paper.parameters.LAW_TABLE`: the same default,
    description and range (or choices) a scenario is checked against."""
    from swarm_core.laws import names
    from swarm_core.laws.paper.parameters import LAW_TABLE
    node = AgentNode('agent', namespace='described', context=rclpy_context)
    try:
        law = node.describe_parameter('law')        # any kind: the paper's, shipped, a user's (docs/laws.md)
        assert all(kind in law.description for kind in names()) and 'FILE.py:Class' in law.description
        for p in LAW_TABLE:
            if p.name == 'law':
                assert node.get_parameter('law').value == p.default
                continue
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


def test_lockstep_answers_the_world_first_and_sends_no_state_nobody_reads(rclpy_context):
    """Lockstep: each step the agent sends its answer on /lockstep/agent_states first, then its
    state on /swarm/states.  Past the first `P.STATES_DEPTH` states, a state no reader is matched
    for is not sent; once a reader matches, every state goes out again.  The world's answer goes
    out every step."""
    scn = load('homotopy_global')
    ctx = rclpy_context
    agent = AgentNode('agent', namespace='agent_0', context=ctx, parameter_overrides=overrides(
        dict(agent_parameters(scn, 0, 'lockstep'), use_sim_time=False)))
    order = []
    for label, pub in (('states', agent.pub), ('answer', agent.driver.batch.pub)):
        real = pub.publish
        pub.publish = lambda raw, real=real, label=label: (order.append(label), real(raw))
    qz, qw = quaternion_from_heading(scn.theta0)
    n = len(scn.names)

    def feed(a, b):
        for k in range(a, b):
            agent.driver.on_input(Step(k, k * scn.dt, 0.0, np.zeros(n, bool), np.zeros(n), scn.pos0[:, 0] + 0.01 * k,
                                       scn.pos0[:, 1], qz, qw, np.zeros(n), np.ones(n, bool), None, None,
                                       None).to_cdr(agent.run_id))
    last = P.STATES_DEPTH + 20
    feed(0, last)
    assert agent.step == last
    # steps 0..: the state of step k + 1 after the answer; the states of steps 1..99 go out
    assert order[:4] == ['answer', 'states', 'answer', 'states']
    assert order.count('answer') == last
    assert order.count('states') == P.STATES_DEPTH - 1
    probe = rclpy.create_node('state_reader', context=ctx)
    got = []
    probe.create_subscription(Odometry, P.STATES, got.append, P.qos_latched(P.STATES_DEPTH))
    ex = make_executor(ctx)
    ex.add_node(probe)
    assert spin_for(ex, lambda: agent.pub.get_subscription_count() >= 1, 10.0)
    order.clear()
    feed(last, last + 10)
    assert order == ['answer', 'states'] * 10
    assert spin_for(ex, lambda: any(P.step_of(P.stamp_to_time(m.header.stamp), scn.dt) == last + 10
                                    for m in got), 10.0)
    probe.destroy_node()
    agent.destroy_node()
