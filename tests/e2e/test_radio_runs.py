"""The communication model in the ROS nodes: a lockstep run with loss, latency, jitter, a
per-link override and a scheduled partition equals the batch engine (positions and u exactly;
headings, rebuilt from quaternions, to 1e-9) and the world publishes the scheduled events on
/swarm/events, also with faults (a frozen follower, a killed leader and failover) on top; a
realtime agent delays incoming states by the latency, and ``swarm drop`` (a CLI process) cuts
what it receives, after which the silent neighbour is forgotten; ``swarm drop 0`` restores it;
so do ``swarm partition`` / ``--heal``."""
import json
import math
import subprocess

import numpy as np
import rclpy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String

from swarm_agent.agent_node import AgentNode
from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.layouts import ProcessStates
from swarm_ros.rosutil import make_executor
from swarm_tools.run.launch import build_nodes
from swarm_tools.run.params import agent_parameters, node_parameters
from tests.helpers import overrides, run_nodes, short_homotopy, spin_for

#: a lossy, delayed radio with one worse link and a partition from t = 5 to 8
COMMS = {'loss': 0.25, 'latency': 0.1, 'jitter': 0.1, 'timeout': 0.6,
         'links': [{'sender': 'agent_0', 'receiver': 'agent_3', 'loss': 0.9}],
         'events': [{'at': 5.0, 'partition': [['agent_0', 'agent_1', 'agent_2']]}, {'at': 8.0, 'partition': []}]}


def comms_scenario(path, **overrides):
    """The six agents over `COMMS` for 12 s (λ rises at t = 4, falls at t = 9), ``overrides``:
    further scenario keys."""
    return short_homotopy(path, name='comms_short', seed=5, duration=12.0, at=2.0, comms=COMMS,
                          lam={'kind': 'tanh_window', 'rise_at': 4.0, 'fall_at': 9.0, 'tau': 1.5}, **overrides)


def test_lockstep_with_a_lossy_delayed_radio_equals_the_batch_engine(tmp_path, rclpy_context):
    path = comms_scenario(tmp_path / 'comms_short.yaml')
    scn = load(str(path))
    out = tmp_path / 'run'
    params = node_parameters(scn, str(path), 'lockstep', output_dir=str(out))
    assert json.loads(params['/agent_3/agent']['comms'])['loss'] == 0.25
    ctx = rclpy_context
    world, commander, agents = build_nodes(params, ctx, log=lambda *a, **k: None)
    probe = rclpy.create_node('probe', context=ctx)
    events = []
    probe.create_subscription(String, P.EVENTS, lambda m: events.append(json.loads(m.data)), P.qos_latched(100))
    ex = make_executor(ctx)
    for nd in [world, commander, *agents, probe]:
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.done, 240.0)
    assert world.failed is None
    spin_for(ex, lambda: sum(e['kind'] == 'comms' for e in events) >= 2, 5.0)
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(scn)
    assert ref.leader.any() and ref.lam.max() > 0.9
    assert 0.5 < ref.meta['comms']['delivered_fraction'] < 0.8
    np.testing.assert_array_equal(got.r, ref.r)                # exact: the same law, the same order
    np.testing.assert_array_equal(got.u, ref.u)
    assert np.abs(got.theta - ref.theta).max() <= 1e-9         # θ comes back through the quaternion
    # the radio mattered: the perfect radio flies differently
    perfect = simulate(_perfect(path))
    assert np.abs(perfect.r - ref.r).max() > 1e-3
    # each agent's radio counted what the engine's did for its incoming links
    a3 = [a for a in agents if a.agent_name == 'agent_3'][0]
    assert a3.core.beliefs.delivered[0, 0] < a3.core.beliefs.delivered[0, 1]      # the 0.9 link
    # (the commander's events — leaders chosen — share the topic)
    assert [(e['t'], e['kind'], e['source'], e['partition']) for e in events if e['kind'] == 'comms'] == [
        (5.0, 'comms', 'scenario', [['agent_0', 'agent_1', 'agent_2']]), (8.0, 'comms', 'scenario', [])]
    for nd in [world, commander, *agents, probe]:
        nd.destroy_node()


FAULTS = dict(faults=[{'at': 3.0, 'freeze': 'agent_4', 'for': 1.5}, {'at': 6.0, 'kill': 'leader:0'}],
              failover={'timeout': 0.5}, reunion=[{'at': 9.0, 'for': 2.0, 'point': 'centroid', 'coupling': 1.0}])


def test_lockstep_radio_with_faults_failover_and_reunion_equals_the_batch_engine(tmp_path, rclpy_context):
    """Nodes in one executor (no processes to signal: a dead or frozen agent obeys the table's
    alive mask): the radio hears nothing from agents out of the table, a frozen agent hears
    nothing while frozen, and the run equals the batch engine (positions and u exactly), dead rows and all."""
    path = comms_scenario(tmp_path / 'comms_faults.yaml', **FAULTS)
    scn = load(str(path))
    ref = simulate(scn)
    kinds = [e['kind'] for e in ref.meta['events']]
    assert 'kill' in kinds and 'freeze' in kinds and 'failover' in kinds and 'rendezvous_on' in kinds, kinds
    assert not np.isfinite(ref.r[-1]).all()                  # the killed leader's rows are NaN
    out = tmp_path / 'run'
    params = node_parameters(scn, str(path), 'lockstep', output_dir=str(out))
    done, world, nodes = run_nodes(params, rclpy_context, 240.0)
    assert done and world.failed is None
    got = Trajectory.load(out / 'trajectory.npz')
    assert np.array_equal(np.isfinite(got.r), np.isfinite(ref.r))
    fin = np.isfinite(ref.r)
    np.testing.assert_array_equal(got.r[fin], ref.r[fin])      # exact
    assert np.nanmax(np.abs(got.theta - ref.theta)) <= 1e-9    # θ comes back through the quaternion
    both = np.isfinite(got.u) & np.isfinite(ref.u)
    np.testing.assert_array_equal(got.u[both], ref.u[both])
    assert np.array_equal(got.leader, ref.leader)
    for nd in nodes:
        nd.destroy_node()


def _perfect(path):
    import yaml

    from swarm_core.scenario.loader import parse
    data = yaml.safe_load(path.read_text())
    data.pop('comms')
    return parse(data, str(path))


def test_realtime_latency_and_swarm_drop(rclpy_context, swarm_cmd, processes):
    scn = load('homotopy_global')
    ctx = rclpy_context
    ex = make_executor(ctx)
    prm = dict(agent_parameters(scn, 1, 'realtime'), comms=json.dumps(dict(latency=0.2, timeout=0.5)))
    agent = AgentNode('agent', namespace='agent_1', context=ctx, parameter_overrides=overrides(prm))
    probe = rclpy.create_node('probe', context=ctx)
    clock = probe.create_publisher(Clock, '/clock', 10)
    states = probe.create_publisher(Float64MultiArray, P.AGENT_STATES, P.qos_latched(10))   # agent_0's process
    ex.add_node(agent)
    ex.add_node(probe)
    assert agent.radio_on
    assert spin_for(ex, lambda: clock.get_subscription_count() and states.get_subscription_count())
    t = [0.0]
    lags = []

    def tick(k):
        for _ in range(k):
            t[0] = round(t[0] + scn.dt, 10)
            c = Clock()
            c.clock.sec, c.clock.nanosec = P.time_to_stamp(t[0])
            clock.publish(c)
            states.publish(ProcessStates(9.0, [0], [t[0]], np.array([[-1.0 + t[0]], [1.0], [0.0], [1.0]]), [0.0])
                           .to_cdr(agent.run_id))
            spin_for(ex, lambda: False, 0.03)
            if 0 in agent.driver.stream.newest:              # agent_0's newest delivered state
                lags.append(agent._now() - agent.driver.stream.newest[0][0])

    def counts():
        """(heard, delivered) of agent_0's states at the radio."""
        j = agent.roster.index('agent_0')
        return int(agent.driver.stream.heard[j]), int(agent.driver.stream.delivered[j])

    def known():
        """agent_0 is in agent_1's control table (only agent_0 publishes states here)."""
        _, rows, _ = agent.driver.table(agent._now())
        return len(rows) == 2

    tick(30)
    heard, got = counts()
    assert heard >= 10 and got == heard                     # no loss configured
    assert lags and min(lags) >= 0.2 - 1e-9                  # never fresher than the latency
    assert known()

    def run_cli(*args):
        p = processes.start([swarm_cmd, *args, '--wait', '20'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
        while p.poll() is None:
            tick(1)
        out = p.stdout.read()
        assert p.returncode == 0, out
        return out

    run_cli('drop', '1.0')
    assert agent.radio.burst[0] == 1.0
    tick(2)
    heard0, got0 = counts()
    tick(20)                                                 # 1 s > timeout + latency
    heard1, got1 = counts()
    assert heard1 >= heard0 + 10 and got1 == got0            # heard, never delivered
    assert not known()                                       # silent > timeout: forgotten
    run_cli('drop', '0')
    tick(20)
    heard2, got2 = counts()
    assert got2 >= got1 + 5 and known()
    # agent_1 in a group of its own (agent_0: the rest) cuts the link; --heal restores it.  A name
    # the swarm lacks is refused once --wait is up (the verb waits that long for every name)
    bad = processes.start([swarm_cmd, 'partition', 'agent_1,ghost', '--wait', '5'], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True)
    while bad.poll() is None:
        tick(1)
    assert bad.returncode == 2 and "unknown agent 'ghost'" in bad.stdout.read()
    run_cli('partition', 'agent_1')
    tick(2)
    _, got3 = counts()
    tick(20)
    assert counts()[1] == got3 and not known()
    run_cli('partition', '--heal')
    tick(20)
    assert counts()[1] >= got3 + 5 and known()
    assert math.isfinite(agent.core.theta[0])
    probe.destroy_node()


def test_realtime_container_radio_agents_hear_their_container_mates(rclpy_context):
    """A planar realtime container of agents 0-2, each with a lossless radio (latency 0.1): on
    the container's own ticks each hears its two container-mates through its radio (their states
    never come back over DDS), delivered no fresher than the latency, and flies on them; a state
    claiming to be a container-mate from another publisher is refused."""
    from swarm_agent.container_node import AgentContainer
    scn = load('homotopy_global')
    ctx = rclpy_context
    names = scn.names[:3]
    comms = json.dumps(dict(latency=0.1, timeout=1.0))
    box = AgentContainer(names, context=ctx, agent_overrides={
        nm: overrides(dict(agent_parameters(scn, k, 'realtime'), comms=comms)) for k, nm in enumerate(names)})
    probe = rclpy.create_node('probe', context=ctx)
    clock = probe.create_publisher(Clock, '/clock', 10)
    states = probe.create_publisher(Float64MultiArray, P.AGENT_STATES, P.qos_latched(10))   # another process
    ex = make_executor(ctx)
    for nd in [box, *box.agents, probe]:
        ex.add_node(nd)
    assert all(a.radio_on for a in box.agents)
    assert spin_for(ex, lambda: clock.get_subscription_count() and states.get_subscription_count())
    t = [0.0]

    def tick(k):
        for _ in range(k):
            t[0] = round(t[0] + scn.dt, 10)
            c = Clock()
            c.clock.sec, c.clock.nanosec = P.time_to_stamp(t[0])
            clock.publish(c)
            spin_for(ex, lambda: False, 0.03)

    tick(20)
    for a in box.agents:
        stream = a.driver.stream
        mates = sorted(b.index for b in box.agents if b is not a)
        assert sorted(stream.newest) == mates, a.agent_name
        assert all(stream.heard[j] >= 10 and stream.delivered[j] == stream.heard[j] for j in mates)
        assert all(a._now() - stream.newest[j][0] >= 0.1 - 1e-9 for j in mates)       # the latency
        _, rows, _ = a.driver.table(a._now())
        assert len(rows) == 3                                   # it flies on its mates
    spoof = ProcessStates(9.0, [1], [t[0]], np.array([[5.0], [5.0], [0.0], [1.0]]), [0.0])
    n, heard = box.agents[0].reject.count, box.agents[0].driver.stream.heard[1]
    states.publish(spoof.to_cdr(box.agents[0].run_id))
    assert spin_for(ex, lambda: box.agents[0].reject.count > n, 5.0)
    assert 'dup-self' in box.agents[0].reject.kinds
    assert box.agents[0].driver.stream.heard[1] == heard                  # never reached its radio
    probe.destroy_node()
