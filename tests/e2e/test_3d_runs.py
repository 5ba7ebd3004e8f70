"""End-to-end in 3D (``dim: 3``): `swarm run` in lockstep, with agent processes and with agent
containers, equals `swarm simulate` bit for bit (r, x, y, z, u, v, λ, leaders), with faults
too; the bag's /swarm/states carry the full pose (the quaternion of the frame [x y z]) and
twist.angular = (0, −v, u); with a radio model (each agent its own beliefs) and faults bit for bit
too; a realtime 3D run splits on a live `swarm lambda 1`; robots are refused in one line before
anything starts."""
import re
import signal
import subprocess

import numpy as np
import pytest

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.model.natural import frame_from_quaternion_3d, quaternion_from_frame
from swarm_core.scenario.loader import load
from tests.agent.test_natural_core import short_3d
from tests.helpers import Lines

KEYS = ('r', 'x', 'y', 'z', 'u', 'v', 'lam', 'leader')


def bag_states(path):
    """{(agent, step): (position (3,), quaternion (4,), angular (3,))} of the bag's /swarm/states."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message

    from swarm_tools.bags.mcap_io import iter_messages
    out = {}
    for m in iter_messages(path, ['/swarm/states']):
        o = deserialize_message(m.data, Odometry)
        p, q, w = o.pose.pose.position, o.pose.pose.orientation, o.twist.twist.angular
        k = round((o.header.stamp.sec + o.header.stamp.nanosec * 1e-9) / 0.1)
        out[o.child_frame_id, k] = (np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]),
                                    np.array([w.x, w.y, w.z]))
    return out


@pytest.mark.parametrize('per', [1, 3], ids=['processes', 'containers'])
def test_3d_lockstep_equals_simulate(per, tmp_path, ros_domain, processes, swarm_cmd):
    path = short_3d(tmp_path / 'h3.yaml', duration=20.0)
    out, bag = tmp_path / 'run', tmp_path / 'run.mcap'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--agents-per-process', str(per)]
                        + (['--record', bag] if per == 3 else []),
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    got, ref = Trajectory.load(out / 'trajectory.npz'), simulate(load(str(path)))
    assert got.r.shape == ref.r.shape == (201, 6, 3)
    for key in KEYS:
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)      # exact
    assert ref.leader.any() and ref.lam.max() > 0.5 and np.abs(ref.v).max() > 0
    if per != 3:
        return
    states = bag_states(bag)
    names = got.names
    assert len(states) == 202 * 6, len(states)            # steps 0 … 200, and 201 after the last u
    for (name, k), (pos, q, w) in states.items():
        if k > 200:
            continue
        i = names.index(name)
        np.testing.assert_array_equal(pos, got.r[k, i])
        np.testing.assert_array_equal(q, np.array(quaternion_from_frame(got.x[k, i], got.y[k, i], got.z[k, i]))[:, 0])
        frame = frame_from_quaternion_3d(*q)
        for f, want in zip(frame, (got.x[k, i], got.y[k, i], got.z[k, i])):
            np.testing.assert_allclose(f[0], want, atol=1e-12)
        held = (0.0, 0.0) if k == 0 else (got.u[k - 1, i], got.v[k - 1, i])
        np.testing.assert_array_equal(w, [0.0, -held[1], held[0]])                # REP 103: (0, −v, u)


def test_3d_on_robots_is_refused_in_one_line(tmp_path, swarm_cmd):
    """Robots are planar: a 3D run on robots is one line, exit 2, also with a radio model."""
    path = short_3d(tmp_path / 'h3.yaml', duration=5.0, comms={'loss': 0.3})
    r = subprocess.run([swarm_cmd, 'run', str(path), '--out', str(tmp_path / 'run'), '--robots', 'external'],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert 'robots are planar' in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def steered_lockstep(tmp_path, ctx, tool, duration=25.0, at=100):
    """A lockstep 3D run in one executor; at step ``at`` ``tool()`` runs in a thread (its own
    participant) while only the commander spins (the swarm waits).  Gives the scenario, the
    trajectory, the lines of events.jsonl and what ``tool`` returned."""
    import threading

    from swarm_ros.rosutil import make_executor
    from swarm_tools.run.launch import build_nodes
    from swarm_tools.run.params import node_parameters
    from tests.helpers import spin_for

    path = short_3d(tmp_path / 'h3.yaml', duration=duration)
    scn = load(str(path))
    out = tmp_path / 'out'
    world, commander, agents = build_nodes(node_parameters(scn, str(path), 'lockstep', output_dir=str(out)),
                                           ctx, log=lambda *a, **k: None)
    ex = make_executor(ctx, events=False)
    for nd in [world, commander, *agents]:
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.driver.lock.cur >= at, 120)
    said = []
    t = threading.Thread(target=lambda: said.append(tool()))
    t.start()
    for nd in [world, *agents]:              # the swarm waits while the tool runs; the commander takes it
        ex.remove_node(nd)
    assert spin_for(ex, lambda: not t.is_alive(), 120)
    for nd in [world, *agents]:
        ex.add_node(nd)
    assert spin_for(ex, lambda: world.done, 300)
    got = world.trajectory()
    for nd in [world, commander, *agents]:
        nd.destroy_node()
    return scn, got, (out / 'events.jsonl').read_text().splitlines(), said[0] if said else None


def replayed(scn, got, lines, value):
    """The one steer command in ``lines`` is (agent_1, ``value``), and the batch engine given it
    (``swarm simulate --replay``) equals the run bit for bit; it changed the run from its step on."""
    import json

    from swarm_core.command.plan import read_commands
    steer = [json.loads(ln) for ln in lines if '"steer"' in ln]
    assert len(steer) == 1 and steer[0]['value'] == value and steer[0]['agent'] == 'agent_1', lines
    ref = simulate(scn, commands=read_commands(lines, scn.names))
    for key in KEYS:
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)
    k = steer[0]['step']
    assert got.leader[k:, 1].all()
    plain = simulate(scn)
    assert np.array_equal(plain.v[:k], got.v[:k]) and not np.array_equal(plain.v[k:], got.v[k:])


def test_3d_live_steering_from_topic_pub_replays_in_simulate(tmp_path, rclpy_context):
    """``ros2 topic pub --once /agent_1/steering std_msgs/msg/Float64MultiArray "{data: [0.0,
    0.02]}"`` (emulated) at some step makes agent_1 a leader with s_k = (0, 0.02); events.jsonl
    names the step, and the batch engine given that command equals the run bit for bit."""
    from rclpy.context import Context

    from tests.fakes.emulate_topic_pub import main as topic_pub_once
    args = ['/agent_1/steering', 'std_msgs/msg/Float64MultiArray', '{data: [0.0, 0.02]}']
    replayed(*steered_lockstep(tmp_path, rclpy_context, lambda: topic_pub_once(args, context=Context()))[:3],
             [0.0, 0.02])


def test_3d_swarm_steer_takes_two_numbers_and_refuses_one(tmp_path, rclpy_context, capsys):
    """`swarm steer agent_1 0.02` in a 3D run is one line, exit 2, and sends nothing (the run
    announces ``dim: 3``); `swarm steer agent_1 0 0.02` steers it as ``ros2 topic pub`` does."""
    from swarm_tools.live.verbs import steer_main

    def tool():
        return steer_main(['agent_1', '0.02', '--wait', '60']), steer_main(['agent_1', '0', '0.02', '--wait', '60'])

    scn, got, lines, codes = steered_lockstep(tmp_path, rclpy_context, tool, duration=10.0, at=40)
    err = capsys.readouterr()
    assert codes == (2, 0), err
    refused = err.err.strip().splitlines()
    assert len(refused) == 1 and 'is 3D: give two numbers, s_u s_v (got 1)' in refused[0], err.err
    assert 'homotopy_3d' in refused[0] and 'swarm steer: agent_1 steering (0, 0.02)' in err.out, err
    replayed(scn, got, lines, [0.0, 0.02])


@pytest.mark.parametrize('per', [1, 3], ids=['processes', 'containers'])
def test_3d_lockstep_with_faults_equals_simulate(per, tmp_path, ros_domain, processes, swarm_cmd):
    """A kill at t = 5 and a freeze from t = 8 for 3 s (signals to a lone agent's process; a
    container obeys the events for its agent): r, x, y, z exactly (NaN where dead, held while
    frozen), u and v where both know them (a killed agent's last u never reaches the world)."""
    path = short_3d(tmp_path / 'h3f.yaml', duration=15.0,
                    faults=[{'at': 5, 'kill': 'agent_2'}, {'at': 8, 'freeze': 'agent_4', 'for': 3}])
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--agents-per-process', str(per)],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    assert not any('lost' in ln for ln in lines.lines), ''.join(lines.lines[-40:])
    got, ref = Trajectory.load(out / 'trajectory.npz'), simulate(load(str(path)))
    for key in ('r', 'x', 'y', 'z', 'lam', 'leader'):
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)
    assert np.isnan(got.r[51:, 2]).all() and np.all(np.diff(got.r[81:110, 4, 0]) == 0)
    for key in ('u', 'v'):
        a, b = getattr(got, key), getattr(ref, key)
        both = np.isfinite(a) & np.isfinite(b)
        assert np.isnan(a[np.isnan(b)]).all() and both.mean() > 0.85
        np.testing.assert_array_equal(a[both], b[both], err_msg=key)


@pytest.mark.parametrize('per', [1, 3], ids=['processes', 'containers'])
def test_3d_lockstep_with_a_radio_and_faults_equals_simulate(per, tmp_path, ros_domain, processes, swarm_cmd):
    """Each agent hears the step's table through its own radio (loss, latency, jitter, a range,
    a worse link, a scheduled partition) with a frozen follower and a killed agent (signals to a
    lone agent's process; a container obeys the events): r, x, y, z, λ and the leaders exactly,
    u and v where both know them."""
    from tests.agent.test_natural_core import radio_3d
    scn = radio_3d(tmp_path / 'h3r.yaml', duration=10.0)
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', scn.source, '--out', out, '--no-figure', '--agents-per-process', str(per)],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    assert not any('lost' in ln for ln in lines.lines), ''.join(lines.lines[-40:])
    got, ref = Trajectory.load(out / 'trajectory.npz'), simulate(scn)
    assert 0.4 < ref.meta['comms']['delivered_fraction'] < 0.8 and ref.leader.any()
    for key in ('r', 'x', 'y', 'z', 'lam', 'leader'):
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)
    assert np.isnan(got.r[61:, 2]).all() and np.all(np.diff(got.r[31:50, 4, 0]) == 0)
    for key in ('u', 'v'):
        a, b = getattr(got, key), getattr(ref, key)
        both = np.isfinite(a) & np.isfinite(b)
        assert np.isnan(a[np.isnan(b)]).all() and both.mean() > 0.85
        np.testing.assert_array_equal(a[both], b[both], err_msg=key)


@pytest.mark.parametrize('per, comms', [(1, None), (3, {'loss': 0.3, 'latency': 0.1, 'jitter': 0.1, 'timeout': 1.0})],
                         ids=['processes', 'containers-radio'])
def test_3d_realtime_splits_on_a_live_swarm_lambda(per, comms, tmp_path, ros_domain, processes, swarm_cmd):
    """Realtime at rtf 4, λ = 0 in the scenario, leaders chosen at t = 5: `swarm lambda 1.0`
    at t ≥ 20 splits the 3D swarm in two (the world's progress line, clusters in space); the
    trajectory holds r, x, y, z and v, orthonormal frames, and unit speed.  Also in agent
    containers whose agents hear through a lossy, delayed radio (each its own table, its
    container's other agents heard through it too)."""
    from swarm_core.analysis.metrics import cluster_labels_3d
    path = short_3d(tmp_path / 'h3rt.yaml', duration=260.0, leaders_at=5, **{'lambda': {'kind': 'constant',
                                                                                      'value': 0.0}},
                    **({'comms': comms} if comms else {}))
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--mode', 'realtime', '--rtf', '4', '--out', out, '--no-figure',
                         '--progress-every', '5', '--agents-per-process', str(per)],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    progress = re.compile(r'\[world\] t= *([\d.]+)  clusters=(\d+)  λ=([\d.]+)')

    def reported(ln, t=0.0, clusters=1, lam=0.0):
        m = progress.search(ln)
        return bool(m) and float(m[1]) >= t and int(m[2]) >= clusters and float(m[3]) >= lam

    assert lines.wait_for(lambda ln: reported(ln, t=20), 120), ''.join(lines.lines)
    cli = subprocess.run([swarm_cmd, 'lambda', '1.0', '--ramp', '5'], capture_output=True, text=True, timeout=60)
    assert cli.returncode == 0, cli.stderr
    assert lines.wait_for(lambda ln: reported(ln, clusters=2, lam=1.0), 180), ''.join(lines.lines[-30:])
    p.send_signal(signal.SIGINT)
    assert lines.wait(p, 60) == 130, ''.join(lines.lines[-30:])
    got = Trajectory.load(out / 'trajectory.npz')
    assert got.dim == 3 and np.isfinite(got.r).all() and np.isfinite(got.z).all()
    t_cli = got.t[np.argmax(got.lam > 0.0)]
    assert t_cli >= 19 and got.lam[-1] == 1.0 and got.leader[-1].sum() == 2
    f = np.stack([got.x[-1], got.y[-1], got.z[-1]], axis=1)
    assert np.abs(np.einsum('kac,kbc->kab', f, f) - np.eye(3)).max() < 1e-9
    speed = np.median(np.linalg.norm(np.diff(got.r, axis=0), axis=2), axis=0) / (got.t[1] - got.t[0])
    assert np.all((speed > 0.95) & (speed < 1.01)), speed           # unit speed (the median step)
    assert cluster_labels_3d(got.r[np.searchsorted(got.t, t_cli) - 1], 4.0)[0] == 1
    assert cluster_labels_3d(got.r[-1], 4.0)[0] >= 2


def test_3d_realtime_radio_drops_what_its_loss_says_and_obeys_swarm_drop(rclpy_context, swarm_cmd, processes):
    """A realtime 3D agent (agent_1) hears agent_0's process through its radio: exactly the
    states whose fate (`radio.link_uniforms`, stream 0) beats the loss are delivered, never one
    fresher than the latency; it flies on them (agent_0 is in its table, dead-reckoned in space);
    `swarm drop 1.0` cuts them until agent_0 is forgotten, and `swarm drop 0` restores them."""
    import json

    import rclpy
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64MultiArray

    from swarm_agent.agent_node import AgentNode
    from swarm_core.radio import link_uniforms
    from swarm_ros import protocol as P
    from swarm_ros.layouts import NaturalProcessStates
    from swarm_ros.rosutil import make_executor
    from swarm_tools.run.params import agent_parameters
    from tests.helpers import overrides, spin_for

    scn = load('homotopy_3d')
    comms = dict(loss=0.3, latency=0.2, timeout=0.5, seed=11)
    ex = make_executor(rclpy_context)
    prm = dict(agent_parameters(scn, 1, 'realtime'), comms=json.dumps(comms))
    agent = AgentNode('agent', namespace='agent_1', context=rclpy_context, parameter_overrides=overrides(prm))
    probe = rclpy.create_node('probe', context=rclpy_context)
    clock = probe.create_publisher(Clock, '/clock', 10)
    states = probe.create_publisher(Float64MultiArray, P.AGENT_STATES, P.qos_latched(10))   # agent_0's process
    ex.add_node(agent)
    ex.add_node(probe)
    assert agent.radio_on and agent.dim == 3
    assert spin_for(ex, lambda: clock.get_subscription_count() and states.get_subscription_count())
    t, lags, fates = [0.0], [], []
    stream = agent.driver.stream
    hear = stream.hear

    def heard_by_radio(j, state, own):                       # each state's stamp and fate
        fates.append((state[0], hear(j, state, own)))
        return fates[-1][1]
    stream.hear = heard_by_radio

    def tick(k):
        for _ in range(k):
            t[0] = round(t[0] + scn.dt, 10)
            c = Clock()
            c.clock.sec, c.clock.nanosec = P.time_to_stamp(t[0])
            clock.publish(c)
            pose = np.array([-1.0 + t[0], 1.0, 0.5, 1, 0, 0, 0, 1, 0, 0, 0, 1], float)[:, None]  # along x
            states.publish(NaturalProcessStates(9.0, [0], [t[0]], pose, [[0.0, 0.0]]).to_cdr(agent.run_id))
            spin_for(ex, lambda: False, 0.03)
            if 0 in stream.newest:
                lags.append(agent._now() - stream.newest[0][0])

    def counts():
        return int(stream.heard[0]), int(stream.delivered[0])

    def known():
        rows, table = stream.table(agent._now(), np.zeros(12))
        return list(rows) == [0, 1] and table.shape == (2, 12)

    tick(60)
    heard, got = counts()
    assert heard >= 30 and len(fates) == heard
    stamps, delivered = np.array(fates).T
    assert np.array_equal(delivered.astype(bool), link_uniforms(comms['seed'], np.round(stamps / scn.dt).astype(int),
                                                                 1, 0) >= comms['loss'])
    assert 0 < got < heard
    assert lags and min(lags) >= 0.2 - 1e-9 and known()
    assert np.isfinite(agent.core.row[0]).all() and agent.step > 0       # it flies

    def run_cli(*args):
        p = processes.start([swarm_cmd, *args, '--wait', '20'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
        while p.poll() is None:
            tick(1)
        out = p.stdout.read()
        assert p.returncode == 0, out
        return out

    run_cli('drop', '1.0')
    tick(2)
    heard0, got0 = counts()
    tick(20)                                                 # 1 s > timeout + latency
    heard1, got1 = counts()
    assert heard1 >= heard0 + 10 and got1 == got0 and not known()
    run_cli('drop', '0')
    tick(20)
    assert counts()[1] >= got1 + 5 and known()
    probe.destroy_node()
