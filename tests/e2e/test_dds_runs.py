"""Runs over the DDS set-ups of `swarm_tools.run.dds`: a small run through a discovery server
that `swarm lambda` and a stock-tool graph listing reach, and a lockstep run over the large-n
profile (UDP loopback, no shared memory) that still equals `swarm simulate`.  The set-ups
themselves, without a run: tests/tools/run/test_dds_setup.py."""
import os
import signal
import subprocess
import sys

import numpy as np

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from swarm_tools.run import dds
from tests.helpers import FAKES, Lines, short_homotopy


def topic_list(env, tries):
    """Topics ``ros2 topic list --no-daemon`` shows (the faithful stand-in,
    tests/fakes/ros2cli_verbs.py: a process of its own, 0.5 s of discovery, one look), run again
    as a user would until it lists /swarm/states (at most ``tries``); the last listing otherwise."""
    out = ''
    for _ in range(tries):
        out = subprocess.run([sys.executable, str(FAKES / 'ros2cli_verbs.py'), 'topic', 'list'], env=env,
                             capture_output=True, text=True, timeout=60).stdout
        if '/swarm/states' in out:
            break
    return out


def test_run_through_a_discovery_server(tmp_path, ros_domain, processes, swarm_cmd):
    """A run with --discovery server: the launcher prints the line a shell needs; with it `swarm
    lambda` reaches the commander (λ changes in the published trajectory) and a stock topic
    listing as a super client sees the run; a listing through another discovery server, or with
    simple discovery on the same domain, does not (a run with its own server is apart).  Realtime
    at rtf 4: a lockstep run would spin both cores while the tools look (lockstep over a server,
    bit for bit: tests/e2e/test_multi_host.py)."""
    # dt 0.1: a realtime run's CPU grows with its rate
    path = short_homotopy(tmp_path / 'short.yaml', duration=4000, lam='{kind: constant, value: 0.0}', at=5, dt=0.1)
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--discovery', 'server', '--mode', 'realtime', '--rtf', '4',
                         '--out', out, '--no-figure', '--progress-every', '1'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait_for('[world] t=', 180), ''.join(lines.lines)
    line = next(ln for ln in lines.lines if 'export ROS_DISCOVERY_SERVER=' in ln)
    shell = dict(os.environ)                  # the test's shell: its domain, LOCALHOST range
    for kv in line.split('export ', 1)[1].split():
        k, v = kv.split('=', 1)
        shell[k] = v
    assert shell['ROS_SUPER_CLIENT'] == 'TRUE' and shell['ROS_DISCOVERY_SERVER'].startswith('127.0.0.1:')
    listed = topic_list(shell, 10)
    assert '/swarm/states' in listed and '/swarm/decision' in listed, listed
    # apart: another discovery server's super client, and simple discovery, see none of it
    other = dds.DiscoveryServer('127.0.0.1')
    other.start(lambda label, args, env, **kw: processes.start(args, env=env, **kw), dict(os.environ), tmp_path)
    assert '/swarm/states' not in topic_list(dict(shell, ROS_DISCOVERY_SERVER=other.locator), 2)
    plain = {k: v for k, v in shell.items() if k not in ('ROS_DISCOVERY_SERVER', 'ROS_SUPER_CLIENT')}
    assert '/swarm/states' not in topic_list(plain, 2)
    # swarm lambda, from that shell
    cli = subprocess.run([swarm_cmd, 'lambda', '1.0'], env=shell, capture_output=True, text=True, timeout=90)
    assert cli.returncode == 0, cli.stdout + cli.stderr
    assert lines.wait_for('λ=1.000', 180), ''.join(lines.lines[-20:])
    p.send_signal(signal.SIGINT)
    assert lines.wait(p, 60) == 130
    # realtime: each row's λ is the one in force when a state of that step came, so a late state
    # can give a row a newer λ than the row after it; the ramp's ends are what `swarm lambda` did
    lam = Trajectory.load(out / 'trajectory.npz').lam
    lam = lam[np.isfinite(lam)]
    assert lam[0] == 0.0 and lam[-1] == 1.0 and np.all((lam >= 0) & (lam <= 1))


def test_lockstep_over_the_udp_profile_equals_simulate(tmp_path, ros_domain, processes, swarm_cmd):
    """Also with /clock only every 7 steps: lockstep inputs carry their own step and time."""
    path = short_homotopy(tmp_path / 'dds_short.yaml', name='dds_short', seed=3, duration=15, at=2,
                          lam={'kind': 'tanh_window', 'rise_at': 5, 'fall_at': 12, 'tau': 1})
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--dds', 'udp', '--clock-every', '7', '--out', out, '--no-figure'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    text = processes.communicate(p, 240)
    assert p.returncode == 0, text[-3000:]
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(load(str(path)))
    assert ref.leader.any() and ref.lam.max() > 0.5          # leaders and λ were exercised
    np.testing.assert_array_equal(got.r, ref.r)                # exact: the same law, the same order
    np.testing.assert_array_equal(got.u, ref.u)
    assert np.abs(got.theta - ref.theta).max() <= 1e-9         # θ comes back through the quaternion
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)
    assert 'stalled' not in text and 'XMLPARSER' not in text      # the profile parsed
