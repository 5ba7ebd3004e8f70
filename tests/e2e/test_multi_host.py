"""One run over two hosts, emulated with two Linux network namespaces joined by a veth pair.

Host A (namespace A, 10.231.X.1) runs `swarm run --remote-agents 3-5 --record`: the discovery
server, world, commander, recorder and agents 0-2.  Host B (namespace B, 10.231.X.2) runs
`swarm join --agents 3-5 --server 10.231.X.1:PORT`.  Each side's DDS profile uses only its veth
address; the namespaces share no loopback, so everything between A and B crosses the veth.
The namespaces and the veth pair are made and removed by the test (root and `ip` needed)."""
import contextlib
import os
import shutil
import subprocess
from collections import defaultdict

import numpy as np
import pytest

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from tests.helpers import Lines, short_homotopy

IP = shutil.which('ip')


def _ip(*args, check=True):
    return subprocess.run([IP, *args], capture_output=True, text=True, timeout=30, check=check)


def _netns_pids(ns):
    r = _ip('netns', 'pids', ns, check=False)
    return [int(x) for x in r.stdout.split()] if r.returncode == 0 else []


def names_for(tag):
    """(namespaces, veth ends) of ``tag``: unique per test process, at most 15 characters."""
    return (f'swA{tag}', f'swB{tag}'), (f'swv{tag}a', f'swv{tag}b')


@contextlib.contextmanager
def two_hosts(tag):
    """{'A': (netns, address), 'B': ...} joined by a veth pair; removed on exit, also on failure
    (any process still in a namespace is SIGKILLed by pid first: all were started by this test)."""
    net = f'10.231.{int(tag) % 250}'
    (ns_a, ns_b), veth = names_for(tag)
    hosts = {'A': (ns_a, f'{net}.1'), 'B': (ns_b, f'{net}.2')}
    made = []
    try:
        for ns, _addr in hosts.values():
            _ip('netns', 'add', ns)
            made.append(ns)
        _ip('link', 'add', veth[0], 'type', 'veth', 'peer', 'name', veth[1])
        for (ns, addr), dev in zip(hosts.values(), veth):
            _ip('link', 'set', dev, 'netns', ns)
            _ip('-n', ns, 'addr', 'add', f'{addr}/24', 'dev', dev)
            _ip('-n', ns, 'link', 'set', dev, 'up')
            _ip('-n', ns, 'link', 'set', 'lo', 'up')     # its own address is delivered via lo
        yield hosts
    finally:
        for ns in made:
            for pid in _netns_pids(ns):
                try:
                    os.kill(pid, 9)
                except ProcessLookupError:
                    pass
            _ip('netns', 'del', ns, check=False)        # removes the veth end inside it (and its peer)
        _ip('link', 'del', veth[0], check=False)         # if the pair never moved into a namespace


def _on_two_hosts(test, *args):
    """Run ``test(hosts, *args)`` on two fresh network namespaces; then nothing is left running,
    and no namespace or veth is left behind."""
    if os.geteuid() != 0:
        pytest.skip('needs root to create network namespaces (ip netns add)')
    if IP is None:
        pytest.skip('needs the ip command (iproute2)')
    processes = args[-1]
    tag = str(os.getpid() % 100000)
    with two_hosts(tag) as hosts:
        try:
            test(hosts, *args)
        finally:
            processes.stop_all()
    namespaces, veth = names_for(tag)
    listed = _ip('netns', 'list').stdout.split()
    assert not [ns for ns in namespaces if ns in listed], listed
    assert all(_ip('link', 'show', dev, check=False).returncode != 0 for dev in veth)


def test_one_run_over_two_hosts(tmp_path, ros_domain, processes, swarm_cmd):
    """Agents split over both hosts; lockstep equals `swarm simulate`; the bag recorded on A holds
    every agent's states."""
    _on_two_hosts(run_over, tmp_path, swarm_cmd, processes)


def test_robot_agents_join_from_another_host(tmp_path, ros_domain, processes, swarm_cmd):
    """``swarm run --remote-agents 3-5 --robots mujoco:agent_2-agent_4`` on A, ``swarm join
    --agents 3-5`` on B: B starts agent_3 and agent_4 as robot agents (the run announced them),
    whose robots are in A's MuJoCo world, and the run equals the same run on one host, bit for bit."""
    _on_two_hosts(robots_over, tmp_path, swarm_cmd, processes)


def robots_over(hosts, tmp_path, swarm_cmd, processes):
    (ns_a, addr_a), (ns_b, addr_b) = hosts['A'], hosts['B']
    path = short_homotopy(tmp_path / 'robots.yaml', duration=6, lam='{kind: constant, value: 0.0}', at=2,
                          curvature=0.05, robots={'length_scale': 0.3, 'cruise_speed': 0.15})
    # an agent dropped as missing (10 s by default) leaves NaN rows in one run only: on a loaded
    # machine each run gets longer, so that the two runs compare their dynamics, not the load
    robots = ('--robots', 'mujoco:agent_2-agent_4', '--missing-timeout', '60')
    run = processes.start([IP, 'netns', 'exec', ns_a, swarm_cmd, 'run', path, '--interface', addr_a,
                           '--server-port', '11811', '--remote-agents', '3-5', *robots, '--out', tmp_path / 'two',
                           '--no-figure'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    run_lines = Lines(run)
    assert run_lines.wait_for(f'discovery server on {addr_a}:11811', 120), ''.join(run_lines.lines)
    join = processes.start([IP, 'netns', 'exec', ns_b, swarm_cmd, 'join', path, '--agents', '3-5',
                            '--server', f'{addr_a}:11811', '--interface', addr_b],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    join_lines = Lines(join)
    assert run_lines.wait(run, 300) == 0, ''.join(run_lines.lines[-40:])
    assert join_lines.wait(join, 60) == 0, ''.join(join_lines.lines)
    assert any('swarm join: 2 of 6 agents on robots (mujoco)' in ln for ln in join_lines.lines), \
        ''.join(join_lines.lines)
    one = processes.start([IP, 'netns', 'exec', ns_a, swarm_cmd, 'run', path, '--interface', addr_a, *robots,
                           '--out', tmp_path / 'one', '--no-figure'],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    one_lines = Lines(one)
    assert one_lines.wait(one, 300) == 0, ''.join(one_lines.lines[-40:])
    two, ref = (Trajectory.load(tmp_path / d / 'trajectory.npz') for d in ('two', 'one'))
    np.testing.assert_array_equal(two.r, ref.r)
    np.testing.assert_array_equal(two.u, ref.u)
    speed = np.linalg.norm(np.diff(two.r, axis=0), axis=2) / (two.t[1] - two.t[0])
    assert speed[0, 2:5].max() < 0.5 and np.abs(speed[:, [0, 1, 5]] - 1.0).max() < 1e-5    # robots, points


def run_over(hosts, tmp_path, swarm_cmd, processes):
    (ns_a, addr_a), (ns_b, addr_b) = hosts['A'], hosts['B']
    path = short_homotopy(tmp_path / 'short.yaml', duration=10, lam='{kind: constant, value: 0.0}', at=3)
    out, bag = tmp_path / 'run', tmp_path / 'run.mcap'
    port = '11811'
    run = processes.start([IP, 'netns', 'exec', ns_a, swarm_cmd, 'run', path, '--interface', addr_a,
                           '--server-port', port, '--remote-agents', '3-5', '--record', bag, '--out', out,
                           '--no-figure'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    run_lines = Lines(run)
    assert run_lines.wait_for(f'discovery server on {addr_a}:{port}', 120), ''.join(run_lines.lines)
    join = processes.start([IP, 'netns', 'exec', ns_b, swarm_cmd, 'join', path, '--agents', '3-5',
                            '--server', f'{addr_a}:{port}', '--interface', addr_b, '--recorded'],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    join_lines = Lines(join)
    assert run_lines.wait(run, 300) == 0, ''.join(run_lines.lines[-40:])
    assert join_lines.wait(join, 60) == 0, ''.join(join_lines.lines)
    assert any('the world has left the graph' in ln for ln in join_lines.lines), ''.join(join_lines.lines)
    # B's agents ran on B: A's launcher started only agents 0-2
    assert any('6 agents, lockstep, 6 processes' in ln for ln in run_lines.lines), ''.join(run_lines.lines[:3])

    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(load(str(path)))
    np.testing.assert_array_equal(got.r, ref.r)
    np.testing.assert_array_equal(got.u, ref.u)
    assert np.abs(got.theta - ref.theta).max() <= 1e-9
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)

    # the bag recorded on A holds every agent's state of every step, B's agents too
    from mcap_ros2.reader import read_ros2_messages
    states = defaultdict(dict)
    for m in read_ros2_messages(str(bag), topics=['/swarm/states']):
        s = m.ros_msg
        states[s.child_frame_id][s.header.stamp.sec * 10**9 + s.header.stamp.nanosec] = s.pose.pose.position
    assert sorted(states) == sorted(got.names)
    grid = [int(round(t * 1e9)) for t in got.t]
    for k, name in enumerate(got.names):
        pos = np.array([[states[name][t].x, states[name][t].y] for t in grid])
        np.testing.assert_array_equal(pos, got.r[:, k])

    # nothing left running in either namespace (the fixture then removes them)
    assert _netns_pids(ns_a) == [] and _netns_pids(ns_b) == []



def test_a_3d_run_over_two_hosts(tmp_path, ros_domain, processes, swarm_cmd):
    """homotopy_3d, shortened, with agents 3-5 joined from B: lockstep equals `swarm simulate`
    bit for bit (r, x, y, z, u, v, λ, leaders)."""
    _on_two_hosts(run_3d_over, tmp_path, swarm_cmd, processes)


def run_3d_over(hosts, tmp_path, swarm_cmd, processes):
    from tests.agent.test_natural_core import short_3d
    (ns_a, addr_a), (ns_b, addr_b) = hosts['A'], hosts['B']
    path = short_3d(tmp_path / 'h3.yaml', duration=8.0)
    out = tmp_path / 'run'
    run = processes.start([IP, 'netns', 'exec', ns_a, swarm_cmd, 'run', path, '--interface', addr_a,
                           '--server-port', '11811', '--remote-agents', '3-5', '--out', out, '--no-figure'],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    run_lines = Lines(run)
    assert run_lines.wait_for(f'discovery server on {addr_a}:11811', 120), ''.join(run_lines.lines)
    join = processes.start([IP, 'netns', 'exec', ns_b, swarm_cmd, 'join', path, '--agents', '3-5',
                            '--server', f'{addr_a}:11811', '--interface', addr_b],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    join_lines = Lines(join)
    assert run_lines.wait(run, 300) == 0, ''.join(run_lines.lines[-40:])
    assert join_lines.wait(join, 60) == 0, ''.join(join_lines.lines)
    got, ref = Trajectory.load(out / 'trajectory.npz'), simulate(load(str(path)))
    assert got.r.shape == (81, 6, 3) and ref.leader.any() and np.abs(ref.v).max() > 0
    for key in ('r', 'x', 'y', 'z', 'u', 'v', 'lam', 'leader'):
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)
    assert _netns_pids(ns_a) == [] and _netns_pids(ns_b) == []
