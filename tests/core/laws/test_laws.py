"""Pure tests of the model and the control laws (no ROS)."""
import math
import warnings

import numpy as np
import pytest

from swarm_core import laws
from swarm_core.laws import swarm_control
from swarm_core.laws.paper import pair_sums
from swarm_core.laws.paper.terms import barrier_term
from swarm_core.model import frenet as model
from swarm_core.model.frenet import heading_frame
from tests.core.laws import gains, paper_law

# ------------------------------------------------------------------ pair term by hand

def _u_of_one_pair(dx, dy, th_k, th_j, gains, kind='local', **law):
    """u of agent k at the origin heading th_k with one neighbour j at r_j = −(dx, dy) heading
    th_j (r_jk = r_k − r_j = (dx, dy)), from `swarm_control`."""
    c, s = heading_frame(np.array([th_k, th_j]))
    pos = np.array([[0.0, 0.0], [-dx, -dy]])
    return swarm_control(pos, c, s, np.array([0]), paper_law(kind=kind, gains=gains, **law))[0]


def test_pair_terms_hand_computed():
    # k at the origin heading +x (x_k = (1,0), y_k = (0,1)); j at (-1,-1) heading +y.
    # r_jk = r_k - r_j = (1, 1): rho = sqrt(2), r̂·x_k = r̂·y_k = 1/sqrt(2), x_j·y_k = 1.
    def u(alpha=0.0, eta=0.0, mu=0.0):
        return _u_of_one_pair(1.0, 1.0, 0.0, math.pi / 2, gains(alpha=alpha, eta=eta, mu=mu, r0=1.5))
    assert u(eta=0.3) == pytest.approx(-0.3 * 0.5, abs=1e-15)                            # baseline
    assert u(alpha=0.2) == pytest.approx(-0.2 * (1 - 1.5 ** 2 / 2) / math.sqrt(2), abs=1e-15)  # spacing
    assert u(mu=0.5) == pytest.approx(0.5, abs=1e-15)                                    # alignment
    assert u(0.2, 0.3, 0.5) == pytest.approx(-0.15 + 0.025 / math.sqrt(2) + 0.5, abs=1e-15)


def test_pair_term_signs_follow_the_paper():
    g = gains(alpha=1.0, eta=0.0, mu=0.0, r0=1.0)
    # j straight to the left of k (r_jk = (0, -2), beyond r0): attraction turns k left (u > 0)
    assert _u_of_one_pair(0.0, -2.0, 0.0, 0.0, g) > 0
    # inside r0 it repels: turn right
    assert _u_of_one_pair(0.0, -0.5, 0.0, 0.0, g) < 0
    # alignment alone: j heading at +30° turns k anticlockwise
    g = gains(alpha=0.0, eta=0.0, mu=1.0, r0=1.0)
    assert _u_of_one_pair(0.0, -2.0, 0.0, math.radians(30), g) == pytest.approx(0.5)


def test_coincident_agents_contribute_zero_not_nan():
    pos = np.zeros((4, 2))
    cos_t, sin_t = heading_frame(np.array([0.0, 1.0, 2.0, 3.0]))
    for kind in laws.paper.LAW_KINDS:
        u = swarm_control(pos, cos_t, sin_t, np.arange(4), paper_law(kind=kind))
        np.testing.assert_allclose(u, 0.0, rtol=0, atol=1e-15, err_msg=kind)   # alignment too
        law = paper_law(kind=kind, target_gain=0.05, barrier_gain=5.0)
        u = swarm_control(pos, cos_t, sin_t, np.arange(4), law, lambda_=0.5,
                          is_leader=np.array([1, 0, 0, 1], bool), steering=np.full(4, 0.01),
                          target=np.zeros(2), barrier=np.zeros((3, 2)))
        assert np.all(np.isfinite(u)), kind


def test_cutoff_function():
    """c(ρ, q, w) (eq. 8): weight 1 where ρ < w, q from ρ = w on."""
    g = gains()
    w, q0 = 4.0, 0.25
    for rho, weight in ((3.99, 1.0), (4.0, q0), (10.0, q0)):
        u = _u_of_one_pair(0.0, -rho, 0.0, 0.3, g, kind='homotopy', cutoff_radius=w, q0=q0)
        assert u == pytest.approx(weight * _u_pair_loop((0.0, 0.0), 0.0, (0.0, rho), 0.3, g), rel=1e-12), rho


def test_frame_from_quaternion_is_orthonormal_and_matches_heading():
    th = np.linspace(-50, 50, 1001)
    c, s = heading_frame(th)
    assert np.allclose(c, np.cos(th), atol=1e-12) and np.allclose(s, np.sin(th), atol=1e-12)
    assert np.allclose(c * c + s * s, 1.0, atol=1e-15)


# ------------------------------------------------------------------ vectorised == per-pair loop

def _u_pair_loop(rk, thk, rj, thj, g):
    """eq. 5-6 written out with math, straight from docs/model.md."""
    dx, dy = rk[0] - rj[0], rk[1] - rj[1]
    rho = math.hypot(dx, dy)
    if rho == 0.0:
        return 0.0
    rx, ry = dx / rho, dy / rho
    xk = (math.cos(thk), math.sin(thk))
    yk = (-math.sin(thk), math.cos(thk))
    xj = (math.cos(thj), math.sin(thj))
    rdotx, rdoty = rx * xk[0] + ry * xk[1], rx * yk[0] + ry * yk[1]
    f = g.alpha * (1 - (g.r0 / rho) ** 2)
    return -g.eta * rdotx * rdoty - f * rdoty + g.mu * (xj[0] * yk[0] + xj[1] * yk[1])


def _law_loop(pos, th, law, lam, leaders, steering, target, barrier):
    """Every law of docs/model.md as a plain double loop over agent pairs."""
    n = len(th)
    g = law
    w = law.cutoff_radius
    def c(rho, q):                                      # eq. 8
        return 1.0 if rho < w else q
    lam_e, q0 = law.effective_lambda_q0(lam)
    out = np.zeros(n)
    lead_idx = [i for i in range(n) if leaders[i]] if law.uses_leaders else []
    for k in range(n):
        yk = (-math.sin(th[k]), math.cos(th[k]))
        xk = (math.cos(th[k]), math.sin(th[k]))
        total = 0.0
        if law.kind == 'target':
            for j in range(n):
                if j == k:
                    continue
                dx, dy = pos[k][0] - pos[j][0], pos[k][1] - pos[j][1]
                rho = math.hypot(dx, dy)
                if rho == 0:
                    continue
                dot = dx * yk[0] + dy * yk[1]
                if law.target_normalised:
                    dot /= rho
                total += c(rho, 0.0) * (-g.alpha * (1 - (g.r0 / rho) ** 2) * dot)
        elif lead_idx and k in lead_idx:
            s = sum(c(math.dist(pos[k], pos[j]), q0) * _u_pair_loop(pos[k], th[k], pos[j], th[j], g)
                    for j in range(n) if j != k)
            total = (1 - lam_e) * s + lam_e * steering[k]
        else:
            lk = None
            if lead_idx:
                lk = min(lead_idx, key=lambda i: (math.dist(pos[k], pos[i]), i))
            q = q0 * (1 - lam_e)
            for j in range(n):
                if j == k:
                    continue
                weight = c(math.dist(pos[k], pos[j]), q)
                if j == lk:
                    weight *= (law.leader_gain - 1) * lam_e + 1
                total += weight * _u_pair_loop(pos[k], th[k], pos[j], th[j], g)
        if target is not None and law.target_gain:
            tx, ty = target[0] - pos[k][0], target[1] - pos[k][1]
            d = math.hypot(tx, ty)
            dot = tx * yk[0] + ty * yk[1]
            if law.target_normalised:
                dot /= d
            total += law.target_gain * g.alpha * (1 - (g.r0 / d) ** 2) * dot
        if barrier is not None and law.barrier_gain:
            vx = vy = 0.0
            for b in barrier:
                if math.dist(b, pos[k]) < w:
                    vx += b[0] - pos[k][0]
                    vy += b[1] - pos[k][1]
            norm = math.hypot(vx, vy)
            if norm > 0:
                vx, vy = vx / norm, vy / norm
                ahead = vx * xk[0] + vy * xk[1]
                side = vx * yk[0] + vy * yk[1]
                gate = (1.0 if ahead > 0 else 0.0) if law.barrier_mode == 'ahead' else float(np.sign(ahead))
                total += -law.barrier_gain * gate * side
        out[k] = total
    return out


@pytest.mark.parametrize('kind', laws.paper.LAW_KINDS)
@pytest.mark.parametrize('seed', range(4))
def test_vectorised_law_equals_pair_loop(kind, seed):
    rng = np.random.default_rng(seed)
    n = 9
    pos = rng.uniform(-6, 6, size=(n, 2))
    th = rng.uniform(-math.pi, math.pi, size=n)
    leaders = np.zeros(n, bool)
    leaders[rng.choice(n, 2, replace=False)] = True
    law = paper_law(kind=kind, gains=gains(*rng.uniform(0.01, 0.5, 3), r0=rng.uniform(0.5, 2)),
                    cutoff_radius=4.0, leader_gain=rng.uniform(5, 50), q0=float(rng.choice([0, 1, 0.05])),
                    target_gain=0.05, target_normalised=bool(seed % 2), barrier_gain=3.0,
                    barrier_mode=('ahead', 'literal')[seed % 2])
    lam = float(rng.uniform())
    steering = rng.uniform(-0.02, 0.02, n)
    target = rng.uniform(-20, 20, 2)
    barrier = pos[0] + rng.uniform(-2, 2, size=(6, 2))
    cos_t, sin_t = heading_frame(th)
    u = swarm_control(pos, cos_t, sin_t, np.arange(n), law, lambda_=lam, is_leader=leaders,
                      steering=steering, target=target, barrier=barrier)
    ref = _law_loop(pos, th, law, lam, leaders, steering, target, barrier)
    np.testing.assert_allclose(u, ref, rtol=0, atol=1e-12)


def test_one_agent_view_equals_batch_bit_for_bit():
    """What an agent node computes (itself as the only receiver) is the batch value exactly."""
    rng = np.random.default_rng(3)
    n = 12
    pos = rng.uniform(-5, 5, (n, 2))
    th = rng.uniform(-3, 3, n)
    leaders = np.zeros(n, bool)
    leaders[[1, 7]] = True
    steer = np.where(leaders, 0.01, 0.0)
    law = paper_law(kind='homotopy', q0=1.0, barrier_gain=5.0, target_gain=0.05)
    c, s = heading_frame(th)
    kw = dict(lambda_=0.37, is_leader=leaders, target=(30.0, 4.0), barrier=pos[:3] + 1.0)
    batch = swarm_control(pos, c, s, np.arange(n), law, steering=steer, **kw)
    for k in range(n):
        # an agent sees neighbours' frames through the message quaternion
        qz, qw = model.quaternion_from_heading(th)
        ck, sk = model.frame_from_quaternion(qz.copy(), qw.copy())
        one = swarm_control(pos.copy(), ck, sk, np.array([k]), law, steering=steer[[k]], **kw)
        assert one[0] == batch[k]


@pytest.mark.parametrize('kind,lam,q0', [('global', 0.0, 1.0), ('homotopy', 0.0, 1.0), ('homotopy', 0.4, 1.0),
                                        ('homotopy', 1.0, 0.0), ('local', 0.0, 0.0), ('target', 0.0, 0.0)])
def test_one_agent_view_equals_batch_with_many_row_blocks(kind, lam, q0):
    """The dense path works in blocks of rows (`pair_sums.DENSE_BLOCK`): a swarm large enough for
    several blocks (and a partial last one) still gives every agent its batch u bit for bit,
    also for an agent whose row holds a coincident neighbour (redone with explicit masks)."""
    rng = np.random.default_rng(5)
    n = 300
    assert pair_sums.DENSE_BLOCK // n < n and n % (pair_sums.DENSE_BLOCK // n) != 0
    pos = rng.uniform(-20, 20, (n, 2))
    pos[17] = pos[40]                                   # two coincident agents
    c, s = heading_frame(rng.uniform(-3, 3, n))
    leaders = np.zeros(n, bool)
    leaders[[3, 150]] = True
    steer = np.where(leaders, 0.01, 0.0)
    law = paper_law(kind=kind, q0=q0, leader_gain=20.0)
    kw = dict(lambda_=lam, is_leader=leaders)
    batch = swarm_control(pos, c, s, np.arange(n), law, steering=steer, **kw)
    assert np.all(np.isfinite(batch))
    for k in (0, 3, 17, 40, 150, 299):
        one = swarm_control(pos, c, s, np.array([k]), law, steering=steer[[k]], **kw)
        assert one[0] == batch[k], k


@pytest.mark.parametrize('n', [9, 80])
@pytest.mark.parametrize('kind', laws.paper.LAW_KINDS)
def test_coincident_agents_equal_pair_loop(kind, n):
    """Agents at the same point contribute exactly nothing to each other (the loop skips them),
    and no floating-point warning escapes: in a small table (the dense path looks for ρ = 0
    before dividing) and in a larger one (it divides and redoes the non-finite rows)."""
    assert 9 * 9 <= pair_sums.GATHER_LIMIT < 80 * 80 <= pair_sums.DENSE_BLOCK
    rng = np.random.default_rng(8)
    pos = rng.uniform(-4, 4, (n, 2)) * math.sqrt(n / 9)
    pos[2] = pos[6]
    pos[7] = pos[6]
    th = rng.uniform(-math.pi, math.pi, n)
    leaders = np.zeros(n, bool)
    leaders[[1, 6]] = True
    law = paper_law(kind=kind, q0=0.05, leader_gain=15.0)
    steering = np.full(n, 0.01)
    c, s = heading_frame(th)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        u = swarm_control(pos, c, s, np.arange(n), law, lambda_=0.6, is_leader=leaders, steering=steering)
        one = swarm_control(pos, c, s, np.array([7]), law, lambda_=0.6, is_leader=leaders,
                            steering=steering[[7]])
    ref = _law_loop(pos, th, law, 0.6, leaders, steering, None, None)
    np.testing.assert_allclose(u, ref, rtol=0, atol=1e-12)
    assert one[0] == u[7]


def test_homotopy_limits():
    rng = np.random.default_rng(11)
    n = 8
    pos = rng.uniform(-6, 6, (n, 2))
    c, s = heading_frame(rng.uniform(-3, 3, n))
    leaders = np.zeros(n, bool)
    leaders[[0, 5]] = True
    steer = np.where(leaders, [0.01 if i == 0 else -0.01 for i in range(n)], 0.0)
    recv = np.arange(n)

    def u(kind, lam=0.0, q0=1.0):
        return swarm_control(pos, c, s, recv, paper_law(kind=kind, q0=q0, leader_gain=25.0), lambda_=lam,
                             is_leader=leaders, steering=steer)
    # λ = 0, q0 = 1: the global, group-averaged law (eq. 4), leaders and all
    np.testing.assert_array_equal(u('homotopy', 0.0, 1.0), u('global'))
    # λ = 0, q0 = 0: the local law (eq. 9)
    np.testing.assert_array_equal(u('homotopy', 0.0, 0.0), u('local'))
    # λ = 1: leader following with local coupling (eq. 10, 11), whatever q0
    for q0 in (0.0, 0.3, 1.0):
        np.testing.assert_array_equal(u('homotopy', 1.0, q0), u('leader_following'))
    np.testing.assert_array_equal(u('leader_following')[leaders], steer[leaders])
    # and it varies smoothly in between
    lams = np.linspace(0, 1, 101)
    vals = np.array([u('homotopy', lam, 1.0) for lam in lams])
    assert np.max(np.abs(np.diff(vals, axis=0))) < 0.1 * np.max(np.abs(vals)) + 1e-12


def test_follower_couples_to_its_nearest_leader():
    # one follower between two leaders, closer to leader 2
    pos = np.array([[0.0, 0.0], [-3.0, 0.0], [1.0, 0.0]])
    c, s = heading_frame(np.array([0.0, 0.5, -0.5]))
    leaders = np.array([False, True, True])
    law = paper_law(kind='leader_following', leader_gain=40.0)
    u = swarm_control(pos, c, s, np.array([0]), law, is_leader=leaders)
    g = law
    th = [0.0, 0.5, -0.5]
    by_hand = 40.0 * _u_pair_loop(pos[0], th[0], pos[2], th[2], g) + _u_pair_loop(pos[0], th[0], pos[1], th[1], g)
    assert u[0] == pytest.approx(by_hand, abs=1e-15)
    assert pair_sums.nearest_leader(pos, np.array([0]), np.array([1, 2]))[0] == 2


def test_barrier_term_turns_away_only_while_ahead():
    law = paper_law(kind='target', barrier_gain=5.0, barrier_mode='ahead')
    c, s = heading_frame(np.array([0.0]))
    pos = np.array([[0.0, 0.0]])
    ahead_left = np.array([[2.0, 1.0]])
    behind_left = np.array([[-2.0, 1.0]])
    u_ahead = barrier_term(pos, c, s, ahead_left, law)[0]
    assert u_ahead < 0                                          # turn right, away from it
    assert barrier_term(pos, c, s, behind_left, law)[0] == 0.0
    literal = paper_law(kind='target', barrier_gain=5.0, barrier_mode='literal')
    assert barrier_term(pos, c, s, behind_left, literal)[0] > 0   # the literal reading turns back
    far = np.array([[10.0, 0.0]])
    assert barrier_term(pos, c, s, far, law)[0] == 0.0      # not sensed beyond w


@pytest.mark.parametrize('kind,lam', [('local', 0.0), ('homotopy', 0.7), ('leader_following', 1.0), ('target', 0.0)])
def test_neighbour_list_equals_whole_table_with_coincident_agents(kind, lam):
    """The pair-list path (KD-tree neighbours within w, summed with np.bincount) gives the
    dense result, coincident agents included, and one agent with its own list gets its batch
    value bit for bit."""
    from swarm_core.laws.paper.pair_sums import neighbour_pairs
    from tests.helpers import pairs_of_one
    rng = np.random.default_rng(9)
    n = 200
    pos = rng.uniform(-15, 15, (n, 2))
    pos[11] = pos[12]
    c, s = heading_frame(rng.uniform(-3, 3, n))
    leaders = np.zeros(n, bool)
    leaders[[0, 12]] = True
    law = paper_law(kind=kind, q0=0.0, leader_gain=20.0)
    kw = dict(lambda_=lam, is_leader=leaders, steering=np.full(n, 0.01))
    pairs = neighbour_pairs(pos, law.cutoff_radius)
    sparse = swarm_control(pos, c, s, np.arange(n), law, pairs=pairs, **kw)
    dense = swarm_control(pos, c, s, np.arange(n), law, **kw)
    np.testing.assert_allclose(sparse, dense, rtol=0, atol=1e-14)
    for k in (0, 11, 12, 150):
        kw1 = dict(kw, steering=kw['steering'][[k]])
        one = swarm_control(pos, c, s, np.array([k]), law, pairs=pairs_of_one(pairs, k), **kw1)
        assert one[0] == sparse[k]
