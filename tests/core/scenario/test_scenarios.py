"""Scenario files, the paper's behaviours on the shipped scenarios, and the CLI (no ROS)."""
import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from swarm_core.analysis.metrics import Barrier
from swarm_core.analysis.outputs import analyse
from swarm_core.engine import reference as engine
from swarm_core.scenario import loader as scenario

SHIPPED = ['global_alignment', 'homotopy_global', 'homotopy_local', 'target_barrier',
           'leader_failover', 'leader_no_failover', 'homotopy_reunion',
           'spl_parallel', 'spl_circular', 'flock_to_circle', 'homotopy_3d', 'ground_3d', 'target_3d']
#: checks a shipped scenario is meant to fail: leader_no_failover is the contrast to
#: leader_failover (without a successor the lost leader's subswarm does not keep its program)
CONTRAST = {'leader_no_failover': {'follows_program'}}


def test_every_shipped_scenario_is_checked_here():
    assert sorted(SHIPPED) == sorted(scenario.shipped_scenarios())


@pytest.fixture(scope='module')
def runs():
    """Each shipped scenario run once with its own seed."""
    out = {}
    for name in SHIPPED:
        scn = scenario.load(name)
        traj = engine.simulate(scn)
        out[name] = (scn, traj) + analyse(traj, scenario=scn)
    return out


@pytest.mark.parametrize('name', SHIPPED)
def test_shipped_scenario_shows_the_papers_behaviour(runs, name):
    """The `expect` checks of each shipped scenario, on its own seed (batch engine)."""
    scn, traj, series, checks = runs[name]
    assert checks, 'every shipped scenario states what it expects'
    failed = {k: v for k, v in checks.items() if not v['passed']}
    assert set(failed) == CONTRAST.get(name, set()), checks


def test_failover_keeps_the_program_and_no_failover_is_captured(runs):
    """With failover a successor flies the lost leader's program (+0.01); without it, the
    orphaned subswarm follows the other leader's program (−0.01) instead."""
    on = runs['leader_failover'][3]['follows_program']
    off = runs['leader_no_failover'][3]['follows_program']
    assert on['successor'] and abs(on['turn_rate'] - 0.01) <= 0.3 * 0.01, on
    assert off['successor'] is None and abs(off['turn_rate'] + 0.01) <= 0.3 * 0.01, off


def test_reunion_splits_then_stays_one_swarm(runs):
    scn, traj, series, checks = runs['homotopy_reunion']
    t, c = series['t'], series['clusters']
    assert c[np.argmin(abs(t - 640))] >= 2                  # Fig. 4's subswarms before the reunion
    assert np.all(c[t >= 1350] == 1)                        # local coupling alone holds them after


def test_fig3_cluster_history(runs):
    scn, traj, series, checks = runs['homotopy_global']
    t, c = series['t'], series['clusters']
    assert np.all(c[t < 400] == 1)                          # one swarm under global coupling
    mid = (t > 480) & (t < 580)
    assert np.all(c[mid] == 2) and np.all(series['one_leader_per_cluster'][mid])
    assert c[-1] == 1                                       # reformed after λ → 0
    assert traj.lam[np.argmin(abs(traj.t - 500))] > 0.99


def test_fig4_stays_split(runs):
    scn, traj, series, checks = runs['homotopy_local']
    t, c = series['t'], series['clusters']
    assert np.all(c[(t >= 300) & (t <= 310)] == 1)
    assert np.all(c[t >= 600] >= 2)
    assert np.max(c) <= 3


def test_fig5_barrier_never_entered_and_target_reached(runs):
    scn, traj, series, checks = runs['target_barrier']
    hull = Barrier(scn.barrier)
    inside = hull.inside(traj.r.reshape(-1, 2))
    assert not inside.any()
    assert series['barrier_clearance'] > 1.0
    assert series['centroid_target_distance'].min() < 10.0
    x = series['centroid'][:, 0]
    assert series['clusters'][(x > 190) & (x < 215)].max() >= 2      # split around the barrier


def test_ground_3d_flies_low_over_the_ground_and_never_below_it(runs):
    """The target on the ground pulls the swarm down; the ground holds it about w above the
    floor, from the glide to the end, and it mills over the target."""
    scn, traj, series, checks = runs['ground_3d']
    z = traj.r[..., 2]
    assert scn.ground == 0.0 and z.min() > scn.ground + 3.0            # never near, never below
    assert series['floor_intrusions_total'] == 0
    late = traj.t >= 100
    assert np.median(z[late]) < scn.law.cutoff_radius + 0.5             # low: about w above the floor
    t, d = series['t'], series['centroid_target_distance']
    assert d.min() < 8.0 and d[t >= 250].max() < 30.0                   # over the target to the end


def test_target_3d_reaches_the_target_and_mills_around_it(runs):
    """The swarm reaches the 3D target as one flock and stays near it, looping through it."""
    scn, traj, series, checks = runs['target_3d']
    t, d = series['t'], series['centroid_target_distance']
    assert d.min() < 5.0
    assert d[t >= 250].max() < 30.0                                     # it stays: it mills
    close = (d < 5.0).astype(int)
    assert np.count_nonzero(np.diff(close[t >= 200]) == 1) >= 3         # and passes through it again and again
    assert np.all(series['clusters'][t >= 250] == 1)


def test_literal_barrier_reading_is_available():
    scn = scenario.load('target_barrier', duration=260)
    data = scn.spec.model_dump(by_alias=True)
    data['barrier']['mode'] = 'literal'
    lit = scenario.parse(data, duration=260)
    assert lit.law.barrier_mode == 'literal'
    tr = engine.simulate(lit, record_every=10)
    assert np.all(np.isfinite(tr.r))


def test_partial_run_is_kept_on_interrupt():
    scn = scenario.load('global_alignment', duration=50)
    calls = []

    def progress(step, steps):
        calls.append(step)
        if step > 300:
            raise KeyboardInterrupt
    tr = engine.simulate(scn, progress=progress)
    assert tr.meta['interrupted'] and 300 < len(tr.t) < scn.steps
    assert np.all(np.isfinite(tr.r))



def test_a_run_shorter_than_its_checks_leaves_them_not_judged():
    """homotopy_global to t = 20: its windows (t = 300-600) and the end are not reached; an
    interrupted run judges nothing about the end; what a short run settles still counts."""
    from swarm_core.analysis.outputs import behaviour_ok
    from swarm_tools.simulate import sweep_table
    scn = scenario.load('homotopy_global', duration=20)
    _, checks = analyse(engine.simulate(scn), scenario=scn)
    assert checks['one_cluster_at']['passed'] is None and checks['split_between']['passed'] is None
    assert 'needs t = 310' in checks['one_cluster_at']['not_judged']
    assert checks['one_cluster_at_end']['passed'] is True           # the end of the run asked for
    assert behaviour_ok(checks) is None
    full = scenario.load('homotopy_global')                          # the file's t = 1000, cut at t = 20
    part = engine.simulate(scenario.load('homotopy_global', duration=20))
    _, cut = analyse(part, scenario=full)
    assert all(v['passed'] is None for v in cut.values()), cut
    table = sweep_table('homotopy_global', [dict(seed=0, ok=None, checks=cut)])
    assert '0/1 (1 not judged' in table and 'failing seeds: []' in table
    # settled by what ran: a second cluster inside a one-cluster window fails at once
    series = dict(t=np.arange(0.0, 21.0), clusters=np.r_[np.ones(15, int), [2] * 6],
                  one_leader_per_cluster=np.zeros(21, bool))
    from swarm_core.analysis.outcomes import evaluate
    got = evaluate({'one_cluster_at': [10, 300]}, series, scn=full)
    assert got['one_cluster_at']['passed'] is False and behaviour_ok(got) is False


# ------------------------------------------------------------------ bad scenario files

def _base():
    return yaml.safe_load(scenario.resolve('homotopy_global')[0])


@pytest.mark.parametrize('mutate,field', [
    (lambda d: d['law'].update(alpha=-1), 'law.alpha'),
    (lambda d: d['law'].update(kind='magic'), 'law.kind'),
    (lambda d: d['law'].update(aplha=0.1), 'law.aplha'),
    (lambda d: d.update(dt=0), 'dt'),
    (lambda d: d.update(duration='long'), 'duration'),
    (lambda d: d['agents'].update(positions=[[0, 0], [1]]), 'agents.positions'),
    (lambda d: d['agents'].update(headings=[0.0, 1.0]), 'agents'),
    (lambda d: d.update({'lambda': {'kind': 'constant', 'value': 1.5}}), 'lambda.constant.value'),
    (lambda d: d['leaders'].update(fixed={'agent_9': {'kind': 'constant', 'curvature': 0.01}}), 'leaders'),
    (lambda d: d['leaders']['programs'][0].update(curvature=float('nan')), 'leaders.programs.0'),
    (lambda d: d.pop('agents'), 'agents'),
])
def test_bad_scenario_gives_one_clear_error_naming_the_field(mutate, field):
    data = _base()
    mutate(data)
    with pytest.raises(scenario.ScenarioError) as err:
        scenario.parse(data, 'bad.yaml')
    msg = str(err.value)
    assert msg.startswith('bad.yaml: ') and field in msg and '\n' not in msg, msg


def test_bad_files(tmp_path):
    with pytest.raises(scenario.ScenarioError, match='not a shipped scenario'):
        scenario.load('no_such_scenario')
    with pytest.raises(scenario.ScenarioError, match='no such scenario file'):
        scenario.load(str(tmp_path / 'missing.yaml'))
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: [unclosed\n')
    with pytest.raises(scenario.ScenarioError, match='not valid YAML'):
        scenario.load(str(bad))
    bad.write_text('- just\n- a list\n')
    with pytest.raises(scenario.ScenarioError, match='mapping'):
        scenario.load(str(bad))


# ------------------------------------------------------------------ CLI

def _swarm(*args, **kw):
    return subprocess.run([sys.executable, '-m', 'swarm_tools.cli', *args], capture_output=True, text=True,
                          timeout=300, **kw)


def test_cli_simulate_writes_outputs(tmp_path):
    r = _swarm('simulate', 'homotopy_global', '--duration', '120', '--seed', '4', '--out', str(tmp_path), '--quiet')
    assert r.returncode == 0, r.stderr
    z = np.load(tmp_path / 'trajectory.npz')
    T = int(round(120 / scenario.load('homotopy_global').dt)) + 1
    assert z['r'].shape == (T, 6, 2) and z['t'].shape == (T,) and z['theta'].shape == (T, 6)
    assert z['u'].shape == (T, 6) and z['lam'].shape == (T,) and list(z['names'])[0] == 'agent_0'
    assert z['t'][-1] == pytest.approx(120.0)
    doc = json.loads((tmp_path / 'metrics.json').read_text())
    assert doc['summary']['seed'] == 4 and doc['summary']['final_clusters'] == 1
    assert len(doc['series']['clusters']) == len(doc['series']['t'])
    assert (tmp_path / 'homotopy_global.png').stat().st_size > 10_000
    # the same seed gives the same run
    r2 = _swarm('simulate', 'homotopy_global', '--duration', '120', '--seed', '4', '--out', str(tmp_path / 'b'),
                '--quiet', '--no-figure')
    assert r2.returncode == 0
    np.testing.assert_array_equal(np.load(tmp_path / 'b' / 'trajectory.npz')['r'], z['r'])


def test_cli_errors_and_help(tmp_path):
    r = _swarm('simulate', 'nope')
    assert r.returncode == 2 and 'not a shipped scenario' in r.stderr
    bad = tmp_path / 'b.yaml'
    bad.write_text('name: x\nagents: {count: 3}\nlaw: {kind: global, r0: -2}\n')
    r = _swarm('simulate', str(bad))
    assert r.returncode == 2 and 'law.r0' in r.stderr
    for verb in ('simulate', 'sweep', 'scenarios'):
        r = _swarm(verb, '--help')
        assert r.returncode == 0 and 'usage: swarm ' + verb in r.stdout
    r = _swarm('frobnicate')
    assert r.returncode == 2 and 'unknown verb' in r.stderr
    assert _swarm('--help').returncode == 0


def test_cli_sweep_counts_behaviour(tmp_path):
    out = tmp_path / 'sweep.md'
    r = _swarm('sweep', 'global_alignment', '--seeds', '2', '--jobs', '1', '--out', str(out))
    assert r.returncode == 0, r.stderr
    assert '| **all checks** | **2/2** |' in out.read_text()
    res = json.loads(out.with_suffix('.json').read_text())
    assert [x['seed'] for x in res['global_alignment']] == [0, 1]
