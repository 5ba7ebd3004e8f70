"""The Python API (swarm_tools.api.Swarm) against real runs, the example test under the
installed pytest plugin, and the notebook.

Every live check reads the effect from the run's own record (trajectory.npz, events.jsonl
through metrics.json), not only from what the API says."""
from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

from tests.helpers import ROOT, Lines

SCENARIO = ROOT / 'examples' / 'six_agents_live.yaml'


# ---------------------------------------------------------------- each command against a real run
def _still(rows):
    """The agent did not move over these rows (recorded as held, or not recorded: NaN)."""
    known = rows[np.isfinite(rows).all(axis=1)]
    return bool((known == known[-1]).all()) if len(known) else True


def _events(run):
    return run.metrics_json()['summary']['events']


@pytest.mark.parametrize('mode', ['lockstep', 'realtime'])
def test_each_command_takes_effect_in_the_runs_record(swarm, mode):
    """λ, steering, pause, kill and a partition through the API; each returns once taken, and
    the run's trajectory and events show it."""
    from swarm_tools.api import SwarmError, UnknownAgent
    run = swarm(SCENARIO, mode=mode, rtf=4, duration=4000, agents_per_process=6, no_figure=True)
    assert run.agents == [f'agent_{i}' for i in range(6)]
    # sim s to wait: a lockstep run goes 40-400 sim s per wall s, and a reliable message lost on a
    # loaded machine holds the ones after it until Fast DDS's next heartbeat (3 wall s)
    span = 400 if mode == 'lockstep' else 60
    first = run.wait_until(lambda m: m['t'] >= 2, timeout=span)
    assert first['lambda'] == 0.0 and first['clusters'] == 1
    # every agent's state heard (the API's reader discovers the agents' writers one by one)
    assert run.wait_until(lambda st: st is not None and st.names == run.agents, timeout=span, on='states')
    run.set_lambda(1.0, ramp=1)
    run.steer('agent_0', 0.05)
    run.pause('agent_1', 2.0)
    run.kill('agent_5')
    t_part = run.partition(['agent_0', 'agent_1'], ['agent_2', 'agent_3', 'agent_4'])
    with pytest.raises(UnknownAgent, match="unknown agent 'agent_9'"):
        run.kill('agent_9')
    assert run.wait_until(lambda m: m['lambda'] == 1.0, timeout=span)['lambda'] == 1.0
    with pytest.raises(SwarmError, match='the run is still going'):
        run.trajectory()
    assert run.stop() == 130                       # as Ctrl-C: the outputs are written
    assert not run.leftover()
    traj, events = run.trajectory(), _events(run)
    kinds = [(e['kind'], e.get('agent'), e.get('command')) for e in events]
    # λ reached 1 (the commander's ramp), and it was 0 before the command
    assert traj.lam[0] == 0.0 and traj.lam[-1] == 1.0, run.log
    cmd = [e for e in events if e['kind'] == 'command']
    assert [(e['command'], e.get('agent')) for e in cmd] == [('lambda', None), ('steer', 'agent_0')], cmd
    # agent_0 steered: a leader from the step of the command on
    k_steer = int(np.searchsorted(traj.t, cmd[1]['t']))
    assert traj.leader[k_steer + 1:, 0].all()
    # agent_1 frozen for 2 sim s and back; agent_5 killed and gone from the table
    assert ('freeze', 'agent_1', None) in kinds and ('resume', 'agent_1', None) in kinds, kinds
    assert ('kill', 'agent_5', None) in kinds
    def step_of(kind, agent):
        return int(np.searchsorted(traj.t, next(e['t'] for e in events if e['kind'] == kind and e['agent'] == agent)))
    k_kill, k_freeze, k_resume = step_of('kill', 'agent_5'), step_of('freeze', 'agent_1'), step_of('resume', 'agent_1')
    # realtime: an agent's last states before the fault may come a few steps after the
    # event's stamp (signals, timers; at rtf 4 on a loaded machine, over 1 sim s once): judge
    # the last quarter of the 2 s freeze
    steps = round(2.0 / (traj.t[1] - traj.t[0]))
    assert k_resume - k_freeze >= steps - 1                                   # 2 sim s frozen
    assert _still(traj.r[k_kill + steps // 2:, 5]) and not _still(traj.r[k_kill + steps // 2:, 4])
    assert _still(traj.r[k_resume - steps // 4:k_resume, 1]) and not _still(traj.r[k_resume:, 1])
    # the partition went out stamped with the run's sim time, and the world wrote it down
    part = [e for e in events if e['kind'] == 'partition']
    assert part and part[0]['groups'] == [['agent_0', 'agent_1'], ['agent_2', 'agent_3', 'agent_4']]
    assert part[0]['t'] == pytest.approx(t_part)


def test_wait_until_that_times_out_says_so_and_leaves_no_process(ros_domain, tmp_path):
    from swarm_tools.api import Swarm, WaitTimeout
    with pytest.raises(WaitTimeout, match=r'never_five_clusters not true after 3 sim s') as err:
        with Swarm.start(SCENARIO, duration=400, out=tmp_path / 'run', agents_per_process=6, no_figure=True) as run:
            def never_five_clusters(m):
                return m['clusters'] >= 5
            t0 = run.t
            run.wait_until(never_five_clusters, timeout=3)
    assert 'newest metrics' in str(err.value)
    assert run.t - t0 >= 3 and run.proc.returncode == 130 and not run.leftover()
    assert (tmp_path / 'run' / 'trajectory.npz').is_file()          # kept, as after Ctrl-C


def test_start_that_fails_says_why_and_leaves_nothing(ros_domain, tmp_path):
    from swarm_tools.api import Swarm, SwarmError
    with pytest.raises(SwarmError, match=r'exit code 2\) before the run started:\n.*--rtf 0') as err:
        Swarm.start(SCENARIO, rtf=0, out=tmp_path / 'run')
    assert 'Traceback' not in str(err.value)
    assert (tmp_path / 'run' / 'swarm_run.log').read_text().startswith('swarm run: --rtf 0')


def test_a_script_that_dies_leaves_no_run_behind(ros_domain, tmp_path):
    """A script SIGKILLed with its run going (no `with`, no atexit): the launcher gets SIGINT,
    stops as on Ctrl-C (the outputs written) and nothing of the run is left."""
    from swarm_tools.api import session_pids
    script = (f'import os\nfrom swarm_tools.api import Swarm\n'
              f's = Swarm.start({str(SCENARIO)!r}, duration=4000, out={str(tmp_path / "run")!r}, in_process=True, '
              f'no_figure=True)\ns.wait_until(lambda m: m["t"] >= 2, timeout=10)\n'
              f'print(s.proc.pid, flush=True)\nos.kill(os.getpid(), 9)\n')
    r = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=180)
    assert r.returncode == -9 and r.stdout.strip().isdigit(), r.stdout + r.stderr
    pid, end = int(r.stdout), time.monotonic() + 60
    while session_pids(pid) and time.monotonic() < end:
        time.sleep(0.1)
    said = (tmp_path / 'run' / 'swarm_run.log').read_text()
    assert not session_pids(pid), said
    assert json.loads((tmp_path / 'run' / 'run.json').read_text())['exit_code'] == 130, said
    assert (tmp_path / 'run' / 'trajectory.npz').is_file()


def test_attach_to_swarm_run_and_a_second_run_on_another_domain(ros_domain, processes, swarm_cmd, tmp_path):
    """One script drives two runs: one started by `swarm run` (attached) on the test's domain,
    one started by the API on a second domain; each takes its own λ.  Both realtime at rtf 4:
    two lockstep runs would spin both cores while the script waits."""
    from swarm_core.engine.trajectory import Trajectory
    from swarm_tools.api import NoSwarm, Swarm
    from swarm_tools.pytest_plugin import claim_domain
    cli = processes.start([swarm_cmd, 'run', SCENARIO, '--in-process', '--mode', 'realtime', '--rtf', '4',
                           '--duration', '4000', '--out',
                           tmp_path / 'cli', '--no-figure'],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(cli)
    assert lines.wait_for('swarm run: run ', 60), ''.join(lines.lines)
    run_id = next(ln for ln in lines.lines if ln.startswith('swarm run: run ')).split()[3].rstrip(':')
    other, lock = claim_domain()
    try:
        with pytest.raises(NoSwarm, match='no run'):
            Swarm.attach(domain=other, wait=1.0)
        with Swarm.attach(out=tmp_path / 'cli', wait=60) as a, \
                Swarm.start(SCENARIO, domain=other, mode='realtime', rtf=4, duration=4000, out=tmp_path / 'api',
                            in_process=True, no_figure=True) as b:
            assert a.run_id == run_id and b.run_id != run_id
            a.set_lambda(1.0, ramp=0)
            b.set_lambda(0.5, ramp=0)
            assert a.wait_until(lambda m: m['lambda'] == 1.0, timeout=20)['lambda'] == 1.0
            assert b.wait_until(lambda m: m['lambda'] == 0.5, timeout=20)['lambda'] == 0.5
            assert a.stop() is None and a.running                   # an attached run is not ours to stop
        assert b.proc.returncode == 130 and not b.leftover()
    finally:
        lock.close()
    processes.stop_all()
    assert cli.returncode == 130
    lam_a = Trajectory.load(tmp_path / 'cli' / 'trajectory.npz').lam
    lam_b = Trajectory.load(tmp_path / 'api' / 'trajectory.npz').lam
    assert set(np.unique(lam_a)) == {0.0, 1.0} and set(np.unique(lam_b)) == {0.0, 0.5}


# ---------------------------------------------------------------- the plugin, the example test, the notebook
def test_example_test_passes_and_a_broken_variant_fails(tmp_path):
    """The user's example test passes under the installed plugin (no conftest of ours), and a
    variant expecting three clusters fails on its assertion, its processes gone all the same."""
    example = ROOT / 'examples' / 'test_lambda_change.py'
    broken = tmp_path / 'test_broken_variant.py'
    text = example.read_text()
    assert 'EXPECTED_CLUSTERS = 2' in text
    broken.write_text(text.replace('EXPECTED_CLUSTERS = 2', 'EXPECTED_CLUSTERS = 3').replace(
        "Path(__file__).with_name('six_agents_live.yaml')", repr(str(SCENARIO))))
    r = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '--rootdir', str(tmp_path),
                        '-c', str(ROOT / 'pytest.ini'), str(example), str(broken)],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 1 and '1 failed, 1 passed' in out, out[-4000:]
    assert 'FAILED ' in out and 'test_broken_variant.py::test_raising_lambda_splits_the_swarm' in out, out[-4000:]
    assert 'assert 2 == 3' in out and ' error' not in out, out[-4000:]
    # the fixture stopped both runs: no process of theirs is left
    ps = subprocess.run(['ps', '-eo', 'args='], capture_output=True, text=True).stdout
    assert str(tmp_path) not in ps


def test_the_notebook_runs_headless(ros_domain):
    nbformat = pytest.importorskip('nbformat')
    from nbclient import NotebookClient
    nb = nbformat.read(ROOT / 'examples' / 'swarm_live.ipynb', as_version=4)
    NotebookClient(nb, timeout=300, kernel_name='python3',
                   resources={'metadata': {'path': str(ROOT / 'examples')}}).execute()
    text = '\n'.join(o.get('text', '') for c in nb.cells if c.cell_type == 'code' for o in c.get('outputs', []))
    assert 'final clusters 2' in text, text[-2000:]
    assert any('image/png' in o.get('data', {}) for c in nb.cells if c.cell_type == 'code'
               for o in c.get('outputs', []))
