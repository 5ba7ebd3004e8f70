"""Parameter studies (swarm_core.study.runner, `swarm sweep --set`): the same table for every
executor, resuming an interrupted study, and one clear error for a bad --set (no ROS)."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import pytest

from swarm_core import study as st
from swarm_tools import simulate as simulate_cli

VENV_BIN = Path(sys.executable).parent

#: a 2 × 2 grid × 3 seeds of Fig. 3, cut short (its checks come out not judged; the table
#: still holds every metric to the last bit)
SETS = ['law.leader_gain=10,30', 'lambda.tau=5,30']
SHORT = {'duration': 40.0}


def _study():
    return st.make_study('homotopy_global', SETS, seeds=3, fixed=SHORT)


def _dask_cluster(processes, tmp_path) -> str:
    """A Dask scheduler and two single-threaded workers on 127.0.0.1 (ended by the `processes`
    fixture, also on failure); the scheduler's address once both workers are in."""
    sched_file = tmp_path / 'scheduler.json'
    processes.start([VENV_BIN / 'dask', 'scheduler', '--host', '127.0.0.1', '--port', '0',
                     '--no-dashboard', '--scheduler-file', sched_file])
    end = time.monotonic() + 120
    while not sched_file.exists() and time.monotonic() < end:
        time.sleep(0.2)
    assert sched_file.exists(), 'the scheduler did not start'
    addr = json.loads(sched_file.read_text())['address']
    assert addr.startswith('tcp://127.0.0.1:')
    for _ in range(2):
        processes.start([VENV_BIN / 'dask', 'worker', addr, '--host', '127.0.0.1', '--nthreads', '1',
                         '--nworkers', '1', '--no-dashboard', '--memory-limit', '0'])
    from distributed import Client
    with Client(addr, timeout=60) as client:
        client.wait_for_workers(2, timeout=180)
    return addr


def test_same_table_for_jobs_1_jobs_2_and_dask(tmp_path, processes):
    """--jobs 1, --jobs 2 and a Dask cluster (a scheduler and two single-threaded workers
    started here on 127.0.0.1, ended by the `processes` fixture also on failure) give the
    same tidy table, byte for byte."""
    s = _study()
    st.validate(s)
    rows1, c1 = st.run_study(s, tmp_path / 'j1')
    rows2, c2 = st.run_study(s, tmp_path / 'j2', jobs=2)
    assert c1 == c2 == {'total': 12, 'cached': 0, 'ran': 12}
    csv1, csv2 = st.to_csv(s, rows1), st.to_csv(s, rows2)
    assert csv1 == csv2
    assert len(csv1.splitlines()) == 13
    assert {r['seed'] for r in rows1} == {0, 1, 2}
    assert len({r['min_distance'] for r in rows1}) > 1      # the runs differ

    addr = _dask_cluster(processes, tmp_path)
    out = tmp_path / 'dask'
    rc = simulate_cli.sweep_main(['homotopy_global', *sum((['--set', x] for x in SETS), []), '--seeds', '3',
                                  '--duration', '40', '--scheduler', addr, '--out', str(out), '--quiet'])
    assert rc == 0
    assert (out / 'runs.csv').read_text() == csv1
    assert (out / 'homotopy_global.png').stat().st_size > 0
    rates = (out / 'rates.csv').read_text().splitlines()
    assert rates[0] == 'law.leader_gain,lambda.tau,check,passed,n,rate,ci_low,ci_high'


def test_a_3d_study_gives_the_same_table_on_dask_and_from_its_cache(tmp_path, processes):
    """homotopy_3d (dim: 3) over a grid: --jobs 1 and the Dask cluster give the same table,
    byte for byte; run again, every row comes from the cache, and the table is the same."""
    sets = ['law.leader_gain=10,30']
    s = st.make_study('homotopy_3d', sets, seeds=2, fixed={'duration': 40.0})
    st.validate(s)
    rows, counts = st.run_study(s, tmp_path / 'j1')
    assert counts == {'total': 4, 'cached': 0, 'ran': 4}
    csv1 = st.to_csv(s, rows)
    assert len({r['min_distance'] for r in rows}) > 1 and all(r['one_cluster_at_end'] for r in rows)
    addr = _dask_cluster(processes, tmp_path)
    out = tmp_path / 'dask'
    argv = ['homotopy_3d', '--set', sets[0], '--seeds', '2', '--duration', '40', '--scheduler', addr,
            '--out', str(out), '--quiet']
    assert simulate_cli.sweep_main(argv) == 0
    assert (out / 'runs.csv').read_text() == csv1
    assert (out / 'homotopy_3d.png').stat().st_size > 0
    (out / 'runs.csv').unlink()
    assert simulate_cli.sweep_main(argv) == 0                   # the 3D rows read back from the cache
    assert (out / 'runs.csv').read_text() == csv1
    assert st.run_study(s, out / 'cache')[1] == {'total': 4, 'cached': 4, 'ran': 0}


class _Stop(KeyboardInterrupt):
    pass


@pytest.mark.parametrize('jobs', [1, 2])
def test_interrupted_study_resumes_without_rerunning(tmp_path, jobs):
    """A Ctrl-C (KeyboardInterrupt in the collecting loop) after 5 runs keeps those runs in the
    cache; the re-run runs only the others, leaves the cached files untouched, and its table
    equals an uninterrupted study's."""
    s = _study()
    cache = tmp_path / 'cache'

    def stop_after_5(counts):
        if counts['ran'] == 5:
            raise _Stop

    with pytest.raises(KeyboardInterrupt):
        st.run_study(s, cache, jobs=jobs, on_result=stop_after_5)
    files = {p.name: p.stat().st_mtime_ns for p in cache.glob('*.json')}
    assert len(files) == 5
    rows, counts = st.run_study(s, cache, jobs=jobs)
    assert counts == {'total': 12, 'cached': 5, 'ran': 7}
    assert {p: (cache / p).stat().st_mtime_ns for p in files} == files
    fresh, _ = st.run_study(s, tmp_path / 'fresh')
    assert st.to_csv(s, rows) == st.to_csv(s, fresh)
    again, counts = st.run_study(s, cache, jobs=jobs)
    assert counts == {'total': 12, 'cached': 12, 'ran': 0}


def test_cache_key_changes_with_scenario_parameters_seed_and_code():
    s = _study()
    keys = {t.key for t in st.tasks(s, version='v1')}
    assert len(keys) == 12
    assert keys == {t.key for t in st.tasks(_study(), version='v1')}
    assert keys.isdisjoint(t.key for t in st.tasks(s, version='v2'))
    other = st.make_study('homotopy_global', SETS, seeds=3, fixed={'duration': 41.0})
    assert keys.isdisjoint(t.key for t in st.tasks(other, version='v1'))


@pytest.mark.parametrize('expr, says', [
    ('law.leader_gian=5,10', 'law.leader_gian: unknown scenario field'),
    ('law.leader_gain=0,10', 'law.leader_gain: Input should be greater than or equal to 1 (got 0)'),
    ('noise.heading=0:0.05:0', "--set noise.heading: '0:0.05:0': empty range"),
    ('lambda.tau=', '--set lambda.tau: empty list of values'),
    ('lambda.tau=5,abc', "lambda.tanh_window.tau: Input should be a valid number"),
    ('leader_gain', 'give FIELD=VALUES'),
])
def test_bad_set_is_one_clear_error_before_any_run(tmp_path, capsys, expr, says):
    out = tmp_path / 'out'
    rc = simulate_cli.sweep_main(['homotopy_global', '--set', 'law.q0=0,1', '--set', expr,
                                  '--seeds', '2', '--out', str(out), '--quiet'])
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1, err
    assert says in err and err.startswith('swarm sweep: ')
    assert not out.exists()             # nothing ran, nothing was written


def test_parse_values_and_wilson():
    assert st.parse_values('5,10,20') == [5, 10, 20]
    assert st.parse_values('0:0.05:6') == pytest.approx([0, 0.01, 0.02, 0.03, 0.04, 0.05])
    assert st.parse_values('true,false') == [True, False]
    lo, hi = st.wilson(10, 10)
    assert hi == 1.0 and lo == pytest.approx(0.7225, abs=1e-4)
    lo, hi = st.wilson(0, 20)
    assert lo == 0.0 and hi == pytest.approx(0.1611, abs=1e-4)


def test_study_file(tmp_path):
    f = tmp_path / 's.yaml'
    f.write_text('name: tiny\nscenario: homotopy_global\nseeds: 2\nset: {duration: 20}\n'
                 'grid: {law.leader_gain: [10, 30], noise.heading: "0:0.02:2"}\n')
    s = st.load_study(f)
    assert s.grid == {'law.leader_gain': [10, 30], 'noise.heading': [0.0, 0.02]}
    assert s.seeds == [0, 1] and s.fixed == {'duration': 20}
    st.validate(s)
    f.write_text('scenario: homotopy_global\ngrid: {law.leader_gain: []}\n')
    with pytest.raises(st.StudyError, match='grid.law.leader_gain'):
        st.load_study(f)


def test_ctrl_c_on_the_cli_keeps_finished_runs_and_resumes(tmp_path, processes, swarm_cmd):
    """SIGINT to the whole process group (what Ctrl-C in a terminal does) during a --jobs 2
    study: exit 130, the finished runs stay cached; the same command then runs only the rest."""
    import os
    import signal
    import subprocess
    out = tmp_path / 'out'
    cmd = [swarm_cmd, 'sweep', 'homotopy_global', '--set', 'law.leader_gain=10,30', '--seeds', '5',
           '--duration', '200', '--jobs', '2', '--out', out, '--quiet', '--engine', 'reference']
    # (the reference engine: the fast one finishes all ten runs before the signal can come)
    p = processes.start(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    cache = out / 'cache'
    end = time.monotonic() + 300
    while p.poll() is None and time.monotonic() < end and \
            (not cache.exists() or len(list(cache.glob('*.json'))) < 2):
        time.sleep(0.05)
    assert p.poll() is None, 'the study ended before it could be interrupted'
    os.killpg(p.pid, signal.SIGINT)
    text = processes.communicate(p, timeout=120)
    assert p.returncode == 130, text
    assert 'interrupted; finished runs are cached' in text and 'Traceback' not in text, text
    kept = len(list(cache.glob('*.json')))
    assert 2 <= kept < 10
    p = processes.start(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    text = processes.communicate(p, timeout=600)
    assert p.returncode == 0, text
    assert f'{10 - kept} runs done, {kept} from the cache' in text, text
    assert len((out / 'runs.csv').read_text().splitlines()) == 11


def test_a_check_whose_window_starts_after_the_run_is_not_judged():
    """fig4_spacing stops at t = 320: homotopy_local's stays_split_from: 600 cannot be judged
    (it was a failure: an empty window)."""
    import numpy as np

    from swarm_core.analysis import outcomes
    from swarm_core.scenario import loader as scenario
    scn = scenario.load('homotopy_local', duration=320)
    series = {'t': np.arange(0.0, 321.0), 'clusters': np.ones(321, int)}
    res = outcomes.evaluate({'stays_split_from': 600, 'one_cluster_from': 400}, series, None, scn)
    assert res['stays_split_from']['passed'] is None and res['one_cluster_from']['passed'] is None
    series['clusters'][300] = 2
    assert outcomes.evaluate({'one_cluster_from': 200}, series, None, scn)['one_cluster_from']['passed'] is False
