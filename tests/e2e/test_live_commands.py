"""Live commands from the shell (docs/commands.md).

- ``ros2 topic pub --once`` (the Jazzy tool, emulated in ``tests/fakes/emulate_topic_pub.py``: default
  QoS RELIABLE/VOLATILE/KEEP_LAST 10, waits for >= 1 matching subscription, publishes once,
  keeps alive 0.1 s, exits) takes effect on the first try, on /swarm/lambda and on a steering
  topic, against a realtime run with ``--record``; ``ros2 param set /commander ...`` too.
- A lockstep run steered live (λ and steering) is re-run exactly by the batch engine from the
  ``command`` events the run wrote (``swarm simulate --replay``).
"""
import json
import subprocess
import threading
import time

import numpy as np

from tests.fakes.emulate_topic_pub import main as topic_pub_once
from tests.fakes.ros2cli_verbs import NodeNotFound, param_set
from tests.helpers import Lines, short_homotopy


def _pub_once_in_own_context(topic, value):
    """The tool in a fresh rclpy Context (a fresh DDS participant, as a new process has)."""
    from rclpy.context import Context
    return topic_pub_once([topic, 'std_msgs/msg/Float64', f'{{data: {value}}}'], context=Context())


def test_topic_pub_once_and_param_set_take_effect_every_time(tmp_path, ros_domain, processes, swarm_cmd, rclpy_context):
    """20 tries of the emulated ``ros2 topic pub --once`` (10 on /swarm/lambda, 10 on
    /agent_0/steering, each a new value; after the first, two at a time side by side) against
    a realtime ``swarm run --record``: after each one the commander publishes the new value
    (its ``ramp`` parameter is set to 0 first, with
    ``ros2 param set``, tests/fakes/ros2cli_verbs.py), and ``/swarm/events`` holds exactly
    one ``command`` event per try.  ``ros2 param set /commander lambda 0.77`` is applied the
    same way; ``lambda 1.5`` is refused."""
    import rclpy
    from std_msgs.msg import Float64, String

    from swarm_ros import protocol as P
    from swarm_ros.rosutil import make_executor
    from tests.helpers import spin_for

    # dt 0.1: a realtime run's CPU grows with its rate, and the commands need no more
    path = short_homotopy(tmp_path / 'rt.yaml', duration=100000, lam='{kind: constant, value: 0.0}', at=1e6, dt=0.1)
    run = processes.start([swarm_cmd, 'run', path, '--mode', 'realtime', '--record', tmp_path / 'bag.mcap',
                           '--out', tmp_path / 'out', '--no-figure'],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(run)
    node = rclpy.create_node('observer', context=rclpy_context)
    ex = make_executor(rclpy_context)
    ex.add_node(node)
    seen = {'lambda': [], 'steer': []}
    events = []
    # transient-local, as `swarm record` reads them: these readers never match the tool's volatile writer
    node.create_subscription(Float64, P.LAMBDA, lambda m: seen['lambda'].append(m.data), P.qos_latched(100))
    node.create_subscription(Float64, '/agent_0/steering', lambda m: seen['steer'].append(m.data), P.qos_latched(100))
    node.create_subscription(String, P.EVENTS, lambda m: events.append(json.loads(m.data)), P.qos_latched(100))
    assert spin_for(ex, lambda: len(seen['lambda']) >= 3, 180), ''.join(lines.lines[-30:])

    def set_param(name, value):
        """``ros2 param set /commander NAME VALUE`` (tests/fakes/ros2cli_verbs.py: a fresh
        participant, the tool's waits), run again as a user would while it says 'Node not found'."""
        got = []

        def shell():
            for _ in range(10):
                try:
                    got.append(param_set('/commander', name, str(value)))
                    return
                except NodeNotFound:
                    pass
        t = threading.Thread(target=shell)
        t.start()
        assert spin_for(ex, lambda: not t.is_alive(), 120) and got, (name, value)
        return got[0]

    assert set_param('ramp', 0.0).successful
    taken = []
    tries = [('/swarm/lambda', 'lambda', 0.3 + 0.02 * k) if k % 2 == 0 else
             ('/agent_0/steering', 'steer', 0.001 * (k + 1)) for k in range(20)]
    # λ first on its own (it fires the leader rule; steering first would make agent_0 a leader
    # by hand), then a steering and a λ try side by side: two tools, each its own participant
    for k in range(-1, 20, 2):
        pair = tries[max(k, 0):k + 2]
        ts = [threading.Thread(target=_pub_once_in_own_context, args=(topic, value)) for topic, _, value in pair]
        t0 = time.monotonic()
        for t in ts:
            t.start()
        spin_for(ex, lambda ts=ts: not any(t.is_alive() for t in ts), 120)
        for topic, key, value in pair:
            hit = spin_for(ex, lambda key=key, value=value: value in seen[key], 30)
            taken.append((topic, value, hit, round(time.monotonic() - t0, 2)))
    assert all(h for _, _, h, _ in taken), '\n'.join([str(x) for x in taken] + [
        ln.rstrip() for ln in lines.lines if 'commander' in ln][-40:])
    assert not set_param('lambda', 1.5).successful
    assert set_param('lambda', 0.77).successful
    assert spin_for(ex, lambda: 0.77 in seen['lambda'], 30)
    assert spin_for(ex, lambda: sum(e.get('kind') == 'command' for e in events) >= 21, 30)
    cmds = [e for e in events if e.get('kind') == 'command']
    assert sorted(round(e['value'], 9) for e in cmds if e['source'] == P.LAMBDA) == \
        [round(0.3 + 0.02 * k, 9) for k in range(0, 20, 2)]
    assert [e['agent'] for e in cmds if e['command'] == 'steer'] == ['agent_0'] * 10
    assert [e['source'] for e in cmds][-1] == 'parameter lambda' and all('step' in e for e in cmds)
    # the leader rule fired when λ rose (the scenario's clock time is never reached)
    assert any(e.get('kind') == 'leaders_chosen' for e in events)
    node.destroy_node()


def test_lockstep_live_commands_replay_in_the_batch_engine(tmp_path, rclpy_context):
    """Lockstep, nodes in one executor: λ = 1 from ``ros2 topic pub --once`` (emulated, its own
    participant) at some step, later steering -0.02 for agent_1.  The run's events.jsonl
    names the step each was applied at; the batch engine given those commands (``swarm
    simulate --replay``) reproduces the ROS trajectory: positions, λ and leaders bit for bit,
    θ and u to 1e-9 (θ travels as a quaternion).  Raising λ also fired the
    leader rule (the scenario's clock time for it is never reached)."""
    from swarm_core.command.plan import read_commands
    from swarm_core.engine.reference import simulate
    from swarm_core.scenario.loader import load
    from swarm_ros.rosutil import make_executor
    from swarm_tools.run.launch import build_nodes
    from swarm_tools.run.params import node_parameters
    from tests.helpers import spin_for

    path = short_homotopy(tmp_path / 'lock.yaml', duration=25, lam='{kind: constant, value: 0.0}', at=1e6)
    scn = load(str(path))
    out = tmp_path / 'out'
    params = node_parameters(scn, str(path), 'lockstep', output_dir=str(out))
    world, commander, agents = build_nodes(params, rclpy_context, log=lambda *a, **k: None)
    ex = make_executor(rclpy_context, events=False)   # a wait-set executor: nodes can leave and come back
    for nd in [world, commander, *agents]:
        ex.add_node(nd)

    def command(topic, value, at_step):
        assert spin_for(ex, lambda: world.driver.lock.cur >= at_step, 120)
        n = len([e for e in world.events if e['kind'] == 'command'])
        t = threading.Thread(target=_pub_once_in_own_context, args=(topic, value))
        t.start()
        # the swarm waits (world and agents not spun) while the tool runs; the commander
        # answers the graph and takes the command
        for nd in [world, *agents]:
            ex.remove_node(nd)
        assert spin_for(ex, lambda: not t.is_alive(), 120)
        for nd in [world, *agents]:
            ex.add_node(nd)
        assert spin_for(ex, lambda: len([e for e in world.events if e['kind'] == 'command']) > n, 60)

    command('/swarm/lambda', 1.0, 100)
    command('/agent_1/steering', -0.02, 250)
    assert spin_for(ex, lambda: world.done, 300)
    got = world.trajectory()
    lines = (out / 'events.jsonl').read_text().splitlines()
    commands = read_commands(lines, scn.names)
    assert sum(len(v) for v in commands.values()) == 2, lines
    ref = simulate(scn, commands=commands)
    assert np.array_equal(got.r, ref.r)                  # positions bit for bit
    assert np.abs(got.theta - ref.theta).max() <= 1e-9   # θ comes back from the quaternion
    assert np.abs(got.u - ref.u).max() <= 1e-9
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)
    assert got.lam.max() > 0.9 and got.leader[:, 1].any()
    assert any(json.loads(ln)['kind'] == 'leaders_chosen' for ln in lines)
    chosen = [e for e in ref.meta['events'] if e['kind'] == 'leaders_chosen']
    step_lam = min(commands)
    assert chosen and step_lam * scn.dt < chosen[0]['t'] < step_lam * scn.dt + 5.0
