"""Every parameter of an agent node, set as ``ros2 param set /agent_0/agent NAME VALUE`` sets it:
either the set takes effect (the agent's output changes: the u it publishes, the neighbours it
uses, the periods it catches up) or it is refused and the value stays.

The sets go through the stock path of the real tool: ros2cli (Jazzy)
``ros2param/api/__init__.py`` ``call_set_parameters`` makes a client of the node's
``<node>/set_parameters`` service (rcl_interfaces/srv/SetParameters) and sends one request
whose value is typed from the command-line text by ``get_parameter_value`` (YAML: ``1`` an
integer, ``0.5`` a double, ``true`` a bool, anything else a string); `ros2_param_set` below does
exactly that.  Live: the law's parameters (not its kind) in both modes (lockstep: from the step
the agent holds, announced on /swarm/events), and in realtime stale_after, future_tolerance and
catch_up_limit; everything else is read-only (docs/ros-graph.md, "Agent parameters")."""
from __future__ import annotations

import copy
import json
import os
import signal

import numpy as np
import pytest

from swarm_core.command.plan import law_with
from swarm_core.model.frenet import quaternion_from_heading
from swarm_ros import protocol as P
from swarm_ros.layouts import ProcessStates, Step
from swarm_tools.run.params import agent_parameters
from tests.helpers import overrides, spin_for

#: the law of the lockstep test: every one of its parameters matters to agent_0's u below
LAW = dict(law='homotopy', alpha=0.05, eta=0.03, mu=0.04, r0=1.5, cutoff_radius=4.0, leader_gain=30.0, q0=0.5,
           target_gain=0.3, target_normalised=False, barrier_gain=2.0, barrier_mode='ahead')
#: a new value for each live law parameter, as typed in a shell
NEW_LAW_TEXT = dict(alpha='0.5', eta='0.2', mu='1', r0='0.7', cutoff_radius='2.5', leader_gain='5.0', q0='0.9',
                    target_gain='1.2', target_normalised='true', barrier_gain='7.5', barrier_mode='literal')
#: a value of the right type for each read-only parameter (the set must be refused all the same)
FIXED_TEXT = dict(agent_name='agent_9', agent_names='[a, b]', agent_index='3', leader='true', x='3.0', y='-2.0',
                  theta='1.0', dt='0.1', mode='realtime', noise_position='0.1', noise_heading='0.1', seed='7',
                  robot='external', comms='{"loss": 0.5}', run_id='other', law='global', state_subscribers='2',
                  lockstep_clock='topic', stale_after='0.5', catch_up_limit='9', future_tolerance='0.1',
                  use_sim_time='false', start_type_description_service='false', pair_sums='compiled', dim='3',
                  z='1.0', frame='[0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0]', ground='2.0')
NAMES = [f'agent_{i}' for i in range(6)]
POS = np.array([[0.0, 0.0], [1.2, 0.4], [-0.8, 1.1], [3.0, -1.0], [6.5, 2.0], [-5.0, -4.5]])
THETA = np.array([0.3, -0.2, 1.1, 2.5, -2.0, 0.7])


def parameter_value(text):
    """ros2param.api.get_parameter_value: the value ``ros2 param set`` sends for ``text``."""
    import yaml
    from rcl_interfaces.msg import ParameterType, ParameterValue
    v = ParameterValue()
    y = yaml.safe_load(text)
    if isinstance(y, bool):
        v.type, v.bool_value = ParameterType.PARAMETER_BOOL, y
    elif isinstance(y, int):
        v.type, v.integer_value = ParameterType.PARAMETER_INTEGER, y
    elif isinstance(y, float):
        v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, y
    elif isinstance(y, list) and all(isinstance(s, str) for s in y):
        v.type, v.string_array_value = ParameterType.PARAMETER_STRING_ARRAY, y
    else:
        v.type, v.string_value = ParameterType.PARAMETER_STRING, text
    return v


def ros2_param_set(ex, client_node, node_name, name, text):
    """ros2param.api.call_set_parameters: one SetParameters request to ``<node_name>/set_parameters``;
    the reply's one SetParametersResult."""
    from rcl_interfaces.msg import Parameter as ParameterMsg
    from rcl_interfaces.srv import SetParameters
    client = client_node.create_client(SetParameters, f'{node_name}/set_parameters')
    try:
        assert spin_for(ex, client.service_is_ready, 30), f'{node_name}/set_parameters not there'
        req = SetParameters.Request()
        req.parameters = [ParameterMsg(name=name, value=parameter_value(text))]
        fut = client.call_async(req)
        assert spin_for(ex, fut.done, 30)
        return fut.result().results[0]
    finally:
        client_node.destroy_client(client)


def _step(n, lam, flags, steering, target, barrier, own=None):
    """The world's step message n over the fixed table (agent_0's row: ``own`` (x, y, θ))."""
    pos, theta = POS.copy(), THETA.copy()
    if own is not None:
        pos[0], theta[0] = own[:2], own[2]
    qz, qw = quaternion_from_heading(theta)
    return Step(n, n * 0.05, lam, flags, steering, pos[:, 0], pos[:, 1], qz, qw, np.zeros(6), np.ones(6, bool),
                target, barrier, None)


def _agent(ctx, mode, **extra):
    from swarm_agent.agent_node import AgentNode
    from swarm_core.scenario.loader import load
    prm = agent_parameters(load('homotopy_global'), 0, mode)
    prm.update(agent_name='agent_0', agent_names=NAMES, agent_index=0, x=float(POS[0, 0]), y=float(POS[0, 1]),
               theta=float(THETA[0]), dt=0.05, **LAW, **extra)
    return AgentNode('agent', namespace='agent_0', context=ctx, parameter_overrides=overrides(prm))


def _probe_of(ctx, agent):
    """(a ``ros2 param``-like node, an executor spinning it and ``agent``, the /swarm/events it hears)."""
    import rclpy
    from std_msgs.msg import String

    from swarm_ros.rosutil import make_executor
    probe = rclpy.create_node('ros2cli_param', context=ctx)
    events = []
    probe.create_subscription(String, P.EVENTS, lambda m: events.append(json.loads(m.data)), P.qos_latched(100))
    ex = make_executor(ctx)
    for nd in (agent, probe):
        ex.add_node(nd)
    return probe, ex, events


def test_lockstep_every_parameter_takes_effect_at_the_next_step_or_is_refused(rclpy_context):
    """Lockstep: each law parameter set (a double typed as an integer too: ``mu 1``) changes the
    u agent_0 publishes from the step it holds on, to the u of its law with that value (bit for
    bit), and the change goes to /swarm/events as a ``command`` event with that step; a value
    out of range and the law's kind are refused; every other parameter is read-only."""
    ctx = rclpy_context
    agent = _agent(ctx, 'lockstep')
    probe, ex, events = _probe_of(ctx, agent)
    lam, flags, steering = 0.4, np.eye(6, dtype=bool)[2], np.full(6, 0.03)
    target, barrier = np.array([8.0, 3.0]), np.array([[1.0, 0.8], [1.5, 0.0], [1.0, -0.8]])

    def step():
        """One step for agent_0; (u it published, u of the law it had, u of that law with nothing changed)."""
        own = (*agent.core.pos[0], agent.core.theta[0])
        s = _step(agent.core.step, lam, flags, steering, target, barrier, own)
        agent.driver.on_input(s.to_cdr(agent.run_id))
        return agent.own[6]

    def expected(law):
        shadow = copy.deepcopy(agent.core)
        shadow.law = law
        s = _step(agent.core.step, lam, flags, steering, target, barrier)
        return shadow.control(s.x, s.y, s.qz, s.qw, lam, flags, steering[0], target, barrier, alive=s.alive)

    step()
    for name, text in NEW_LAW_TEXT.items():
        before, at = agent.law, agent.core.step
        res = ros2_param_set(ex, probe, '/agent_0/agent', name, text)
        assert res.successful, (name, res.reason)
        want = expected(law_with(before, {name: agent.get_parameter(name).value}))
        assert want != expected(before), name                  # the table makes every parameter matter
        assert step() == want, name                            # from the step it held
        mine = lambda name=name: [e for e in events if name in e.get('parameters', {})]
        assert spin_for(ex, mine, 10), name
        ev = mine()[-1]
        assert (ev['kind'], ev['command'], ev['agent'], ev['step'], ev['node']) == ('command', 'law', 'agent_0',
                                                                                   at, 'agent'), ev
    for name, text in [('alpha', '-1.0'), ('q0', '2.0'), ('barrier_mode', 'sideways'), ('alpha', 'fast')]:
        law = agent.law
        res = ros2_param_set(ex, probe, '/agent_0/agent', name, text)
        assert not res.successful and res.reason, (name, text)
        assert agent.law is law
    for name, text in FIXED_TEXT.items():
        assert name in agent._parameters, name
        was = agent.get_parameter(name).value
        res = ros2_param_set(ex, probe, '/agent_0/agent', name, text)
        assert not res.successful, (name, text)
        assert agent.get_parameter(name).value == was, name
    covered = set(NEW_LAW_TEXT) | set(FIXED_TEXT)
    assert set(agent._parameters) == covered, set(agent._parameters) ^ covered     # every parameter
    probe.destroy_node()
    agent.destroy_node()


def test_a_robot_agents_robot_parameters_are_read_only(rclpy_context):
    """The parameters a robot agent has besides (its robot's) are read once at the start."""
    import rclpy

    from swarm_ros.rosutil import make_executor
    agent = _agent(rclpy_context, 'lockstep', robot='external', length_scale=0.2, cruise_speed=0.2)
    probe = rclpy.create_node('ros2cli_param', context=rclpy_context)
    ex = make_executor(rclpy_context)
    for nd in (agent, probe):
        ex.add_node(nd)
    robot = dict(length_scale='0.5', cruise_speed='0.5', max_angular='1.0', odom_timeout='3.0',
                 neighbour_timeout='3.0', max_jump='1.0', robot_frame='world', cmd_type='Twist',
                 robot_clock='wall', odom_reliability='best_effort')
    assert set(agent._parameters) == set(NEW_LAW_TEXT) | set(FIXED_TEXT) | set(robot)
    for name, text in robot.items():
        was = agent.get_parameter(name).value
        assert not ros2_param_set(ex, probe, '/agent_0/agent', name, text).successful, name
        assert agent.get_parameter(name).value == was
    probe.destroy_node()
    agent.destroy_node()


def test_realtime_parameters_take_effect_at_the_next_tick(rclpy_context):
    """Realtime: a law parameter changes the u of the next control period; stale_after the
    neighbours in its table; future_tolerance which states from ahead of its clock it takes;
    catch_up_limit the periods it flies after its process was stopped (SIGCONT)."""
    import rclpy
    from rosgraph_msgs.msg import Clock

    from swarm_ros.rosutil import make_executor
    ctx = rclpy_context
    agent = _agent(ctx, 'realtime')
    probe = rclpy.create_node('ros2cli_param', context=ctx)
    clock = probe.create_publisher(Clock, '/clock', 10)
    ex = make_executor(ctx)
    for nd in (agent, probe):
        ex.add_node(nd)
    assert spin_for(ex, lambda: clock.get_subscription_count() > 0)
    tag = 1000.0

    def hear(i, t):
        """A state of agent i stamped t from another process (its batch on /swarm/agent_states)."""
        qz, qw = quaternion_from_heading(THETA[i:i + 1])
        m = ProcessStates(tag + i, np.array([i]), np.array([t]), np.array([[POS[i, 0]], [POS[i, 1]], qz, qw]),
                          np.zeros(1))
        agent.driver.on_input(m.to_cdr(agent.run_id))

    def tick(t, periods=1):
        """Clock to t; the u of the tick (the agent must move ``periods`` periods)."""
        steps = agent.step + periods
        c = Clock()
        c.clock.sec, c.clock.nanosec = P.time_to_stamp(t)
        clock.publish(c)
        assert spin_for(ex, lambda: agent.step >= steps, 10), (t, agent.step, steps)
        spin_for(ex, lambda: False, 0.2)
        assert agent.step == steps
        return agent.u_history[-1][1]

    def law_u(law, now):
        own, rows, flags = agent.driver.table(now)
        shadow = copy.deepcopy(agent.core)
        shadow.law = law
        return shadow.control(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], agent.lam, flags, agent.steering,
                              agent.target, agent.barrier, row=own)

    for i in (1, 2, 3):
        hear(i, 0.0)
    tick(0.05)
    # a law parameter: the next period's u is the new law's
    old = agent.law
    assert ros2_param_set(ex, probe, '/agent_0/agent', 'alpha', '0.6').successful
    want = law_u(law_with(old, {'alpha': 0.6}), 0.1)
    assert want != law_u(old, 0.1) and tick(0.1) == want
    # stale_after: agents 1-3 were heard at t = 0; at 1.5 s they are in the table (2 s), at 1 s they are not
    assert len(agent.driver.table(1.5)[1]) == 4
    assert ros2_param_set(ex, probe, '/agent_0/agent', 'stale_after', '1.0').successful
    assert len(agent.driver.table(1.5)[1]) == 1 and agent.driver.stale_after == 1.0
    # future_tolerance: a state 1 s ahead of the clock is refused with 0.5 s, taken with 3 s
    assert ros2_param_set(ex, probe, '/agent_0/agent', 'future_tolerance', '0.5').successful
    n = agent.reject.count
    hear(4, 1.15)
    assert agent.reject.count == n + 1 and 'agent_4' not in agent.driver.heard.newest
    assert ros2_param_set(ex, probe, '/agent_0/agent', 'future_tolerance', '3').successful
    hear(4, 1.15)
    assert 'agent_4' in agent.driver.heard.newest
    # catch_up_limit: after a stop (SIGCONT) a long gap moves the agent that many periods
    assert ros2_param_set(ex, probe, '/agent_0/agent', 'catch_up_limit', '2').successful
    os.kill(os.getpid(), signal.SIGCONT)
    tick(5.0, periods=2)
    # the same in lockstep's parameters is refused (nothing reads them there): see the lockstep test
    probe.destroy_node()
    agent.destroy_node()


@pytest.mark.parametrize('text', ['0', '-3'])
def test_realtime_catch_up_limit_stays_in_its_range(text, rclpy_context):
    import rclpy

    from swarm_ros.rosutil import make_executor
    agent = _agent(rclpy_context, 'realtime')
    probe = rclpy.create_node('ros2cli_param', context=rclpy_context)
    ex = make_executor(rclpy_context)
    for nd in (agent, probe):
        ex.add_node(nd)
    assert not ros2_param_set(ex, probe, '/agent_0/agent', 'catch_up_limit', text).successful
    assert agent.driver.catch_up_limit == 4
    probe.destroy_node()
    agent.destroy_node()


@pytest.mark.refuses_inputs
def test_realtime_driver_parameters_are_bounded_logged_and_recorded(rclpy_context, capfd):
    """stale_after and future_tolerance stay within what a run can use (from two control
    periods to 60 and 10 sim s); a set in range is logged in one line and published on
    /swarm/events as a ``parameter`` event (the world writes it to events.jsonl)."""
    agent = _agent(rclpy_context, 'realtime')
    probe, ex, events = _probe_of(rclpy_context, agent)
    for name, text in [('stale_after', '0.05'), ('stale_after', '61'), ('stale_after', '1e9'),
                       ('future_tolerance', '0'), ('future_tolerance', '0.09'), ('future_tolerance', '11'),
                       ('future_tolerance', '1e9')]:
        was = getattr(agent.driver, name)
        assert not ros2_param_set(ex, probe, '/agent_0/agent', name, text).successful, (name, text)
        assert getattr(agent.driver, name) == was
    assert not events
    for name, text, value in [('stale_after', '0.1', 0.1), ('stale_after', '60', 60.0),
                              ('future_tolerance', '10', 10.0), ('catch_up_limit', '7', 7)]:
        was = getattr(agent.driver, name)
        assert ros2_param_set(ex, probe, '/agent_0/agent', name, text).successful, (name, text)
        assert getattr(agent.driver, name) == value
        assert spin_for(ex, lambda name=name: any(name in e.get('parameters', {}) for e in events), 10), name
        ev = [e for e in events if name in e.get('parameters', {})][-1]
        assert (ev['kind'], ev['agent'], ev['parameters'], ev['was'], ev['node']) == (
            'parameter', 'agent_0', {name: value}, {name: was}, 'agent'), ev
        assert {'t', 'step'} <= set(ev)
    logged = capfd.readouterr().err
    assert 'realtime: stale_after 2.0 -> 0.1 from step' in logged, logged
    assert 'realtime: catch_up_limit 4 -> 7 from step' in logged, logged
    probe.destroy_node()
    agent.destroy_node()


@pytest.mark.refuses_inputs
@pytest.mark.parametrize('contained', [False, True], ids=['alone', 'in a container'])
def test_a_law_set_the_law_raises_on_is_refused(rclpy_context, contained):
    """A law parameter set whose law raises on the agent's last table (its step's) is refused
    with the law's one line, the agent keeps its law and goes on; alone and in an agent
    container alike."""
    import rclpy

    from swarm_agent.container_node import AgentContainer
    from swarm_core.scenario.loader import load
    from swarm_ros.rosutil import make_executor
    scn = load('homotopy_global')
    law = dict(law='tests.agent.test_law_trial:Picky', cutoff_radius=4.0, gain=1.0)

    def prm(k):
        p = {k: v for k, v in agent_parameters(scn, k, 'lockstep').items() if k not in LAW}
        p.update(agent_names=NAMES, x=float(POS[k, 0]), y=float(POS[k, 1]), theta=float(THETA[k]), dt=0.05, **law)
        return overrides(p)
    if contained:
        box = AgentContainer(NAMES[:2], context=rclpy_context, agent_overrides={nm: prm(k) for k, nm in
                                                                                 enumerate(NAMES[:2])})
        agent, on_step, nodes = box.agents[1], box._on_step, [box, *box.agents]
    else:
        from swarm_agent.agent_node import AgentNode
        agent = AgentNode('agent', namespace='agent_1', context=rclpy_context, parameter_overrides=prm(1))
        on_step, nodes = agent.driver.on_input, [agent]
    probe = rclpy.create_node('ros2cli_param', context=rclpy_context)
    ex = make_executor(rclpy_context)
    for nd in (*nodes, probe):
        ex.add_node(nd)
    flags, steering = np.zeros(6, bool), np.zeros(6)

    def step():
        n = agent.core.step
        on_step(_step(n, 0.0, flags, steering, None, None, (*agent.core.pos[0], agent.core.theta[0])).to_cdr(''))
        return agent.core.step == n + 1

    assert step()
    before = agent.law
    res = ros2_param_set(ex, probe, '/agent_1/agent', 'gain', '6')
    assert not res.successful and 'Picky raised ValueError: gain 6 with neighbours' in res.reason, res.reason
    assert agent.law is before and agent.get_parameter('gain').value == 1.0
    assert 'law parameters gain=6.0' in agent.reject.lines[-1]
    assert step()                                                     # the agent goes on
    assert ros2_param_set(ex, probe, '/agent_1/agent', 'gain', '4').successful
    assert step() and agent.u_history[-1][1] == pytest.approx(0.04)
    probe.destroy_node()
    for nd in nodes[:1]:
        nd.destroy_node()
