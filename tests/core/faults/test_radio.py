"""The communication model (swarm_core.radio) in the batch engine and in one agent's core:
statistics of loss and delay against the configured values (binomial / CLT bounds),
determinism by seed, partitions, radio range, bursts, forgetting, dead reckoning, and the
agent-side radio reproducing the batch engine bit for bit."""
import math

import numpy as np
import pytest
from scipy import stats

from swarm_agent.agent_core import AgentCore
from swarm_core.engine.reference import SwarmStepper, simulate
from swarm_core.model.frenet import frame_from_quaternion, quaternion_from_heading
from swarm_core.model.integrate import zoh_step
from swarm_core.radio import Beliefs, CommModel, StreamRadio, change_from_event, dead_reckon, link_uniforms
from swarm_core.scenario.loader import ScenarioError, load, parse

#: family-wise false-alarm rate of each statistical assertion
ALPHA = 1e-6

BASE = dict(name='comms_test', seed=3, dt=0.05, duration=20.0,
            agents=dict(positions=[[-1, 1], [0, 1], [1, 1], [-1, 0], [0, 0], [1, 0]]),
            law=dict(kind='global'))
NAMES = [f'agent_{i}' for i in range(6)]


def scenario(comms, **kw):
    return parse(dict(BASE, comms=comms, **kw), 'test')


def run_stepper(scn, steps=None):
    st = SwarmStepper(scn)
    for _ in range(scn.steps if steps is None else steps):
        st.step()
    return st


def binom_ok(k, n, p, alpha):
    """k successes of n trials are consistent with probability p (two-sided, level alpha)."""
    lo, hi = stats.binom.interval(1 - alpha, n, p)
    return lo <= k <= hi


def test_fate_is_a_pure_function_of_seed_step_receiver_sender():
    k, j = np.meshgrid(np.arange(5), np.arange(7), indexing='ij')
    a = link_uniforms(11, 42, k, j)
    b = np.array([[link_uniforms(11, 42, kk, jj) for jj in range(7)] for kk in range(5)])
    assert np.array_equal(a, b)
    assert not np.array_equal(a, link_uniforms(12, 42, k, j))
    assert not np.array_equal(a, link_uniforms(11, 43, k, j))
    assert not np.array_equal(a, link_uniforms(11, 42, j.T, k.T).T)       # direction matters
    u = link_uniforms(0, np.arange(20000)[:, None], 1, 2).ravel()
    assert u.min() >= 0.0 and u.max() < 1.0
    assert stats.kstest(u, 'uniform').pvalue > ALPHA


def test_perfect_model_changes_nothing():
    plain = load('homotopy_global', duration=30.0)
    assert plain.comm_model() is None
    data = dict(BASE)
    a = simulate(parse(data, 'x'))
    b = simulate(parse(dict(data, comms={}), 'x'))
    c = simulate(parse(dict(data, comms=dict(timeout=0.5, dead_reckoning=False)), 'x'))
    for tr in (b, c):
        assert np.array_equal(a.r, tr.r) and np.array_equal(a.u, tr.u)
    assert 'comms' not in b.meta


@pytest.mark.parametrize('loss', [0.1, 0.45])
def test_measured_loss_matches_configured_per_link(loss):
    scn = scenario(dict(loss=loss, links=[dict(sender='agent_0', receiver='agent_5', loss=0.8)]))
    st = run_stepper(scn)
    sent, got = st.beliefs.sent, st.beliefs.delivered
    override = np.zeros((6, 6), bool)
    override[5, 0] = True
    links = st.beliefs.other & ~override
    alpha = ALPHA / (links.sum() + 1)
    for k, j in zip(*np.nonzero(links)):
        assert binom_ok(got[k, j], sent[k, j], 1 - loss, alpha), (k, j, got[k, j], sent[k, j])
    assert binom_ok(got[5, 0], sent[5, 0], 0.2, alpha)
    # pooled over links; the run is long enough that the bound is informative (± < 0.03)
    n_all, k_all = sent[links].sum(), got[links].sum()
    assert binom_ok(k_all, n_all, 1 - loss, ALPHA)
    lo, hi = stats.binom.interval(1 - ALPHA, n_all, 1 - loss)
    assert (hi - lo) / n_all < 0.06


def expected_delay_pmf(latency, jitter, dt, d_max=50):
    """P(delay = d steps) for delay = ceil((latency + U·jitter)/dt), U uniform in [0, 1)."""
    edges = (np.arange(-1, d_max + 1) * dt - latency) / jitter
    cdf = np.clip(edges, 0.0, 1.0)
    return np.diff(cdf)


def test_measured_delays_match_latency_and_jitter():
    latency, jitter, dt = 0.12, 0.2, 0.05
    scn = scenario(dict(latency=latency, jitter=jitter))
    st = run_stepper(scn)
    counts = st.beliefs.delay_counts
    pmf = expected_delay_pmf(latency, jitter, dt)
    d = np.arange(counts.size)
    assert counts.sum() == st.beliefs.sent.sum()                  # no loss configured
    assert np.all(pmf[:counts.size][counts > 0] > 0)              # only possible delays occur
    assert d[counts > 0].min() == math.ceil(latency / dt - 1e-9)
    # chi-square goodness of fit of the delay histogram
    exp = pmf[:counts.size] * counts.sum()
    keep = exp > 0
    assert stats.chisquare(counts[keep], exp[keep]).pvalue > ALPHA
    mean = (d * counts).sum() / counts.sum() * dt
    m_exp = (np.arange(pmf.size) * pmf).sum() * dt
    sd = math.sqrt((((np.arange(pmf.size) * dt - m_exp) ** 2) * pmf).sum() / counts.sum())
    assert abs(mean - m_exp) < 5 * sd
    assert st.comms_stats()['mean_delay'] == pytest.approx(mean)


def test_same_seed_same_fates_other_seed_different():
    cfg = dict(loss=0.3, latency=0.1, jitter=0.1)
    a, b = simulate(scenario(cfg)), simulate(scenario(cfg))
    assert np.array_equal(a.r, b.r) and a.meta['comms'] == b.meta['comms']
    c = simulate(scenario(dict(cfg, seed=99)))                  # the radio's own seed
    d = simulate(scenario(cfg, seed=4))                          # the scenario's seed
    assert a.meta['comms'] != c.meta['comms'] and not np.array_equal(a.r, c.r)
    assert a.meta['comms'] != d.meta['comms']


def test_partition_blocks_every_link_across_groups_and_heals():
    groups = [['agent_0', 'agent_1', 'agent_2'], ['agent_3', 'agent_4']]     # agent_5: the rest
    scn = scenario(dict(partition=groups, events=[dict(at=10.0, partition=[])]))
    st = SwarmStepper(scn)
    for _ in range(200):                        # t < 10
        st.step()
    label = np.array([0, 0, 0, 1, 1, 2])
    across = label[:, None] != label[None, :]
    assert st.beliefs.delivered[across].sum() == 0
    assert np.all(st.beliefs.delivered[~across & st.beliefs.other] == 200)
    # what a receiver believes: nothing of the other groups
    rows, *_ = st.beliefs.table(0, 199, st.comms)
    assert list(rows) == [0, 1, 2]
    before = st.beliefs.delivered.copy()
    for _ in range(50):
        st.step()
    assert np.all((st.beliefs.delivered - before)[st.beliefs.other] == 50)   # healed at t = 10


def test_radio_range_and_burst_drop():
    scn = scenario(dict(radio_range=1.2, events=[dict(at=1.0, drop=1.0, duration=1.0)]))
    m = scn.comm_model()
    pos = scn.pos0
    arr = m.decide(0, np.arange(6), pos, np.arange(6), pos)
    d = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
    assert np.array_equal(arr >= 0, d <= 1.2)
    for n in range(1, 60):
        arr = m.decide(n, np.arange(6), pos, np.arange(6), pos)
        off = ~np.eye(6, dtype=bool)
        if 20 <= n < 40:
            assert np.all(arr[off] == -1)            # burst: t in [1, 2)
        else:
            assert np.array_equal(arr >= 0, d <= 1.2)


def test_silent_sender_is_forgotten_after_the_timeout():
    m = CommModel.from_config(dict(timeout=0.5, links=[dict(sender='agent_1', receiver='agent_0', loss=1.0)],
                                   events=[]), NAMES, 0.05)
    b = Beliefs([0], 6)
    x = np.arange(6.0)
    zeros = np.zeros(6)
    q = np.ones(6)
    # step 0: everything heard (loss override starts below via a fresh model with no override)
    b.receive(0, np.zeros((1, 6), int), x, x, zeros, q, zeros)
    for n in range(1, 15):
        arr = m.decide(n, [0], np.zeros((1, 2)), np.arange(6), np.zeros((6, 2)))
        assert arr[0, 1] == -1 and np.all(arr[0, 2:] == n)
        b.receive(n, arr, x, x, zeros, q, zeros)
        rows, *_ = b.table(0, n, m)
        assert (1 in rows) == (n * 0.05 <= 0.5 + 1e-12), n       # 10 steps = 0.5 s: still known


def test_dead_reckoning_is_the_exact_arc():
    rng = np.random.default_rng(1)
    pos = rng.uniform(-5, 5, (8, 2))
    theta = rng.uniform(-3, 3, 8)
    u = rng.uniform(-0.3, 0.3, 8)
    qz, qw = quaternion_from_heading(theta)
    age = np.arange(8) * 0.05
    p, z, w = dead_reckon(pos, qz, qw, u, age, moved=age > 0)
    assert np.array_equal(p[0], pos[0]) and (z[0], w[0]) == (qz[0], qw[0])     # not moved: the same bits
    # equal (to rounding) to stepping ZOH age/dt times with the same u
    pp, tt = pos.copy(), theta.copy()
    for _ in range(7):
        pp, tt = zoh_step(pp, tt, u, 0.05)
    assert np.allclose(p[7], pp[7], atol=1e-12, rtol=0)
    c, s = frame_from_quaternion(z[7], w[7])
    assert np.allclose((c, s), (np.cos(tt[7]), np.sin(tt[7])), atol=1e-12)


def test_dead_reckoning_by_angle_sums_equals_the_arc_from_the_yaw():
    # the angle-sum form against the straightforward one (yaw from the quaternion, `zoh_step`,
    # quaternion of the new heading) over headings round the circle (±π included), horizons
    # up to 20 s, turns of several radians and u = 0
    rng = np.random.default_rng(7)
    m = 4000
    pos = rng.uniform(-50, 50, (m, 2))
    theta = np.concatenate(([np.pi, -np.pi, 0.0, np.pi / 2], rng.uniform(-np.pi, np.pi, m - 4)))
    u = np.where(np.arange(m) % 10 == 0, 0.0, rng.uniform(-1.5, 1.5, m))
    horizon = rng.uniform(0.0, 20.0, m)
    qz, qw = quaternion_from_heading(theta)
    p, z, w = dead_reckon(pos, qz, qw, u, horizon)
    p_arc, th_arc = zoh_step(pos, 2.0 * np.arctan2(qz, qw), u, horizon)
    z_arc, w_arc = quaternion_from_heading(th_arc)
    assert np.max(np.abs(p - p_arc)) < 1e-12
    assert np.max(np.abs(frame_from_quaternion(z, w)[0] - frame_from_quaternion(z_arc, w_arc)[0])) < 1e-13
    assert np.max(np.abs(frame_from_quaternion(z, w)[1] - frame_from_quaternion(z_arc, w_arc)[1])) < 1e-13
    assert np.max(np.abs(np.hypot(z, w) - 1.0)) < 1e-14                     # still a unit quaternion
    still = u == 0.0                                                       # straight on: the sent heading
    assert np.allclose(p[still], pos[still] + horizon[still, None] * np.stack(frame_from_quaternion(qz, qw), 1)[still],
                       atol=1e-12, rtol=0)


@pytest.mark.parametrize('comms', [
    dict(loss=0.3, latency=0.1, jitter=0.15),
    dict(loss=0.2, latency=0.05, dead_reckoning=False, timeout=0.3,
         links=[dict(receiver='agent_2', loss=0.9)],
         events=[dict(at=3.0, partition=[['agent_0', 'agent_1']]), dict(at=6.0, drop=0.5, duration=2.0)]),
])
def test_agents_with_their_own_radio_reproduce_the_batch_engine(comms):
    """One AgentCore per agent, each deciding only its incoming links (as an agent process
    does), equals the batch engine bit for bit, on the homotopy law with leaders and λ."""
    scn = load('homotopy_global', duration=12.0)
    scn.spec.leaders.at = 2.0
    scn.spec.lambda_.rise_at, scn.spec.lambda_.fall_at, scn.spec.lambda_.tau = 4.0, 9.0, 1.5
    scn = parse(dict(scn.spec.model_dump(by_alias=True, exclude_none=True), comms=comms), 'x')
    ref = simulate(scn)
    n = len(scn.names)
    agents = [AgentCore(i, n, *scn.pos0[i], scn.theta0[i], scn.law, scn.dt) for i in range(n)]
    for a in agents:
        a.attach_comms(CommModel.from_config(scn.comms_config(), scn.names, scn.dt, scn.seed))
    plan = scn.command_plan()
    for step in range(scn.steps + 1):
        x = np.array([a.pos[0, 0] for a in agents])
        y = np.array([a.pos[0, 1] for a in agents])
        q = np.array([a.quaternion for a in agents])
        u_sent = np.array([a.u_last for a in agents])
        c, s = frame_from_quaternion(q[:, 0], q[:, 1])
        lam, leaders, steering = plan.update(step * scn.dt, np.stack([x, y], 1), c, s)
        flags = np.zeros(n, bool)
        flags[leaders] = True
        us = [a.comms_control(step, x, y, q[:, 0], q[:, 1], u_sent, lam, flags, steering[i])
              for i, a in enumerate(agents)]
        assert np.array_equal(np.stack([x, y], 1), ref.r[step])
        assert np.array_equal(np.array(us), ref.u[step]), step
        for a, u in zip(agents, us):
            a.advance(u)
    assert ref.leader.any() and ref.lam.max() > 0.5
    assert ref.meta['comms']['delivered_fraction'] < 0.95


def test_lossy_radio_changes_the_flight():
    a = simulate(scenario({}))
    b = simulate(scenario(dict(loss=0.5, latency=0.5)))
    assert not np.allclose(a.r[-1], b.r[-1])


@pytest.mark.parametrize('comms,msg', [
    (dict(loss=1.5), 'comms.loss: Input should be less than or equal to 1'),
    (dict(partition=[['agent_0', 'nobody']]), "comms: partition: unknown agent 'nobody'"),
    (dict(links=[dict(sender='ghost', loss=0.1)]), "comms: links.0.sender: unknown agent 'ghost'"),
    (dict(events=[dict(at=3.0)]), 'comms.events.0: Value error, a comms event needs one of'),
    (dict(lossy=0.1), 'comms.lossy: Extra inputs are not permitted'),
])
def test_bad_comms_sections_give_one_line_errors(comms, msg):
    with pytest.raises(ScenarioError) as e:
        scenario(comms)
    assert msg in str(e.value) and '\n' not in str(e.value)


def test_rk4_with_a_radio_is_refused():
    with pytest.raises(ScenarioError, match='needs integrator zoh'):
        scenario(dict(loss=0.1), integrator='rk4')


def test_stream_radio_delays_drops_forgets_and_dead_reckons():
    """The realtime receive side: same fates as `decide` for the state's step, held until
    stamp + delay, range on the sender's position, timeout, dead reckoning to now."""
    cfg = dict(latency=0.1, jitter=0.1, loss=0.3, radio_range=5.0, timeout=0.5)
    model = CommModel.from_config(cfg, NAMES, 0.05, seed=2)
    ref = CommModel.from_config(cfg, NAMES, 0.05, seed=2)
    r = StreamRadio(model, 1)
    own = (0.0, 0.0, 0.0, 1.0)
    for n in range(1, 41):
        t = n * 0.05
        for j, x in ((0, 1.0), (2, 6.0)):                   # agent_2 out of range
            st = (t, x, 0.0, *quaternion_from_heading(0.0), 0.1)
            got = r.hear(j, st, own[:2])
            arr = ref.decide(n, [1], [own[:2]], [j], [[x, 0.0]])[0, 0]
            assert got == (arr >= 0)
            if got:
                assert r.in_flight[-1][0] == pytest.approx(t + (arr - n) * 0.05)
        rows, states = r.table(t, own)
        assert 2 not in rows
        if 0 in r.newest:
            assert t - r.newest[0][0] >= 0.1 - 1e-9             # never fresher than the latency
    assert r.delivered[2] == 0 and r.heard[2] == 40
    assert binom_ok(r.delivered[0], 40, 0.7, ALPHA)
    # dead reckoning: straight line at unit speed with u = 0.1 → the exact arc to now
    now = 40 * 0.05 + 0.25                                  # everything in flight has landed
    r.release(now)
    t_last, x_last = r.newest[0][0], r.newest[0][1]
    rows, states = r.table(now, own)
    assert list(rows) == [0, 1] and now - t_last >= 0.25 - 1e-9
    p_ref, th_ref = zoh_step(np.array([[x_last, 0.0]]), np.array([0.0]), np.array([0.1]), now - t_last)
    assert np.array_equal(states[0, :2], p_ref[0])
    # silence: forgotten after the timeout
    rows, _ = r.table(t_last + 0.5 + 1e-6, own)
    assert list(rows) == [1]


def test_runtime_events_are_validated():
    assert change_from_event(dict(t=1.0, kind='drop', loss=0.3, duration=5)) == dict(drop=0.3, duration=5)
    assert change_from_event(dict(t=1.0, kind='partition', groups=[])) == dict(partition=[])
    assert change_from_event(dict(t=1.0, kind='kill', agent='agent_3')) is None
    assert change_from_event(dict(t=1.0, kind='comms', source='scenario', loss=0.2)) is None
    for bad in (dict(kind='drop', loss=1.5), dict(kind='drop', loss=0.1, duration=-1),
                dict(kind='partition', groups='a,b'), dict(kind='comms', latency=float('nan')), [1]):
        with pytest.raises(ValueError):
            change_from_event(bad)
    m = CommModel.from_config(None, NAMES, 0.05)
    assert m.perfect
    with pytest.raises(ValueError, match="unknown agent 'ghost'"):
        m.apply(dict(partition=[['ghost']]), 0)


def test_dead_and_frozen_agents_send_nothing_and_are_forgotten():
    """Faults with a radio (batch engine): a killed agent's last state ages out of every
    receiver's beliefs after the timeout; a frozen agent neither sends nor listens while frozen."""
    comms = dict(loss=0.1, latency=0.05, timeout=0.5)
    scn = scenario(comms, faults=[dict(at=2.0, kill='agent_5'), dict(at=3.0, freeze='agent_2', **{'for': 1.0})])
    st = SwarmStepper(scn)
    for _ in range(40):                      # to t = 2.0: the kill applies at step 40
        st.step()
    sent_before = st.beliefs.sent.copy()
    for _ in range(30):                      # to t = 3.5: agent_2 frozen from step 60
        st.step()
    b = st.beliefs
    others = [0, 1, 3, 4]
    assert (b.stamp[others, 5] < 40).all()                  # nothing from agent_5 after its death
    assert (b.sent[:, 5] == sent_before[:, 5]).all()        # and nothing counted as sent
    assert (b.stamp[others, 2] < 60).all() and (b.stamp[2, [0, 1, 3, 4]] < 60).all()
    rows = b.table(0, st.step_index, st.comms)[0]
    assert 5 not in rows and 2 not in rows                  # both silent for longer than 0.5 s
    for _ in range(15):                      # to t = 4.25: agent_2 back from step 80
        st.step()
    assert 2 in b.table(0, st.step_index, st.comms)[0] and 5 not in b.table(0, st.step_index, st.comms)[0]
    assert (b.stamp[2, [0, 1, 3, 4]] >= 80).any()           # and it hears again
    ref = simulate(scn)
    assert np.isnan(ref.r[41:, 5]).all() and np.isfinite(ref.r[:, :5]).all()


def test_a_radio_without_per_link_overrides_needs_no_n_squared_memory():
    """No n × n override tables unless a link sets one (a 30,000-agent swarm needed 3 × 7 GB
    for them before); a link's override still applies to that link only."""
    import tracemalloc
    names = [f'a{i}' for i in range(5000)]
    tracemalloc.start()
    m = CommModel.from_config(dict(loss=0.1), names, 0.05)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 20e6, peak                     # 3 × 5000² float64 would be 600 MB
    assert m.decide(0, [0, 1], np.zeros((2, 2)), [0, 1, 2], np.zeros((3, 2))).shape == (2, 3)
    one = CommModel.from_config(dict(links=[dict(receiver='a1', sender='a0', loss=1.0)]), names[:10], 0.05)
    arrival = one.decide(0, np.arange(10), np.zeros((10, 2)), np.arange(10), np.zeros((10, 2)))
    assert arrival[1, 0] == -1 and (np.delete(arrival.ravel(), 10) >= 0).all()


def test_fates_drawn_in_blocks_equal_the_fate_function():
    """The engine draws the uniforms of many steps at once (`CommModel._uniforms`): every
    arrival across block boundaries equals the one computed from `link_uniforms` alone."""
    m = CommModel.from_config(dict(loss=0.4, latency=0.05, jitter=0.3), NAMES, 0.05, seed=9)
    k, j = np.meshgrid(np.arange(6), np.arange(6), indexing='ij')
    steps_per_block = 16384 // 36
    for step in list(range(0, 5)) + [steps_per_block - 1, steps_per_block, 3 * steps_per_block + 7]:
        arr = m.decide(step, np.arange(6), np.zeros((6, 2)), np.arange(6), np.zeros((6, 2)))
        lost = link_uniforms(9, step, k, j, 0) < 0.4
        delay = np.ceil((0.05 + 0.3 * link_uniforms(9, step, k, j, 1)) / 0.05 - 1e-9).astype(int)
        want = np.where(lost, -1, step + delay)
        want[k == j] = step
        assert np.array_equal(arr, want), step


def test_radio_range_statistics_over_random_geometry():
    """Over 400 steps of random positions: no message beyond the range is delivered, and the
    delivered fraction within range is 1 − loss (binomial, level ALPHA)."""
    m = CommModel.from_config(dict(radio_range=1.5, loss=0.25), NAMES, 0.05, seed=2)
    rng = np.random.default_rng(4)
    within = got = 0
    for step in range(400):
        pos = rng.uniform(-1.5, 1.5, (6, 2))
        arr = m.decide(step, np.arange(6), pos, np.arange(6), pos)
        d = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
        off = ~np.eye(6, dtype=bool)
        assert not (arr[off & (d > 1.5)] >= 0).any()
        within += int((off & (d <= 1.5)).sum())
        got += int((arr[off & (d <= 1.5)] >= 0).sum())
    assert within > 3000 and binom_ok(got, within, 0.75, ALPHA)
    assert not binom_ok(got, within, 0.7, ALPHA) and not binom_ok(got, within, 0.8, ALPHA)


def test_partition_cuts_exactly_the_named_links_from_its_step():
    """A scheduled partition with loss 0: from its step on, a link is cut if and only if its
    ends are in different groups (the agents in no group form one more group); before, none."""
    groups = [['agent_1', 'agent_4'], ['agent_0']]
    m = CommModel.from_config(dict(events=[dict(at=1.0, partition=groups)]), NAMES, 0.05)
    label = np.array([1, 0, 2, 2, 0, 2])
    for step in (0, 19, 20, 21, 100):
        arr = m.decide(step, np.arange(6), np.zeros((6, 2)), np.arange(6), np.zeros((6, 2)))
        cut = arr < 0
        assert np.array_equal(cut, (label[:, None] != label[None, :]) if step >= 20 else np.zeros((6, 6), bool))


def test_one_law_call_for_all_receivers_equals_each_receiver_alone():
    """`belief_controls` for the whole swarm equals, bit for bit, each receiver asking alone
    with its own beliefs (what an agent process does), on a run with loss, latency, jitter,
    leaders and a partition."""
    from swarm_core.step import belief_controls
    scn = load('homotopy_global', duration=6.0)
    scn.spec.leaders.at = 1.0
    scn = parse(dict(scn.spec.model_dump(by_alias=True, exclude_none=True),
                     comms=dict(loss=0.5, latency=0.1, jitter=0.2, partition=[['agent_0', 'agent_5']])), 'x')
    st = run_stepper(scn, 80)
    n = st.n
    t, lam, is_leader, steering, _ = st.inputs()
    assert is_leader.any()
    u_all = st.control(t, st.pos, st.theta, 0.6, is_leader, steering)
    for k in range(n):
        one = Beliefs([k], n)
        one.stamp, one.state = st.beliefs.stamp[k:k + 1], st.beliefs.state[:, k:k + 1]
        one.other = st.beliefs.other[k:k + 1]
        u = belief_controls(st.law, one, st.step_index, st.comms, st.pos[k:k + 1], st.theta[k:k + 1], 0.6,
                            is_leader, steering[k:k + 1])
        assert u[0] == u_all[k], k
    assert len(set(u_all)) == n


def test_radio_that_delivers_everything_gives_the_law_of_the_true_table():
    """A radio that loses and delays nothing (a range no pair reaches): every receiver
    believes the true states, so `belief_controls` (pair list, each receiver's own nearest
    leader) equals the law on the true table to rounding, leaders and λ included."""
    from swarm_core.model.frenet import heading_frame
    from swarm_core.step import alive_control
    scn = load('homotopy_global', duration=5.0)
    scn.spec.leaders.at = 1.0
    scn = parse(dict(scn.spec.model_dump(by_alias=True, exclude_none=True), comms=dict(radio_range=1e6)), 'x')
    st = run_stepper(scn, 40)
    t, lam, is_leader, steering, _ = st.inputs()
    assert is_leader.sum() == 2
    for lam in (0.0, 0.5, 1.0):
        got = st.control(t, st.pos, st.theta, lam, is_leader, steering)
        c, s = heading_frame(st.theta)
        want = alive_control(st.pos, c, s, np.arange(st.n), st.law, lam, is_leader, steering)
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12), (lam, got - want)


def test_each_message_predicted_once_gives_the_same_bits(monkeypatch):
    """Above MESSAGES_ONCE believed pairs each message (sender, stamp) is dead-reckoned once
    and shared by its receivers: the same bits as predicting every pair (an agent's path)."""
    import swarm_core.radio as comms
    scn = parse(dict(name='c30', seed=1, dt=0.05, duration=3.0, law=dict(kind='global'),
                     agents=dict(count=30, positions={'rule': 'grid', 'spacing': 1.5}, headings={'rule': 'cone'}),
                     comms=dict(loss=0.5, latency=0.05, jitter=0.1)), 'test')
    st = run_stepper(scn, 40)
    once = st.beliefs.known_pairs(st.step_index, st.comms)
    assert once[0].size > comms.MESSAGES_ONCE
    monkeypatch.setattr(comms, 'MESSAGES_ONCE', 10 ** 9)
    every = st.beliefs.known_pairs(st.step_index, st.comms)
    assert all(np.array_equal(p, q) for p, q in zip(once, every))
    assert len(np.unique(st.step_index - st.beliefs.stamp)) > 2              # several ages held
