"""The `swarm` CLI as a new user meets it (no ROS): bad output paths and flags get one line and
exit 2 before any work is done, help shows defaults, and Ctrl-C keeps what was computed."""
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from tests.helpers import Lines


def _swarm(*args, timeout=120):
    return subprocess.run([sys.executable, '-m', 'swarm_tools.cli', *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


def _one_clean_line(r, *words):
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert 'Traceback' not in r.stderr, r.stderr
    assert all(w in r.stderr for w in words), r.stderr


def test_simulate_unwritable_out_is_one_line_before_the_run(tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    r = _swarm('simulate', 'homotopy_global', '--out', blocker / 'sub', '--quiet')
    _one_clean_line(r, 'cannot create output directory', str(blocker / 'sub'))
    assert 'step' not in r.stderr          # refused before any step was computed


def test_sweep_bad_out_and_jobs_are_refused_before_the_work(tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    r = _swarm('sweep', 'global_alignment', '--seeds', '1', '--jobs', '1', '--out', blocker / 'x' / 'sweep.md')
    _one_clean_line(r, 'cannot create output directory')
    assert 'seed 0' not in r.stderr
    r = _swarm('sweep', 'global_alignment', '--seeds', '1', '--jobs', '0')
    _one_clean_line(r, '--jobs must be ≥ 1')
    # a missing directory for --out is created, as `swarm simulate --out` does
    out = tmp_path / 'new' / 'dir' / 'sweep.md'
    r = _swarm('sweep', 'global_alignment', '--seeds', '1', '--jobs', '1', '--out', out)
    assert r.returncode == 0, r.stderr
    assert '| **all checks** | **1/1** |' in out.read_text()


def test_scenario_without_kind_names_the_missing_field(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: x\nagents: {count: 3}\nlaw: {kind: global}\nlambda: {constant: 0.5}\n')
    r = _swarm('simulate', bad)
    _one_clean_line(r, 'lambda', 'kind', 'constant, tanh_window, ramps')
    assert len(r.stderr.strip().splitlines()) == 1
    bad.write_text('name: x\nagents: {count: 3}\nlaw: {kind: global}\n'
                   'leaders: {fixed: {agent_0: {curvature: 0.01}}}\n')
    r = _swarm('simulate', bad)
    _one_clean_line(r, 'leaders.fixed.agent_0', 'kind', 'constant, sinusoid, waypoint')


@pytest.mark.parametrize('verb, flag', [('sweep', '--jobs'), ('sweep', '--first-seed'), ('sweep', '--integrator')])
def test_help_shows_defaults(verb, flag):
    r = _swarm(verb, '--help')
    assert r.returncode == 0
    text = ' '.join(r.stdout.split())
    after = text.split(flag, 2)[-1]
    assert 'default' in after.split(' --')[0], after[:200]


@pytest.mark.parametrize('jobs', [1, 2])
def test_sweep_ctrl_c_keeps_the_finished_seeds(tmp_path, jobs):
    """SIGINT to the sweep (what Ctrl-C does) once a seed has finished: exit 130 promptly, the
    finished seeds in the printed table and in --out (Markdown + JSON), no worker left."""
    out = tmp_path / 'sweep.md'
    p = subprocess.Popen([sys.executable, '-m', 'swarm_tools.cli', 'sweep', 'global_alignment', '--seeds', '200',
                          '--jobs', str(jobs), '--out', str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        lines = Lines(p)
        assert lines.wait_for('(1/200)', 120), ''.join(lines.lines)
        os.kill(p.pid, signal.SIGINT)
        t0 = time.monotonic()
        rc = lines.wait(p, 60)
        took = time.monotonic() - t0
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    text = ''.join(lines.lines)
    assert rc == 130, text
    assert 'Traceback' not in text and 'INTERRUPTED after' in text, text
    res = json.loads(out.with_suffix('.json').read_text())['global_alignment']
    seeds = [r['seed'] for r in res]
    assert 1 <= len(seeds) < 200 and seeds == list(range(len(seeds)))
    assert f'({len(seeds)} seeds: 0..{len(seeds) - 1})' in out.read_text()
    assert all(r['ok'] is not None for r in res)        # no partial (interrupted) seed counted
    # the pool's workers are gone with it (they were in the sweep's session): wait for that,
    # not a fixed time (a worker may take a moment to exit after the pool's SIGTERM)
    def session_left():
        ps = subprocess.run(['ps', '-eo', 'sid='], capture_output=True, text=True).stdout.split()
        return str(p.pid) in ps
    t_end = time.monotonic() + 30
    while session_left() and time.monotonic() < t_end:
        time.sleep(0.1)
    assert not session_left(), f'processes of the sweep left behind (exit after {took:.1f} s)'


@pytest.mark.parametrize('verb, flag', [('lambda', '--wait'), ('steer', '--wait'), ('kill', '--wait'),
                                        ('pause', '--wait'), ('drop', '--wait'), ('partition', '--wait'),
                                        ('run', '--mode'), ('run', '--progress-every'), ('play', '--delay'),
                                        ('play', '--wait-for-subscribers')])
def test_ros_verbs_help_shows_defaults(verb, flag):
    test_help_shows_defaults(verb, flag)


def test_run_and_record_refuse_unwritable_outputs_before_starting(tmp_path):
    """One line and exit 2 before any process starts (they were tracebacks; a bad --record
    path failed the run only once the recorder had started)."""
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    r = _swarm('run', 'global_alignment', '--duration', '1', '--out', blocker / 'run')
    _one_clean_line(r, 'cannot create output directory')
    for bag, words in [(blocker / 'x.mcap', ('--record', 'cannot create its directory')),
                       (tmp_path / 'x.bag', ('--record', 'must name a .mcap file'))]:
        r = _swarm('run', 'global_alignment', '--duration', '1', '--out', tmp_path / 'run', '--record', bag)
        _one_clean_line(r, *words)
        assert 'processes' not in r.stdout          # nothing was started
    r = _swarm('record', '--out', blocker / 'x.mcap', '--duration', '1')
    _one_clean_line(r, 'swarm record: cannot write')


@pytest.mark.parametrize('args', [('lambda', '0.5'), ('steer', 'agent_0', '0.01'), ('kill', 'agent_0'),
                                  ('pause', 'agent_0', '3'), ('drop', '0.5'), ('partition', 'agent_0')])
def test_live_verbs_refuse_a_negative_or_nonnumeric_wait(args):
    """`--wait -1` was accepted (and waited no time at all); every live verb shares one type."""
    for bad in ('-1', 'nan', 'soon'):
        r = _swarm(*args, '--wait', bad, timeout=60)
        assert r.returncode == 2 and '--wait' in r.stderr and 'Traceback' not in r.stderr, (args, bad, r.stderr)


def test_rk4_reference_run_does_not_overwrite_the_zoh_run(tmp_path):
    for extra in ((), ('--integrator', 'rk4')):
        r = subprocess.run([sys.executable, '-m', 'swarm_tools.cli', 'simulate', 'global_alignment', '--duration', '2',
                            '--quiet', '--no-figure', *extra],
                           capture_output=True, text=True, timeout=120, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
    zoh = np.load(tmp_path / 'runs' / 'global_alignment-seed0' / 'trajectory.npz')['r']
    rk4 = np.load(tmp_path / 'runs' / 'global_alignment-seed0-rk4' / 'trajectory.npz')['r']
    assert zoh.shape == rk4.shape and not np.array_equal(zoh, rk4)


def test_a_3d_scenario_is_simulated_but_refused_by_the_ros_commands_on_robots(tmp_path):
    r = _swarm('run', '--robots', 'external', 'homotopy_3d')
    _one_clean_line(r, 'a 3D scenario (dim: 3)', 'robots are planar for now')
    assert len(r.stderr.strip().splitlines()) == 1
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: bad\ndim: 3\nagents: {positions: [[0, 0], [1, 0]]}\n')
    r = _swarm('simulate', bad, '--quiet', '--out', tmp_path / 'out')
    _one_clean_line(r, 'agents.positions: a position of a 3D scenario (dim: 3) has 3 coordinates')
    r = _swarm('simulate', 'homotopy_3d', '--duration', '20', '--quiet', '--out', tmp_path / 'out3')
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / 'out3' / 'trajectory.npz') as z:
        assert z['r'].shape == (201, 6, 3) and z['v'].shape == (201, 6)
    assert (tmp_path / 'out3' / 'homotopy_3d.png').exists()
