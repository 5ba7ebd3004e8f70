"""The checks of the Sepulchre-Paley-Leonard formations (analysis/outcomes.py):
``circular_formation`` (the centres c_k = r_k + i e^{iθ_k}/ω0 gather, every agent turns at ω0)
and ``splay_state`` (max_{1≤m<N} |(1/N) Σ_j e^{imθ_j}| small), on trajectories made by hand
and on the shipped scenarios; and their schema."""
import numpy as np
import pytest

from swarm_core.analysis import outcomes
from swarm_core.analysis.outputs import analyse
from swarm_core.engine import reference as engine
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario import loader as scenario

OMEGA0 = 0.2


def circling(n=6, omega0=OMEGA0, phases=None, centre=(3.0, -1.0), t_end=100.0, dt=0.5):
    """A trajectory of n agents on the circle of radius 1/ω0 about ``centre``, anticlockwise at
    ω0, at angles ``phases`` (default: evenly spaced, the splay state)."""
    phi = 2 * np.pi * np.arange(n) / n if phases is None else np.asarray(phases, float)
    t = np.arange(0.0, t_end + dt / 2, dt)
    ang = phi[None, :] + omega0 * t[:, None]
    r = np.stack([np.cos(ang), np.sin(ang)], -1) / omega0 + np.asarray(centre)
    theta = np.angle(np.exp(1j * (ang + np.pi / 2)))
    return Trajectory([f'agent_{i}' for i in range(n)], t, r, theta, np.full((len(t), n), omega0),
                      np.zeros(len(t)), np.zeros((len(t), n), bool))


CIRCLE = {'at': 100, 'omega0': OMEGA0, 'spread_below': 0.01, 'turn_rate_within': 0.002}


def test_a_splay_circle_passes_both_checks():
    traj = circling()
    ok, d = outcomes.check_trajectory('circular_formation', CIRCLE, traj, None)
    assert ok and d['spread'] < 1e-12 and d['turn_rate_error'] == 0.0 and d['t_formed'] == 0.0
    ok, d = outcomes.check_trajectory('splay_state', {'at': 100, 'below': 0.01}, traj, None)
    assert ok and d['order'] < 1e-12 and d['t_splay'] == 0.0


def test_centres_apart_or_a_wrong_turn_rate_fail_the_circular_formation():
    traj = circling()
    traj.r[:, 2] += [1.0, 0.0]                       # agent 2's centre 1 away from the others'
    ok, d = outcomes.check_trajectory('circular_formation', CIRCLE, traj, None)
    c = traj.r[-1, :, 0] + 1j * traj.r[-1, :, 1] + 1j * np.exp(1j * traj.theta[-1]) / OMEGA0
    assert not ok and d['spread'] == pytest.approx(np.abs(c - c.mean()).max() * OMEGA0, rel=1e-3)
    assert d['t_formed'] is None
    traj = circling()
    traj.u[120:, 4] = OMEGA0 + 0.01                  # from t = 60 one agent turns faster
    ok, d = outcomes.check_trajectory('circular_formation', CIRCLE, traj, None)
    assert not ok and d['turn_rate_error'] == pytest.approx(0.01)
    ok, d = outcomes.check_trajectory('circular_formation', dict(CIRCLE, at=50), traj, None)
    assert ok and d['t_formed'] == 0.0               # judged at the sample nearest at = 50


def test_t_formed_is_when_the_formation_holds_from_on():
    traj = circling()
    traj.r[:41, 1] += [0.0, 2.0]                     # apart until t = 20, on the circle after
    ok, d = outcomes.check_trajectory('circular_formation', CIRCLE, traj, None)
    assert ok and d['t_formed'] == 20.5


def test_phases_together_or_in_a_pattern_are_not_the_splay_state():
    ok, d = outcomes.check_trajectory('splay_state', {'at': 100, 'below': 0.01},
                                      circling(phases=np.full(6, 0.3)), None)
    assert not ok and d['order'] == pytest.approx(1.0) and d['harmonic'] == 1
    # two groups of three opposite each other: |p_1| = 0 but the second harmonic is whole
    ok, d = outcomes.check_trajectory('splay_state', {'at': 100, 'below': 0.01},
                                      circling(phases=[0, 0, 0, np.pi, np.pi, np.pi]), None)
    assert not ok and d['order'] == pytest.approx(1.0) and d['harmonic'] == 2
    # the 6-splay with the m = 6 harmonic whole is still a splay state (only m < N count)
    assert outcomes.check_trajectory('splay_state', {'at': 100, 'below': 0.01}, circling(), None)[0]


def test_dead_agents_are_left_out():
    traj = circling(n=7, phases=np.r_[2 * np.pi * np.arange(6) / 6, 0.4])
    traj.r[60:, 6] = np.nan                          # the seventh, off the splay, is gone from t = 30
    traj.theta[60:, 6] = np.nan
    traj.u[59:, 6] = np.nan
    ok, d = outcomes.check_trajectory('circular_formation', CIRCLE, traj, None)
    assert ok and d['spread'] < 1e-12
    ok, d = outcomes.check_trajectory('splay_state', {'at': 100, 'below': 0.01}, traj, None)
    assert ok and d['t_splay'] == 30.0               # the six left are a 6-splay


def test_omega0_comes_from_the_scenarios_law():
    circ = scenario.load('spl_circular')
    assert outcomes.circular_law_omega0(circ.law) == 0.2
    assert outcomes.circular_law_omega0(scenario.load('flock_to_circle').law) == 0.2     # a blend's to-law
    assert outcomes.circular_law_omega0(scenario.load('spl_parallel').law) is None
    arg = {k: v for k, v in CIRCLE.items() if k != 'omega0'}
    assert outcomes.check_trajectory('circular_formation', arg, circling(), circ)[1]['omega0'] == 0.2
    with pytest.raises(ValueError, match='give omega0'):
        outcomes.check_trajectory('circular_formation', arg, circling(), scenario.load('spl_parallel'))


def _with_expect(expect):
    data, source = scenario.read_yaml('spl_circular')
    data['expect'] = expect
    return scenario.parse(data, source)


@pytest.mark.parametrize('expect, words', [
    ({'circular_formation': {'at': 10, 'spread_below': 0.1}}, 'turn_rate_within'),
    ({'circular_formation': {'at': 10, 'spread_below': -1, 'turn_rate_within': 1}}, 'spread_below'),
    ({'circular_formation': {'at': 10, 'spread_below': 1, 'turn_rate_within': 1, 'omega0': 0}}, 'omega0'),
    ({'circular_formation': {'at': 10, 'spread_below': 1, 'turn_rate_within': 1, 'radius': 5}}, 'radius'),
    ({'splay_state': {'at': 10, 'below': 2}}, 'below'),
    ({'splay_state': {'at': -1, 'below': 0.1}}, 'at'),
    ({'splay_state': 0.1}, 'splay_state'),
])
def test_the_schema_names_a_bad_argument(expect, words):
    with pytest.raises(scenario.ScenarioError, match=words):
        _with_expect(expect)


def test_the_schema_keeps_what_was_given():
    scn = _with_expect({'circular_formation': {'at': 10, 'spread_below': 0.1, 'turn_rate_within': 0.01},
                        'splay_state': {'at': 10, 'below': 0.1}})
    assert scn.spec.expect == {'circular_formation': {'at': 10, 'spread_below': 0.1, 'turn_rate_within': 0.01},
                               'splay_state': {'at': 10, 'below': 0.1}}


@pytest.mark.parametrize('communication, w', [(0, 12.0), (1, 12.0)])
def test_spl_circular_forms_the_splay_circle(communication, w):
    """The shipped scenario, all-to-all and with limited communication (w above the circle's
    diameter 2/ω0 = 10): centres together, turning at ω0, in the splay state by t = 1000."""
    data, source = scenario.read_yaml('spl_circular')
    data['law'] = dict(data['law'], communication=communication, cutoff_radius=w)
    scn = scenario.parse(data, source)
    _, checks = analyse(engine.simulate(scn), scenario=scn)
    assert set(checks) == {'circular_formation', 'splay_state'}
    assert all(v['passed'] for v in checks.values()), checks
    assert checks['circular_formation']['spread'] < 1e-3 and checks['splay_state']['order'] < 1e-3


def test_spl_parallel_flies_parallel():
    scn = scenario.load('spl_parallel')
    _, checks = analyse(engine.simulate(scn), scenario=scn)
    assert checks and all(v['passed'] for v in checks.values()), checks


def test_a_run_that_stops_before_at_is_not_judged():
    scn = scenario.load('spl_circular')
    short = scenario.load('spl_circular', duration=50)
    traj = engine.simulate(short)
    series, _ = analyse(traj, scenario=short)
    checks = outcomes.evaluate(scn.spec.expect, series, traj, scn)
    assert {v['passed'] for v in checks.values()} == {None}
