"""The Sepulchre-Paley-Leonard laws (`laws.spl`) against a computation by hand: plain Python
loops over the agents with complex numbers, written from the papers' formulas and nothing of
spl.py, on random tables, all-to-all and with limited communication, several numbers of
harmonics M, all receivers or some; and `Blend` at λ = 0 and 1 equal to each law alone."""
import cmath
import math

import numpy as np
import pytest

from swarm_core.laws import Blend, CircularFormation, ParallelFormation, swarm_control
from swarm_core.model.frenet import heading_frame
from tests.core.laws import paper_law

N = 9
#: the largest |u_law − u_by_hand| allowed (the sums are the same up to rounding)
TOL = 1e-12


def table(seed, n=N, side=12.0):
    """A random table: positions in a square (one coincident pair), headings, and (cos, sin)
    through the quaternion as agents see them."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0.0, side, (n, 2))
    pos[3] = pos[5]
    cos_t, sin_t = heading_frame(rng.uniform(-np.pi, np.pi, n))
    return pos, cos_t, sin_t


def receiver_sets(seed, n=N):
    rng = np.random.default_rng(1000 + seed)
    return [np.arange(n), rng.choice(n, 4, replace=False), np.array([n - 1])]


def neighbours(pos, k, w, communication):
    """The rows j whose terms enter agent k's sums: every row all-to-all (j = k adds
    sin 0 = 0 and c_k − c_k = 0), else the other agents at a distance < w."""
    if communication == 0:
        return range(len(pos))
    return [j for j in range(len(pos))
            if j != k and math.hypot(pos[j][0] - pos[k][0], pos[j][1] - pos[k][1]) < w]


def phase_sum(theta, k, m, nbrs):
    """∂U_m/∂θ_k = (1/(mN)) Σ_j sin(m(θ_j − θ_k)), N the table size."""
    return sum(math.sin(m * (theta[j] - theta[k])) for j in nbrs) / (m * len(theta))


def parallel_by_hand(pos, cos_t, sin_t, receivers, omega0, gain, w, communication):
    """u_k = ω0 − (K/N) Σ_j sin(θ_j − θ_k) (SPL 2007; over the neighbours within w, SPL 2008)."""
    theta = [math.atan2(s, c) for c, s in zip(cos_t, sin_t)]
    out = []
    for k in receivers:
        out.append(omega0 - gain * phase_sum(theta, k, 1, neighbours(pos, k, w, communication)))
    return np.array(out)


def circular_by_hand(pos, cos_t, sin_t, receivers, omega0, kappa, harmonics, gain, gain_last, w,
                     communication):
    """u_k = ω0 (1 + κ ⟨e^{iθ_k}, (Pc)_k⟩) − Σ_{m=1..M} K_m ∂U_m/∂θ_k, c_k = r_k + i e^{iθ_k}/ω0,
    ⟨a, b⟩ = Re(conj(a) b); all-to-all (Pc)_k = c_k − mean c, limited communication
    (1/N) Σ_{j within w} (c_k − c_j) (SPL 2007, 2008)."""
    n = len(pos)
    heading = [complex(c, s) for c, s in zip(cos_t, sin_t)]
    theta = [cmath.phase(e) for e in heading]
    centre = [complex(pos[j][0], pos[j][1]) + 1j * heading[j] / omega0 for j in range(n)]
    mean = sum(centre) / n
    out = []
    for k in receivers:
        nbrs = neighbours(pos, k, w, communication)
        if communication == 0:
            pc = centre[k] - mean
        else:
            pc = sum(centre[k] - centre[j] for j in nbrs) / n
        u = omega0 * (1.0 + kappa * (heading[k].conjugate() * pc).real)
        for m in range(1, harmonics + 1):
            u -= (gain_last if m == harmonics else gain) * phase_sum(theta, k, m, nbrs)
        out.append(u)
    return np.array(out)


@pytest.mark.parametrize('communication', [0, 1])
@pytest.mark.parametrize('seed', range(4))
@pytest.mark.parametrize('omega0, gain', [(0.0, -0.1), (0.3, 0.7), (-0.2, -2.5)])
def test_parallel_formation_equals_the_loops(communication, seed, omega0, gain):
    pos, cos_t, sin_t = table(seed)
    w = 4.0 + seed
    law = ParallelFormation(omega0=omega0, phase_gain=gain, communication=communication, cutoff_radius=w)
    for recv in receiver_sets(seed):
        u = swarm_control(pos, cos_t, sin_t, recv, law)
        want = parallel_by_hand(pos, cos_t, sin_t, recv, omega0, gain, w, communication)
        assert u.shape == recv.shape
        np.testing.assert_allclose(u, want, rtol=0, atol=TOL)


@pytest.mark.parametrize('communication', [0, 1])
@pytest.mark.parametrize('seed', range(3))
@pytest.mark.parametrize('harmonics', [1, 2, 4, N, N + 3])
def test_circular_formation_equals_the_loops(communication, seed, harmonics):
    pos, cos_t, sin_t = table(seed)
    w = 5.0 + seed
    rng = np.random.default_rng(seed)
    omega0, kappa = rng.uniform(0.1, 1.0), rng.uniform(0.2, 3.0)
    gain, gain_last = rng.uniform(-1, 1), rng.uniform(-1, 1)
    law = CircularFormation(omega0=omega0, kappa=kappa, harmonics=harmonics, phase_gain=gain,
                            phase_gain_last=gain_last, communication=communication, cutoff_radius=w)
    for recv in receiver_sets(seed):
        u = swarm_control(pos, cos_t, sin_t, recv, law)
        want = circular_by_hand(pos, cos_t, sin_t, recv, omega0, kappa, harmonics, gain, gain_last, w,
                                communication)
        assert u.shape == recv.shape
        np.testing.assert_allclose(u, want, rtol=0, atol=TOL)


def test_limited_communication_sees_only_the_neighbours_within_w():
    """Agents farther apart than w do not steer each other with ``communication: 1``: an agent
    alone in its disc turns at ω0 exactly; all-to-all it does not."""
    pos = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 1.0]])
    cos_t, sin_t = heading_frame(np.array([0.3, -2.0, 1.0]))
    law = CircularFormation(omega0=0.5, harmonics=3, phase_gain=0.4, phase_gain_last=-0.3,
                            communication=1, cutoff_radius=4.0)
    assert swarm_control(pos, cos_t, sin_t, np.array([0]), law)[0] == 0.5
    assert swarm_control(pos, cos_t, sin_t, np.array([0]), law.with_parameters(communication=0))[0] != 0.5
    par = ParallelFormation(omega0=0.1, phase_gain=-1.0, communication=1, cutoff_radius=4.0)
    assert swarm_control(pos, cos_t, sin_t, np.array([0]), par)[0] == 0.1


def test_the_splay_state_on_one_circle_is_an_equilibrium():
    """N agents evenly spaced on the circle of radius 1/ω0 about one centre, each flying its
    tangent: every centre is that centre and Σ_j e^{imθ_j} = 0 for m < N, so u_k = ω0."""
    n, omega0 = 6, 0.2
    phi = 2 * np.pi * np.arange(n) / n
    pos = np.stack([np.cos(phi), np.sin(phi)], 1) / omega0 + [3.0, -1.0]
    cos_t, sin_t = heading_frame(phi + np.pi / 2)                  # anticlockwise: turning at +ω0
    law = CircularFormation(omega0=omega0, harmonics=n, phase_gain=0.1, phase_gain_last=-0.1)
    for communication in (0, 1):
        u = swarm_control(pos, cos_t, sin_t, np.arange(n), law.with_parameters(communication=communication,
                                                                                cutoff_radius=12.0))
        np.testing.assert_allclose(u, omega0, rtol=0, atol=1e-12)


# ------------------------------------------------------------------ Blend at the ends

def _leaders(n=N):
    lead = np.zeros(n, bool)
    lead[[1, 6]] = True
    return lead


@pytest.mark.parametrize('pair', ['global-circular', 'parallel-homotopy'])
@pytest.mark.parametrize('seed', range(3))
def test_blend_at_lambda_0_and_1_is_each_law_alone_bit_for_bit(pair, seed):
    """u = (1 − λ) u_from + λ u_to is u_from at λ = 0 and u_to at λ = 1 exactly, for the
    paper's global law blended into spl_circular and spl_parallel into the paper's homotopy law
    with leaders (its leader rule and steering included)."""
    if pair == 'global-circular':
        a = paper_law(kind='global')
        b = CircularFormation(omega0=0.2, harmonics=N, phase_gain=0.1, phase_gain_last=-0.1, cutoff_radius=4.0)
    else:
        a = ParallelFormation(omega0=0.05, phase_gain=-0.3, communication=1, cutoff_radius=5.0)
        b = paper_law(kind='homotopy', q0=1.0, leader_gain=30.0)
    blend = Blend(a, b)
    pos, cos_t, sin_t = table(seed)
    rng = np.random.default_rng(seed)
    is_leader = _leaders()
    for recv in receiver_sets(seed):
        steering = rng.uniform(-0.05, 0.05, recv.size)
        kw = dict(is_leader=is_leader, steering=steering)
        for lam, alone in ((0.0, a), (1.0, b)):
            got = swarm_control(pos, cos_t, sin_t, recv, blend, lambda_=lam, **kw)
            want = swarm_control(pos, cos_t, sin_t, recv, alone, lambda_=lam, **kw)
            assert np.array_equal(got, want), (lam, alone, got - want)
        half = swarm_control(pos, cos_t, sin_t, recv, blend, lambda_=0.5, **kw)
        mid = 0.5 * (swarm_control(pos, cos_t, sin_t, recv, a, lambda_=0.5, **kw)
                     + swarm_control(pos, cos_t, sin_t, recv, b, lambda_=0.5, **kw))
        np.testing.assert_allclose(half, mid, rtol=1e-15, atol=1e-15)
