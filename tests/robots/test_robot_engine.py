"""The robot engine of studies (`swarm_robots.engine`, no ROS): deterministic, the reference
engine where no agent has a robot, its metrics on hand-made cases, and the studies on robots.
That it equals the ROS lockstep run of `swarm run --robots mujoco` bit for bit:
tests/robots/ros/test_mujoco_runs.py."""
import copy

import numpy as np
import pytest

from swarm_core.engine import reference
from swarm_core.model.frenet import quaternion_from_heading
from swarm_core.scenario import loader as scenario
from swarm_robots.engine import RobotStepper, collisions, robot_rows, simulate
from tests.helpers import ROOT, SIX_AGENTS

STUDIES = ROOT / 'studies'
ROBOTS = {'length_scale': 0.3, 'cruise_speed': 0.15, 'frame': 'odom'}


def six(duration=6, **over):
    d = copy.deepcopy(SIX_AGENTS)
    d.update(duration=duration, robots=dict(ROBOTS), **over)
    return scenario.parse(d, 'six', seed=0)


def test_robot_sets():
    assert robot_rows(6, 'none') == [] and robot_rows(5, 'half') == [0, 1, 2] and robot_rows(3, 'all') == [0, 1, 2]
    with pytest.raises(ValueError, match='one of none, half, all'):
        robot_rows(3, 'some')


def test_three_robots_deterministic_and_robots_not_points():
    scn = six()
    a, b = simulate(scn, 'half'), simulate(scn, 'half')
    for f in ('r', 'theta', 'u'):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert a.meta['robots'] == b.meta['robots'] and a.meta['robots']['robots'] == ['agent_0', 'agent_1', 'agent_2']
    speed = np.linalg.norm(np.diff(a.r, axis=0), axis=2) / scn.dt
    assert speed[0, :3].max() < 0.5 and np.abs(speed[:, 3:] - 1).max() < 1e-5   # robots start from rest
    assert 0 < a.meta['robots']['iae_mean'] < 0.05


def test_kinematic_only_equals_the_reference_engine():
    scn = six(duration=20)
    a, b = simulate(scn, 'none'), reference.simulate(scn)
    for f in ('r', 'theta', 'u', 'lam', 'leader'):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert a.meta['robots']['robots'] == [] and a.meta['robots']['iae_mean'] == 0.0


def test_with_a_radio_a_robot_agents_own_heading_is_its_row_of_the_table():
    """As the agent node on a MuJoCo robot reads it (`AgentCore.take_reported`): the heading
    of the quaternion its robot's pose was reported with, unwrapped near the one before; the
    kinematic agents' own headings are their true ones."""
    from swarm_core.robot_units import reported_heading
    st = RobotStepper(six(duration=2, comms={'loss': 0.2}), [0, 1, 2])
    near = st.own_headings(st.theta)
    for _ in range(10):
        st.step()
        own = st.own_headings(st.theta)
        qz, qw = quaternion_from_heading(st.theta)
        assert own[3:].tolist() == st.theta[3:].tolist()
        assert own[:3].tolist() == [reported_heading(qz[i], qw[i], near[i]) for i in range(3)]
        assert np.abs(own[:3] - st.theta[:3]).max() < 1e-12
        near = own
    assert st.comms is not None


def test_turn_limit_and_iae_on_a_hand_made_case(monkeypatch):
    """Every agent commanded u = 20 (needs ω = 10 rad/s at v0/L = 0.5: clipped at 2.84 rad/s),
    one step of 1 model s: the robots turn at most 2.84 rad/s, so |u − u_ach| ≥ 20 − 2·2.84."""
    scn = six(duration=3, dt=1.0)
    monkeypatch.setattr(RobotStepper, 'control', lambda self, *a, **k: np.full(self.n, 20.0))
    traj = simulate(scn, 'all')
    m = traj.meta['robots']
    # commanded at the limit from the first command to the end: 3 model s = 6 robot s each
    assert m['turn_limit_fraction'] == pytest.approx(1.0)
    assert m['turn_limit_seconds_total'] == pytest.approx(6 * 6.0)
    turned = np.diff(traj.theta, axis=0)              # model units: rad per 1-s step
    assert (turned <= 2.84 * 2 + 1e-9).all()
    assert m['iae_mean'] == pytest.approx(np.abs(20.0 - turned).sum(axis=0).mean(), rel=0.02)
    assert m['iae_mean'] > 3 * (20 - 2 * 2.84)


def test_collisions_counts_each_entry():
    r = np.zeros((4, 2, 2))
    r[:, 1, 0] = [5.0, 0.5, 5.0, 0.1]                    # apart, close, apart, close again
    assert collisions(r, 1.0) == 2
    assert collisions(r[:2], 1.0) == 1 and collisions(r[[1, 3]], 1.0) == 1


def test_faults_refused():
    with pytest.raises(ValueError, match='faults'):
        simulate(six(faults=[{'kind': 'kill', 'agent': 'agent_1', 'at': 1.0}]))


# ------------------------------------------------------------------ the study on robots

@pytest.mark.parametrize('name', ['robots_fig3', 'robots_fig5', 'robots_scale'])
def test_shipped_robot_studies_parse(name):
    from swarm_core import study as st
    s = st.load_study(STUDIES / f'{name}.yaml')
    st.validate(s)
    tasks = st.tasks(s)
    assert {t.engine for t in tasks} == {'robots'} and len(s.seeds) >= (10 if 'fig' in name else 3)
    assert len(tasks) == len(s.cells()) * len(s.seeds)


def test_a_two_run_robot_study_runs_and_is_cached(tmp_path):
    from swarm_core import study as st
    s = st.load_study(STUDIES / 'robots_fig3.yaml')
    s.grid = {'robot_set': ['none', 'all']}
    s.fixed['duration'] = 10
    s.seeds = [0]
    st.validate(s)
    rows, counts = st.run_study(s, tmp_path / 'cache')
    assert counts == {'total': 2, 'cached': 0, 'ran': 2}
    kin, rob = rows
    assert kin['robot_set'] == 'none' and kin['iae_mean'] == 0.0 and kin['contacts'] == 0
    assert rob['robot_set'] == 'all' and rob['iae_mean'] > 0 and 0 <= rob['turn_limit_fraction'] <= 1
    from swarm_core.study.tables import check_names
    assert check_names(rows, s.params) == ['ok', 'one_cluster_at', 'split_between', 'one_cluster_at_end']
    assert 'IAE of u' in st.robot_metrics_markdown(s, rows)
    assert st.run_study(s, tmp_path / 'cache')[1]['cached'] == 2


def test_a_robot_set_is_checked():
    from swarm_core import study as st
    s = st.load_study(STUDIES / 'robots_fig3.yaml')
    s.grid = {'robot_set': ['some']}
    with pytest.raises(st.StudyError, match='robot_set .some.: one of none, half, all'):
        st.validate(s)
    s.grid = {'robot_set': ['all']}
    del s.fixed['robots.length_scale'], s.fixed['robots.cruise_speed'], s.data['robots']
    with pytest.raises(st.StudyError, match="needs the scenario's robots: section"):
        st.validate(s)
