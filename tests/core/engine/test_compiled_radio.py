"""The radio model in the study fast path (swarm_core.laws.paper.fast_run, fast_run_kernels) against
the reference engine (swarm_core.radio in swarm_core.engine.reference).  Pure: no ROS."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from swarm_core import radio as comms
from swarm_core import study as st
from swarm_core.engine import fast
from swarm_core.engine import reference as engine
from swarm_core.laws.paper import fast_run
from swarm_core.laws.paper import fast_run_kernels as fast_kernels
from swarm_core.model.frenet import frame_from_quaternion
from swarm_core.scenario import loader as scenario
from tests.helpers import ROOT

#: every shipped scenario and example with a radio model
RADIO_SCENARIOS = [s for s in scenario.shipped_scenarios() + sorted(str(p) for p in (ROOT / 'examples').glob('*.yaml'))
                   if yaml.safe_load(scenario.resolve(s)[0]).get('comms')]

SIX = [f'agent_{i}' for i in range(6)]


def _max_diff(a, b):
    return max(float(np.nanmax(np.abs(x - y))) for x, y in ((a.r, b.r), (a.theta, b.theta), (a.u, b.u)))


def _same_run(scn, record_every=1):
    """Both engines on ``scn``: the fast one ran, and agrees with the reference to 1e-9."""
    ref, got = engine.simulate(scn, record_every=record_every), fast.simulate(scn, record_every=record_every)
    assert got.meta['engine'] == 'fast', got.meta.get('fallback')
    assert got.r.shape == ref.r.shape and _max_diff(got, ref) < 1e-9
    assert np.array_equal(got.leader, ref.leader) and got.meta['events'] == ref.meta['events']
    assert got.meta['comms'] == ref.meta['comms']            # the same fates, message by message
    return got


def test_there_is_a_shipped_radio_scenario():
    assert any(s.endswith('homotopy_global_radio.yaml') for s in RADIO_SCENARIOS)


@pytest.mark.parametrize('name', RADIO_SCENARIOS)
def test_fast_radio_equals_reference_to_t50_on_every_shipped_radio_scenario(name):
    _same_run(scenario.load(name, duration=50.0))


@pytest.mark.parametrize('name', ['homotopy_global', 'homotopy_local'])
@pytest.mark.parametrize('radio', [
    dict(loss=0.5),
    dict(latency=0.35),                                           # 4 steps late, in order
    dict(loss=0.2, latency=0.1, jitter=0.4),                      # late and out of order
    dict(radio_range=2.0, loss=0.1),
    dict(partition=[SIX[:3]]),                                    # two groups: 0-2 and the rest
    dict(partition=[SIX[:2], SIX[2:4]], timeout=0.5, dead_reckoning=False),
    dict(loss=0.3, links=[{'sender': 'agent_0', 'receiver': 'agent_3', 'loss': 0.9},
                          {'receiver': 'agent_5', 'latency': 1.0, 'jitter': 0.2}]),
    dict(loss=0.99, timeout=20.0),                                # beliefs up to 200 steps old
], ids=['loss', 'latency', 'jitter', 'range', 'partition', 'partitions-timeout-no-dr', 'links', 'old-beliefs'])
def test_fast_radio_equals_reference_to_t50_on_radio_variants(name, radio):
    _same_run(scenario.load(name, duration=50.0, comms=radio))


def test_fast_radio_through_the_fig3_split_with_leaders_and_noise():
    # leaders chosen by the rule at t = 310, λ up near 400: the leader terms on beliefs
    scn = scenario.load('homotopy_global', duration=460.0, comms=dict(loss=0.5, latency=0.1),
                        noise={'heading': 0.01})
    traj = _same_run(scn, record_every=3)
    assert traj.leader[-1].sum() == 2


def test_fast_radio_target_law():
    _same_run(scenario.load('target_barrier', duration=50.0, comms=dict(loss=0.5, latency=0.1, radio_range=5.0)))


def test_radio_events_fall_back_to_the_reference():
    scn = scenario.load('homotopy_global', duration=5.0, comms=dict(loss=0.3, events=[{'at': 2, 'drop': 1.0}]))
    assert fast.fallback_reason(scn) == 'radio events'
    got, ref = fast.simulate(scn), engine.simulate(scn)
    assert (got.meta['engine'], got.meta['fallback']) == ('reference', 'radio events')
    assert np.array_equal(got.u, ref.u)


def test_compiled_dead_reckoning_is_the_reference_sums():
    # `fast_kernels._dead_reckon` against `comms.dead_reckon` (the same angle sums) state by state
    rng = np.random.default_rng(3)
    m = 500
    theta = rng.uniform(-np.pi, np.pi, m)
    st = np.stack([*rng.uniform(-20, 20, (2, m)), np.sin(0.5 * theta), np.cos(0.5 * theta),
                   np.where(np.arange(m) % 7 == 0, 0.0, rng.uniform(-1, 1, m))])
    sent = np.concatenate([st, frame_from_quaternion(st[2], st[3])])[None]      # (1, 7, m): as sent
    horizon = rng.uniform(0.0, 20.0, m)
    pos, qz, qw = comms.dead_reckon(st[:2].T, st[2], st[3], st[4], horizon)
    want = np.stack([pos[:, 0], pos[:, 1], *frame_from_quaternion(qz, qw)], axis=1)
    got = np.array([fast_kernels._dead_reckon(sent, 0, r, horizon[r]) for r in range(m)])
    assert np.max(np.abs(got - want)) < 1e-13


def test_compiled_fates_are_the_reference_fates():
    # every link of a few steps: loss, jitter, per-link values, a partition and the range
    n = 7
    names = [f'a{i}' for i in range(n)]
    model = comms.CommModel.from_config(dict(seed=12345, loss=0.4, latency=0.05, jitter=0.3, radio_range=3.0,
                                             partition=[names[:3]], links=[{'sender': 'a1', 'loss': 0.0},
                                                                           {'receiver': 'a6', 'jitter': 1.0}]),
                                        names, 0.1)
    rf, seed, link, labels, stats = fast_run.radio_arguments(model, n)
    keys = fast_kernels.radio_state(n, 1, 1)[7]
    rng = np.random.default_rng(1)
    arrival = np.empty((n, n), np.int64)
    for step in (0, 1, 17, 123456):
        pos = rng.uniform(-3, 3, size=(n, 2))
        fast_kernels._decide(step, pos[:, 0].copy(), pos[:, 1].copy(), seed[0], rf, link, labels, keys, arrival, stats)
        want = model.decide(step, np.arange(n), pos, np.arange(n), pos)
        assert np.array_equal(arrival, want), step
        assert (want == -1).any() and (want > step).any()          # the cases are exercised


def test_fast_radio_drop_rate_and_delays_match_their_parameters():
    # 30 links × 2001 steps: the delivered fraction within 4 σ of 1 − p; the delay of the
    # message is ceil((L + J·U)/dt − 1e-9) steps, U uniform: L = 0.1, J = 0.2, dt = 0.1 →
    # 1, 2 or 3 steps with probabilities 0, 1/2, 1/2 (1 step only if U = 0)
    p = 0.3
    scn = scenario.load('homotopy_global', duration=200.0, comms=dict(loss=p, latency=0.1, jitter=0.2))
    stats = fast.simulate(scn).meta['comms']
    sent = 30 * (scn.steps + 1)
    assert stats['sent'] == sent
    assert abs(stats['delivered_fraction'] - (1 - p)) < 4 * np.sqrt(p * (1 - p) / sent)
    assert stats['max_delay'] == pytest.approx(0.3) and stats['mean_delay'] == pytest.approx(0.25, abs=0.005)


def test_fast_radio_partition_cuts_exactly_the_named_links():
    scn = scenario.load('homotopy_global', duration=20.0, comms=dict(partition=[SIX[:2]]))
    stats = fast.simulate(scn).meta['comms']
    # 0-1 and 2-5 hear each other: 2 + 12 of 30 links carry every message
    assert stats['delivered'] == (2 + 12) * (scn.steps + 1) and stats['sent'] == 30 * (scn.steps + 1)


def test_small_radio_study_outcomes_equal(tmp_path):
    s = st.make_study('homotopy_global', [('law.leader_gain', [10, 50]), ('lambda.tau', [1, 30])], seeds=1,
                      fixed={'comms.loss': 0.5})
    assert fast.fallback_reason(scenario.load('homotopy_global', comms={'loss': 0.5})) is None
    fast_rows, _ = st.run_study(s, tmp_path / 'fast', engine='fast')
    ref_rows, _ = st.run_study(s, tmp_path / 'reference', engine='reference')
    judged = [k for k in ref_rows[0] if isinstance(ref_rows[0][k], bool) or 'clusters' in k or 't_' in k]
    assert 'split_between.t_split' in judged
    assert [{k: r[k] for k in judged} for r in fast_rows] == [{k: r[k] for k in judged} for r in ref_rows]
