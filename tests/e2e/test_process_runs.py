"""End-to-end: `swarm run` with every agent, the world and the commander as OS processes."""
import os
import re
import signal
import subprocess
import time

import numpy as np

from swarm_core.analysis.metrics import cluster_labels
from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from tests.helpers import Lines, short_homotopy, steps_done_reference

# homotopy_global's law, agents and start at dt = 0.1, with the λ window brought forward (rise at
# t = 30, fall at 90, leaders chosen at 10) so that the split and the reform fit in t = 180
# (1800 steps) instead of t = 1000 (10000 steps): measured with the batch engine, seeds 0-5 are
# one swarm until t ≈ 50-65, two at t = 70-110, one again by t = 160.


def children_of(pid):
    out = subprocess.run(['ps', '-eo', 'pid,ppid'], capture_output=True, text=True).stdout.split('\n')[1:]
    return [int(a) for a, b in (ln.split() for ln in out if ln.strip()) if int(b) == pid]


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f'/proc/{pid}/stat') as f:
        return f.read().split(')')[1].split()[0] != 'Z'


def test_processes_lockstep_split_reform_equals_simulate(tmp_path, ros_domain, processes, swarm_cmd):
    path = short_homotopy(tmp_path / 'homotopy_short.yaml', duration=180, dt=0.1,
                          lam='{kind: tanh_window, rise_at: 30, fall_at: 90, tau: 15}', at=10)
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--progress-every', '50'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert p.wait(timeout=400) == 0, ''.join(lines.lines[-30:])
    got = Trajectory.load(out / 'trajectory.npz')
    scn = load(str(path))
    ref = simulate(scn)
    np.testing.assert_array_equal(got.r, ref.r)                # exact: the same law, the same order
    np.testing.assert_array_equal(got.u, ref.u)
    assert np.abs(got.theta - ref.theta).max() <= 1e-9         # θ comes back through the quaternion
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)
    # the behaviour, from what was published
    def clusters(t):
        return cluster_labels(got.r[int(round(t / scn.dt))], 4.0)

    assert clusters(40)[0] == 1
    c, labels = clusters(85)
    assert c == 2
    leaders = np.flatnonzero(got.leader[int(round(85 / scn.dt))])
    assert len(leaders) == 2 and labels[leaders[0]] != labels[leaders[1]]
    assert clusters(180)[0] == 1
    assert any('[world] finished' in ln for ln in lines.lines)


def test_sigint_stops_every_process(tmp_path, ros_domain, processes, swarm_cmd):
    p = processes.start([swarm_cmd, 'run', 'homotopy_global', '--out', tmp_path / 'run', '--no-figure',
                         '--progress-every', '5'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    # t = 5 (50 steps done): at the first line (t = 0) no step may be complete yet, and then there
    # is nothing to keep
    assert lines.wait_for('[world] t=    5.00', 120), ''.join(lines.lines)
    kids = children_of(p.pid)
    assert len(kids) == 8                                # world, commander, 6 agents
    os.kill(p.pid, signal.SIGINT)                        # what Ctrl-C does to the launcher
    assert p.wait(timeout=15) == 130
    end = time.monotonic() + 5
    while time.monotonic() < end and any(alive(k) for k in kids):
        time.sleep(0.1)
    assert not [k for k in kids if alive(k)]
    # nothing lost: the steps done are saved (as `swarm simulate` saves an interrupted run) and
    # equal the batch engine's; no node prints a traceback on the way out
    lines.t.join(timeout=10)
    text = ''.join(lines.lines)
    assert 'Traceback' not in text and 'Exception in' not in text, text[-3000:]
    got = Trajectory.load(tmp_path / 'run' / 'trajectory.npz')
    n = len(got.t)
    assert n >= 2 and np.all(np.isfinite(got.r)) and np.all(np.isfinite(got.u)), text[-2000:]
    ref = steps_done_reference('homotopy_global', n)
    np.testing.assert_array_equal(got.r, ref.r[:n])
    np.testing.assert_array_equal(got.u, ref.u[:n])
    assert np.array_equal(got.lam, ref.lam[:n])


def test_sigint_in_process_keeps_the_steps_done(tmp_path, ros_domain, processes, swarm_cmd):
    """`swarm run --in-process`: Ctrl-C ends the run at once (a busy executor used to go on to
    the end, or cut a callback off with a traceback) and the steps done are saved."""
    p = processes.start([swarm_cmd, 'run', 'homotopy_global', '--in-process', '--out', tmp_path / 'run',
                         '--no-figure', '--progress-every', '5'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait_for('[world] t=    5.00', 120), ''.join(lines.lines)
    os.kill(p.pid, signal.SIGINT)
    assert p.wait(timeout=30) == 130, ''.join(lines.lines[-20:])
    lines.t.join(timeout=10)
    text = ''.join(lines.lines)
    assert 'Traceback' not in text and '[world] finished' not in text, text[-3000:]
    got = Trajectory.load(tmp_path / 'run' / 'trajectory.npz')
    n = len(got.t)
    dt = load('homotopy_global').dt
    assert 5 / dt <= n < 1000 / dt + 1 and np.all(np.isfinite(got.r))
    np.testing.assert_array_equal(got.r, steps_done_reference('homotopy_global', n).r[:n])


def test_sigterm_stops_every_process(tmp_path, ros_domain, processes, swarm_cmd):
    p = processes.start([swarm_cmd, 'run', 'homotopy_global', '--out', tmp_path / 'run', '--no-figure',
                         '--progress-every', '5'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait_for('[world] t=', 120), ''.join(lines.lines)
    kids = children_of(p.pid)
    os.kill(p.pid, signal.SIGTERM)
    assert p.wait(timeout=15) == 130
    end = time.monotonic() + 5
    while time.monotonic() < end and any(alive(k) for k in kids):
        time.sleep(0.1)
    assert not [k for k in kids if alive(k)]


def test_realtime_lambda_from_the_cli_splits_the_swarm(tmp_path, ros_domain, processes, swarm_cmd):
    """λ = 0 throughout in the scenario; leaders chosen at t = 5; `swarm lambda 1.0` mid-run
    must change the published λ and split the swarm.  The run is stopped (Ctrl-C: the steps
    done are saved) once the world reports two clusters at λ = 1."""
    path = tmp_path / 'homotopy_rt.yaml'
    short_homotopy(path, duration=260, lam='{kind: constant, value: 0.0}', at=5)
    out = tmp_path / 'run'
    # rtf 4: at rtf 5, a clean clone's loaded suite starved the agents once, and the swarm was two
    # clusters at λ = 0 before the command (periods past catch_up_limit are lost in realtime)
    p = processes.start([swarm_cmd, 'run', path, '--mode', 'realtime', '--rtf', '4', '--dt', '0.1',
                         '--out', out, '--no-figure', '--progress-every', '5'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    progress = re.compile(r'\[world\] t= *([\d.]+)  clusters=(\d+)  λ=([\d.]+)')

    def reported(ln, t=0.0, clusters=1, lam=0.0):
        """A progress line at sim time >= t with >= clusters clusters at λ >= lam."""
        m = progress.search(ln)
        return bool(m) and float(m[1]) >= t and int(m[2]) >= clusters and float(m[3]) >= lam

    assert lines.wait_for(lambda ln: reported(ln, t=20), 120), ''.join(lines.lines)
    cli = subprocess.run([swarm_cmd, 'lambda', '1.0', '--ramp', '5'], capture_output=True, text=True, timeout=60)
    assert cli.returncode == 0, cli.stderr
    # the split takes ~30-60 sim s once λ = 1 (a run that ends first, at t = 260, fails here)
    assert lines.wait_for(lambda ln: reported(ln, clusters=2, lam=1.0), 180), ''.join(lines.lines[-30:])
    p.send_signal(signal.SIGINT)
    assert lines.wait(p, 60) == 130, ''.join(lines.lines[-30:])
    got = Trajectory.load(out / 'trajectory.npz')
    t_cli = got.t[np.argmax(got.lam > 0.0)]
    assert got.lam[got.t < 19].max() == 0.0
    assert t_cli >= 19 and got.lam[-1] == 1.0
    # the leaders chosen at t = 5 are in the world's trajectory (they were all False in realtime)
    assert not got.leader[got.t < 4].any() and got.leader[-1].sum() == 2, got.leader.sum(axis=1)[::100]
    assert np.all(np.isfinite(got.r)) and np.all(np.isfinite(got.theta))
    # unit speed in realtime too (agents that moved one dt per timer call flew at 0.55-0.7): the
    # median over 5 sim s windows, as a loaded machine can starve every agent for a few seconds
    # (the periods beyond catch_up_limit are lost), which a run this short does not average out
    w = int(round(5.0 / (got.t[1] - got.t[0])))
    n = (len(got.t) - 1) // w
    steps = np.linalg.norm(np.diff(got.r, axis=0), axis=2)[:n * w].reshape(n, w, -1)
    speed = np.median(steps.sum(axis=1) / (got.t[w] - got.t[0]), axis=0)
    assert n >= 8 and np.all((speed > 0.9) & (speed < 1.01)), speed
    c_before = cluster_labels(got.r[np.searchsorted(got.t, t_cli) - 1], 4.0)[0]
    c_end = cluster_labels(got.r[-1], 4.0)[0]
    assert c_before == 1 and c_end >= 2, (c_before, c_end)


def test_swarm_run_rejects_a_bad_scenario(tmp_path, swarm_cmd):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: x\nagents: {count: 3}\nlaw: {alpha: -1}\n')
    r = subprocess.run([swarm_cmd, 'run', bad, '--out', tmp_path / 'o'], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and 'law.alpha' in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_cli_rejects_bad_lambda_and_steering(swarm_cmd):
    for args, word in ((['lambda', 'nan'], 'λ=nan'), (['lambda', '1.5'], 'λ=1.5'),
                       (['lambda', '--', '-0.5'], 'λ=-0.5'),
                       (['steer', 'agent_0', 'inf'], 'steering=inf'),
                       (['steer', 'agent_0', '1e308'], 'steering=1e+308'),
                       (['pause', 'agent_1', '1e308'], 'pause seconds=1e+308'),
                       (['lambda', '1', '--ramp', '1e308'], 'ramp=1e+308')):
        r = subprocess.run([swarm_cmd, *args], capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and word in r.stderr, (args, r.stderr)


def test_agent_process_rejects_a_bad_parameter(ros_domain, processes):
    import sys
    exe = os.path.join(os.path.dirname(sys.executable), 'swarm_agent')
    p = processes.start([exe, '--ros-args', '-p', 'cutoff_radius:=-1.0', '-r', '__ns:=/agent_0'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out, _ = p.communicate(timeout=60)
    assert p.returncode == 2
    errs = [ln for ln in out.splitlines() if 'parameter cutoff_radius' in ln]
    assert len(errs) == 1 and 'Traceback' not in out


def test_realtime_leader_rule_reads_the_agents_states(tmp_path, ros_domain, processes, swarm_cmd):
    """The realtime commander chooses the leaders from the states the agents send, not from
    the start: seed 6's swarm reshapes before the rule fires at t = 10, and its lateral
    extremes are then agents 4 and 1, not 5 and 0 as at t = 0 (the batch engine, which lockstep
    equals bit for bit; their lateral offsets lead the next agent's by ≥ 0.8 over t = 8-10, so a
    state one period old picks the same).  A commander that dropped every lone agent's state
    chose 5 and 0."""
    path = short_homotopy(tmp_path / 'turns.yaml', duration=14, dt=0.1, lam='{kind: constant, value: 0.0}', at=10,
                          seed=6)
    ref = simulate(load(str(path)))
    want = set(np.flatnonzero(ref.leader[-1]))
    assert want == {1, 4} and not ref.leader[0].any()
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--mode', 'realtime', '--rtf', '4', '--out', out, '--no-figure'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 120) == 0, ''.join(lines.lines[-30:])
    got = Trajectory.load(out / 'trajectory.npz')
    assert set(np.flatnonzero(got.leader[-1])) == want, ''.join(lines.lines[-30:])
