"""Scenarios in three dimensions (no ROS): the schema, the batch engine, the outputs, the
shipped 3D scenario's split and reform."""
import numpy as np
import pytest

from swarm_core.analysis.metrics import time_series
from swarm_core.analysis.outputs import analyse, write_outputs
from swarm_core.engine import Trajectory
from swarm_core.engine import reference as engine
from swarm_core.scenario import ScenarioError, load, parse

SIX = [[-1, 1, 0], [0, 1, 0], [1, 1, 0], [-1, 0, 0], [0, 0, 0], [1, 0, 0]]


def _scenario(**over):
    data = dict(name='s3', dim=3, dt=0.1, duration=20, agents=dict(positions=SIX, headings={'rule': 'cap'}))
    data.update(over)
    return data


@pytest.mark.parametrize('over,text', [
    (dict(agents=dict(positions=[[0, 0], [1, 0]])), 'agents.positions: a position of a 3D scenario (dim: 3) '
                                                     'has 3 coordinates [x, y, z], got 2'),
    (dict(agents=dict(positions=SIX, headings=[0.1] * 6)), 'agents.headings: a 3D scenario (dim: 3) takes'),
    (dict(agents=dict(positions=SIX, headings={'rule': 'cone'})), 'agents.headings: a 3D scenario (dim: 3) takes'),
    (dict(agents=dict(positions=SIX, headings={'vectors': [[1, 0, 0]] * 5 + [[0, 0, 0]]})),
     'agents.headings: heading 5 (0, 0, 0) has no direction'),
    (dict(agents=dict(positions=SIX, headings={'vectors': [[1, 0, 0]] * 5 + [[0, float('nan'), 1]]})),
     'agents.headings: heading 5'),
    (dict(target={'position': [3, 4]}), 'target.position: the target of a 3D scenario'),
    (dict(barrier={'points': [[0, 0], [1, 0], [0, 1]]}), 'barrier.points: a barrier point of a 3D scenario'),
    (dict(barrier={'points': [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]}), 'do not span a volume'),
    (dict(leaders={'fixed': {'agent_0': {'kind': 'constant', 'curvature': 0.01}}}),
     'leaders.fixed.agent_0.constant.curvature: a 3D scenario (dim: 3) steers a leader by [s_u, s_v]'),
    (dict(law={'kind': 'spl_parallel'}), 'law spl_parallel is planar only'),
    (dict(robots={'scale': 1.0}), 'robots: not in 3D scenarios yet'),
    (dict(dim=4), 'dim: must be 2 or 3 (got 4)'),
])
def test_a_planar_value_in_a_3d_scenario_is_one_line_naming_the_key(over, text):
    with pytest.raises(ScenarioError) as err:
        parse(_scenario(**over), 's3.yaml')
    assert text in str(err.value) and '\n' not in str(err.value)


@pytest.mark.parametrize('over,key', [
    (dict(agents=dict(positions=SIX)), 'agents.positions'),
    (dict(agents=dict(count=6), target={'position': [1, 2, 3]}), 'target.position'),
    (dict(agents=dict(count=6), leaders={'fixed': {'agent_0': {'kind': 'constant', 'curvature': [0.01, 0]}}}),
     'leaders.fixed.agent_0.constant.curvature'),
])
def test_a_3d_value_in_a_planar_scenario_is_one_line_naming_the_key(over, key):
    with pytest.raises(ScenarioError) as err:
        parse(dict(name='s2', **over), 's2.yaml')
    assert f's2.yaml: {key}' in str(err.value) and '\n' not in str(err.value)


def test_the_cap_rule_is_seeded_and_stays_in_its_cap():
    spec = _scenario(agents=dict(count=50, headings={'rule': 'cap', 'half_width': 0.3, 'axis': [0, 0, 2]}))
    a, b, c = (parse(spec, seed=s) for s in (1, 1, 2))
    np.testing.assert_array_equal(a.frames0[0], b.frames0[0])
    assert not np.array_equal(a.frames0[0], c.frames0[0])
    assert np.all(a.frames0[0][:, 2] >= np.cos(0.3) - 1e-12)
    x = parse(_scenario(agents=dict(positions=SIX[:2], headings={'vectors': [[2, 0, 0], [0, 3, 4]]}))).frames0[0]
    np.testing.assert_allclose(x, [[1, 0, 0], [0, 0.6, 0.8]])


def test_a_planar_start_in_3d_flies_as_the_planar_engine():
    theta = np.linspace(-0.6, 0.7, 6)
    headings = np.stack([np.cos(theta), np.sin(theta), np.zeros(6)], axis=1).tolist()
    common = dict(law={'kind': 'homotopy'}, lambda_={'kind': 'constant', 'value': 0.4}, duration=100)
    common['lambda'] = common.pop('lambda_')
    s3 = parse(_scenario(agents=dict(positions=SIX, headings={'vectors': headings}),
                         leaders={'fixed': {'agent_0': {'kind': 'constant', 'curvature': [0.02, 0.0]}}}, **common))
    s2 = parse(dict(name='s2', dt=0.1, agents=dict(positions=[p[:2] for p in SIX], headings=theta.tolist()),
                    leaders={'fixed': {'agent_0': {'kind': 'constant', 'curvature': 0.02}}}, **common))
    t3, t2 = engine.simulate(s3), engine.simulate(s2)
    assert np.all(t3.v == 0.0) and np.all(t3.r[..., 2] == 0.0)
    np.testing.assert_allclose(t3.r[..., :2], t2.r, atol=1e-6)
    np.testing.assert_allclose(t3.u, t2.u, atol=1e-8)


def test_the_hold_converges_to_rk4_in_3d_at_first_order():
    spec = _scenario(law={'kind': 'global'}, duration=30)
    rk4 = engine.simulate(parse(spec, integrator='rk4', dt=0.05))
    assert rk4.meta['integrator'] == 'rk4'
    e1 = np.abs(engine.simulate(parse(spec, dt=0.1)).r[-1] - rk4.r[-1]).max()
    e2 = np.abs(engine.simulate(parse(spec, dt=0.05)).r[-1] - rk4.r[-1]).max()
    assert e1 < 0.05 and 1.6 < e1 / e2 < 2.5


def test_a_3d_run_writes_its_trajectory_and_metrics(tmp_path):
    scn = parse(_scenario(target={'position': [30, 0, 5]}, barrier={'ground': -0.5}))
    traj = engine.simulate(scn)
    series, checks = analyse(traj, scenario=scn)
    write_outputs(tmp_path, scn, traj, series, checks)
    with np.load(tmp_path / 'trajectory.npz') as z:
        T = len(traj.t)
        assert sorted(z.files) == sorted(['t', 'r', 'x', 'y', 'z', 'u', 'v', 'lam', 'leader', 'names'])
        assert z['r'].shape == z['x'].shape == z['z'].shape == (T, 6, 3) and z['v'].shape == (T, 6)
    back = Trajectory.load(tmp_path / 'trajectory.npz')
    assert back.dim == 3 and back.theta is None and np.array_equal(back.y, traj.y)
    assert (tmp_path / 's3.png').exists() and series['centroid'].shape[1] == 3
    assert 'centroid_target_distance' in series and 'floor_intrusions_total' in series


def test_metrics_in_3d_count_clusters_polarisation_and_floor_intrusions_by_hand():
    r = np.array([[[0, 0, 0], [0, 0, 3.9], [0, 0, 7.8], [9, 0, 0]],
                  [[0, 0, 0], [0, 0, 4.0], [0, 0, -1.5], [0, 3, 0]]], dtype=float)
    x = np.zeros_like(r)
    x[..., 0] = 1
    x[1, 3] = [0, 0, 1]
    leader = np.zeros((2, 4), bool)
    s = time_series(np.array([0.0, 1.0]), r, x, leader, 4.0, ground=-1.0)
    assert s['clusters'].tolist() == [2, 2]                # 3.9 < w chains; 4.0 is not < w
    np.testing.assert_allclose(s['polarisation'], [1.0, np.hypot(0.75, 0.25)])
    np.testing.assert_allclose(s['min_distance'], [3.9, 1.5])
    assert s['floor_intrusions_total'] == 1 and s['intrusions'].tolist() == [0, 1]


def test_the_shipped_3d_scenario_forms_splits_in_two_and_reforms():
    scn = load('homotopy_3d')
    traj = engine.simulate(scn)
    series, checks = analyse(traj, scenario=scn)
    assert traj.r.shape[2] == 3 and np.abs(traj.v).max() > 1e-3        # it leaves the plane
    assert all(c['passed'] for c in checks.values()), checks
    c, t = series['clusters'], series['t']
    assert c[(t >= 300) & (t <= 400)].max() == 1
    assert c[(t >= 450) & (t <= 600)].min() == 2                       # two subswarms near λ = 1
    assert checks['split_between']['t_split'] == 448.0 and checks['one_cluster_at_end']['t_reform'] == 916.0


def test_rotating_every_normal_pair_about_x_at_the_start_leaves_the_motion():
    scn = parse(_scenario(law={'kind': 'global'}, duration=100))
    base = engine.simulate(scn)
    x, y, z = scn.frames0
    phi = np.linspace(0.3, 2.9, 6)[:, None]
    scn.frames0 = (x, np.cos(phi) * y + np.sin(phi) * z, -np.sin(phi) * y + np.cos(phi) * z)
    turned = engine.simulate(scn)
    assert np.abs(turned.u - base.u).max() > 1e-3                   # (u, v) are read in other normals
    np.testing.assert_allclose(turned.r, base.r, atol=1e-8)
    np.testing.assert_allclose(turned.x, base.x, atol=1e-8)


@pytest.mark.parametrize('seed', range(5))
def test_two_agents_end_abreast_at_r0_from_random_3d_starts(seed):
    rng = np.random.default_rng(seed)
    law = {'kind': 'global', 'eta': 1.0, 'alpha': 1.0, 'mu': 1.0, 'r0': 1.0}
    scn = parse(dict(name='two', dim=3, dt=0.05, duration=20, law=law,
                     agents=dict(positions=rng.uniform(-3, 3, (2, 3)).tolist(),
                                 headings={'vectors': rng.normal(size=(2, 3)).tolist()})))
    traj = engine.simulate(scn)
    d = traj.r[-1, 1] - traj.r[-1, 0]
    rho = np.linalg.norm(d)
    assert abs(rho - 1.0) < 1e-3                                      # spacing r0
    assert 1 - traj.x[-1, 0] @ traj.x[-1, 1] < 1e-6                   # parallel headings
    assert abs(d @ traj.x[-1, 0]) / rho < 1e-3                        # a baseline across the heading
