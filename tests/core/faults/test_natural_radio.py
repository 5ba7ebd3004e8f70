"""The radio model in 3D (natural_radio.py, step.natural_belief_controls): beliefs of position
and frame, the same fates as the planar radio, a range in space."""
import numpy as np

from swarm_core.engine import reference as engine
from swarm_core.engine.natural import NaturalStepper
from swarm_core.model.natural import initial_frames, natural_step
from swarm_core.natural_radio import NaturalBeliefs, natural_dead_reckon
from swarm_core.radio import CommModel
from swarm_core.scenario import parse
from swarm_core.step import natural_belief_controls

SIX = [[-1, 1, 0], [0, 1, 0.5], [1, 1, 0], [-1, 0, 0.5], [0, 0, 0], [1, 0, 0.5]]
LAW = dict(kind='homotopy', alpha=0.02, eta=0.02, mu=0.02, r0=1.5, cutoff_radius=4.0, leader_gain=30.0, q0=1.0)
LEADER = {'fixed': {'agent_0': {'kind': 'constant', 'curvature': [0.01, 0.005]}}}


def _scenario(**over):
    data = dict(name='r3', dim=3, dt=0.1, duration=30, law=LAW, leaders=LEADER,
                agents=dict(positions=SIX, headings={'rule': 'cap', 'half_width': 0.7}),
                **{'lambda': {'kind': 'constant', 'value': 0.5}})
    data.update(over)
    return parse(data, 'r3.yaml')


def _same(a, b):
    return all(np.array_equal(getattr(a, k), getattr(b, k), equal_nan=True) for k in ('r', 'x', 'y', 'z', 'u', 'v'))


def test_a_radio_with_perfect_links_equals_no_radio_bit_for_bit():
    plain = engine.simulate(_scenario())
    assert _same(plain, engine.simulate(_scenario(comms={})))                     # the perfect section
    everyone = engine.simulate(_scenario(comms={'radio_range': 1e6, 'timeout': 0.5}))  # the radio's own path
    assert everyone.meta['comms']['delivered_fraction'] == 1.0 and everyone.meta['comms']['max_delay'] == 0.0
    assert _same(plain, everyone)
    faults = [{'at': 5, 'kill': 'agent_3'}]     # equal up to the kill; then the others still believe in it
    a = engine.simulate(_scenario(faults=faults))
    b = engine.simulate(_scenario(faults=faults, comms={'radio_range': 1e6, 'timeout': 0.5}))
    assert np.array_equal(a.r[:51], b.r[:51], equal_nan=True) and np.array_equal(a.u[:50], b.u[:50])
    assert not np.array_equal(a.u[50], b.u[50], equal_nan=True) and np.isnan(b.r[50:, 3]).all()


def test_loss_changes_the_run_and_delivers_its_fraction():
    plain = engine.simulate(_scenario())
    lossy = engine.simulate(_scenario(comms={'loss': 0.3, 'latency': 0.1, 'jitter': 0.2}))
    c = lossy.meta['comms']
    assert c['sent'] == 6 * 5 * 301 and abs(c['delivered_fraction'] - 0.7) < 0.02
    assert 0.1 <= c['mean_delay'] <= 0.3 and abs(c['max_delay'] - 0.3) < 1e-12
    assert not np.array_equal(plain.r, lossy.r)
    assert np.abs(lossy.r[-1] - plain.r[-1]).max() < 5.0
    again = engine.simulate(_scenario(comms={'loss': 0.3, 'latency': 0.1, 'jitter': 0.2}))
    assert _same(lossy, again)


def test_an_agent_alone_gets_the_batch_engines_u_v_bit_for_bit():
    scn = _scenario(comms={'loss': 0.4, 'latency': 0.2, 'jitter': 0.3})
    st = NaturalStepper(scn)
    for _ in range(40):
        t, lam, lead, steer = st.inputs()
        uv = st.control(t, st.pos, (st.x, st.y, st.z), lam, lead, steer)
        st.advance(t, uv, lead)
    t, lam, lead, steer = st.inputs()
    uv = st.control(t, st.pos, (st.x, st.y, st.z), lam, lead, steer)
    for k in range(6):
        alone = NaturalBeliefs([k], 6)
        alone.stamp[:], alone.state[:] = st.beliefs.stamp[k:k + 1], st.beliefs.state[:, k:k + 1]
        mine = natural_belief_controls(scn.law, alone, st.step_index, st.comms, st.pos[k:k + 1],
                                       (st.x[k:k + 1], st.y[k:k + 1], st.z[k:k + 1]), lam, lead, steer[k:k + 1])
        np.testing.assert_array_equal(mine[0], uv[k])


def test_the_radio_range_is_a_distance_in_space():
    m = CommModel.from_config({'radio_range': 2.0}, ['a', 'b', 'c'], 0.1)
    pos = np.array([[0, 0, 0], [0, 0, 2.5], [1.5, 0, 1.0]], float)
    arrival = m.decide(0, [0, 1, 2], pos, [0, 1, 2], pos)
    assert arrival.tolist() == [[0, -1, 0], [-1, 0, -1], [0, -1, 0]]     # a, b: 0 apart seen from above


def test_dead_reckoning_flies_the_held_u_v_on_the_exact_arc():
    rng = np.random.default_rng(3)
    r = rng.normal(size=(4, 3))
    x, y, z = initial_frames(rng.normal(size=(4, 3)))
    u, v = rng.uniform(-0.3, 0.3, 4), rng.uniform(-0.3, 0.3, 4)
    horizon = np.array([0.0, 0.1, 0.3, 0.3])
    got = natural_dead_reckon(r, x, y, z, u, v, horizon)
    for i, h in enumerate(horizon):
        want = (r[i:i + 1], x[i:i + 1], y[i:i + 1], z[i:i + 1])
        for _ in range(int(round(h / 0.1))):
            want = natural_step(*want, u[i:i + 1], v[i:i + 1], 0.1)
        for g, w in zip(got, want):
            np.testing.assert_allclose(g[i], w[0], atol=1e-13)
    assert all(np.array_equal(g[0], w[0]) for g, w in zip(got, (r, x, y, z)))      # age 0: unchanged


def test_a_dead_agent_is_forgotten_after_the_timeout():
    scn = _scenario(comms={'loss': 0.1, 'timeout': 1.0}, faults=[{'at': 2, 'kill': 'agent_2'}])
    st = NaturalStepper(scn)
    for _ in range(20 + 11):
        t, lam, lead, steer = st.inputs()
        uv = st.control(t, st.pos, (st.x, st.y, st.z), lam, lead, steer)
        st.advance(t, uv, lead)
        a, j = st.beliefs.known_pairs(st.step_index, st.comms)[:2]
        if st.step_index <= 29:
            assert 2 in j[a != 2]                       # others still believe it (they cannot know)
    assert 2 not in j                                   # forgotten 1 s after its last message
    assert np.all(uv[2] == 0.0)
