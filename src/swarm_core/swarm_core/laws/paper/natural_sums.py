"""The paper's laws lifted to three dimensions (no ROS): (u_k, v_k) of each receiver.

The planar pair term (eq. 5) is the y_k component of one vector,

    g_jk = −η (r̂·x_k) r̂ − f(ρ) r̂ + μ x_j,      r̂ = r_jk/ρ,  f(ρ) = α (1 − (r0/ρ)²)

In 3D that vector is projected onto agent k's normal plane (I − x_k x_kᵀ) and both components
are read: u_jk = g_jk·y_k, v_jk = g_jk·z_k (y_k, z_k ⊥ x_k, so the projection is implicit).
The cutoff (eq. 8), the nearest leader l(k) (Euclidean), ℓc, q(λ) and the homotopy (eq. 12-14)
apply to (u, v) component by component; a leader's program is s_k = (s_u, s_v).  Target (eq. 15)
and barrier (eq. 16) are the planar terms' vector forms, read the same way; a ``ground`` height
h is a floor z = h whose closest point is sensed as one more barrier point.  Dense numpy sums
over the table, in blocks of receiver rows; no Python loop over pairs; from
`compiled_sums.COMPILED_LIMIT` agents on, compiled kernels (`natural_compiled`, equal to
rounding), as the planar engine chooses them.  ``law`` is a `PaperLaw`.
"""
from __future__ import annotations

import numpy as np

from swarm_core.laws.paper.natural_compiled import compiled_controls_3d, use_compiled

#: about this many pair entries per block of receiver rows
BLOCK = 1 << 16


def nearest_leader_3d(pos, receivers, leader_rows):
    """l(k): the table row of the leader nearest to each receiver (ties to the lower row); −1 if none."""
    if leader_rows.size == 0:
        return np.full(receivers.size, -1, dtype=np.intp)
    d = pos[receivers][:, None, :] - pos[leader_rows][None, :, :]
    return leader_rows[np.einsum('klc,klc->kl', d, d).argmin(axis=1)]


def _weights(law, rr, recv_leader, lam, q0, partner):
    """W_jk (b, N): c(ρ, q, w) with q = q0 (1 − λ) (a follower) or q0 (a leader), eq. 8, 13, 14,
    times (ℓc − 1)λ + 1 on the pair with l(k) (a follower); 0 on the self and coincident pairs."""
    within = rr < law.cutoff_radius * law.cutoff_radius
    far = q0 * (1.0 - lam) if recv_leader is None else np.where(recv_leader, q0, q0 * (1.0 - lam))[:, None]
    W = np.where(within, 1.0, far)
    if partner is not None:
        follower = partner >= 0
        W[follower, partner[follower]] *= (law.leader_gain - 1.0) * lam + 1.0
    W[~np.isfinite(rr)] = 0.0
    return W


def _dot3(a, b):
    """a·b of 3-vectors along the last axis, one receiver at a time: ((a₀b₀ + a₁b₁) + a₂b₂),
    elementwise, so a row's value does not depend on the other rows."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


#: from this many pair entries on, a block is summed by component (`_by_component`): contiguous
#: (b, N) arrays; below it in (b, 3, N) arrays (fewer numpy calls).  Both give the same bits.
BY_COMPONENT = 2048


def _block_sum(law, pos, x, recv, lam, q0, recv_leader, leader_rows):
    """Σ_j W_jk g_jk (b, 3) of the receivers ``recv`` (table rows); recv_leader: which of them
    lead, leader_rows: the leaders' rows (or None); l(k) from the same ρ² as
    `nearest_leader_3d` (ties to the lower row).  Each receiver's sum over j is `np.add.reduce`
    over its own contiguous row of products and everything else is elementwise, so a
    receiver's (u, v) is the same bit for bit whichever receivers are asked with it (an agent
    alone, a container, the batch engine)."""
    if len(recv) * len(pos) >= BY_COMPONENT:
        return _by_component(law, pos, x, recv, lam, q0, recv_leader, leader_rows)
    d = pos[recv][:, :, None] - np.ascontiguousarray(pos.T)[None]  # (b, 3, N), C order: r_jk = r_k − r_j
    rr, f, inv, partner = _distances(law, d[:, 0], d[:, 1], d[:, 2], recv_leader, leader_rows)
    if law.avoidance_only:                                         # eq. 15: −f r_jk within w
        return np.add.reduce(_avoidance(law, rr, f, inv)[:, None, :] * d, axis=2)
    W, coef = _coefficients(law, d[:, 0], d[:, 1], d[:, 2], x[recv], rr, f, inv, recv_leader, lam, q0, partner)
    align = np.add.reduce(W[:, None, :] * np.ascontiguousarray(x.T)[None], axis=2)     # Σ_j W_jk x_j
    return np.add.reduce(coef[:, None, :] * d, axis=2) + law.mu * align


def _by_component(law, pos, x, recv, lam, q0, recv_leader, leader_rows):
    """`_block_sum` with one contiguous (b, N) array per component: the same products summed
    in the same order, so the same bits."""
    pk = pos[recv]
    d = [pk[:, c, None] - pos[None, :, c] for c in range(3)]
    rr, f, inv, partner = _distances(law, *d, recv_leader, leader_rows)
    out = np.empty((len(recv), 3))
    if law.avoidance_only:
        h = _avoidance(law, rr, f, inv)
        for c in range(3):
            np.add.reduce(h * d[c], axis=1, out=out[:, c])
        return out
    W, coef = _coefficients(law, *d, x[recv], rr, f, inv, recv_leader, lam, q0, partner)
    for c in range(3):                                             # + μ Σ_j W_jk x_j
        out[:, c] = np.add.reduce(coef * d[c], axis=1) + law.mu * np.add.reduce(W * x[None, :, c], axis=1)
    return out


def _distances(law, d0, d1, d2, recv_leader, leader_rows):
    """ρ² (b, N) (∞ on the self and coincident pairs), f(ρ), 1/ρ² and l(k) (from ρ² before the
    self pair is masked; None without leaders)."""
    rr = d0 * d0 + d1 * d1 + d2 * d2
    partner = None
    if leader_rows is not None:
        partner = np.where(recv_leader, -1, leader_rows[rr[:, leader_rows].argmin(axis=1)])
    rr[rr == 0.0] = np.inf                                         # the self pair, coincident agents: 0
    inv = 1.0 / rr
    return rr, law.alpha * (1.0 - law.r0 * law.r0 * inv), inv, partner


def _avoidance(law, rr, f, inv):
    """The coefficient of r_jk in eq. 15's pair term: −f within w (over ρ if normalised)."""
    h = -f * (rr < law.cutoff_radius * law.cutoff_radius)
    if law.target_normalised:
        h *= np.sqrt(inv)
    return h


def _coefficients(law, d0, d1, d2, xk, rr, f, inv, recv_leader, lam, q0, partner):
    """W_jk (b, N) and the coefficient of r_jk in W_jk g_jk: W (−η (r̂·x_k) − f) / ρ."""
    W = _weights(law, rr, recv_leader, lam, q0, partner)
    s = np.sqrt(inv)                                               # 1/ρ: r̂ = s r_jk
    along = (d0 * xk[:, 0, None] + d1 * xk[:, 1, None] + d2 * xk[:, 2, None]) * s     # r̂·x_k
    return W, W * (-law.eta * along - f) * s


def pair_sums_3d(law, pos, x, receivers, lam, q0, leaders):
    """Σ_j W_jk g_jk (K, 3) of every receiver (the pair term of eq. 4, 9, 13 as a vector), in
    blocks of receiver rows."""
    recv_leader = leader_rows = None
    if leaders is not None and leaders.any():
        recv_leader, leader_rows = leaders[receivers], leaders.nonzero()[0]
    step = max(1, BLOCK // max(1, len(pos)))
    if receivers.size <= step:                                     # one block (small swarms)
        return _block_sum(law, pos, x, receivers, lam, q0, recv_leader, leader_rows)
    out = np.empty((receivers.size, 3))
    for a in range(0, receivers.size, step):
        b = min(a + step, receivers.size)
        out[a:b] = _block_sum(law, pos, x, receivers[a:b], lam, q0, None if recv_leader is None else
                              recv_leader[a:b], leader_rows)
    return out


def read_normal(vec, yk, zk):
    """(a·y_k, a·z_k) (K, 2) of vectors a (K, 3): their components in each receiver's normal plane."""
    out = np.empty((len(vec), 2))
    out[:, 0], out[:, 1] = _dot3(vec, yk), _dot3(vec, zk)
    return out


def world_vector_3d(law, pos, x, receivers, target, barrier, ground):
    """The target (eq. 15) and barrier (eq. 16) terms of the receivers as vectors (K, 3), before
    projection; None where neither applies."""
    aims = target is not None and law.target_gain != 0.0
    senses = law.barrier_gain != 0.0 and (ground is not None or (barrier is not None and len(barrier)))
    if not (aims or senses):
        return None
    pos_k, x_k = pos[receivers], x[receivers]
    out = np.zeros_like(pos_k)
    if aims:
        rbar = np.asarray(target, float)[None, :] - pos_k
        d2 = _dot3(rbar, rbar)
        inv = np.divide(1.0, d2, out=np.zeros_like(d2), where=d2 > 0.0)
        scale = law.target_gain * law.alpha * (1.0 - law.r0 * law.r0 * inv) * (d2 > 0.0)
        if law.target_normalised:
            scale = scale * np.sqrt(inv)
        out += scale[:, None] * rbar
    if senses:
        v = barrier_direction_3d(pos_k, barrier, ground, law.cutoff_radius)
        ahead = _dot3(v, x_k)
        gate = (ahead > 0.0).astype(float) if law.barrier_mode == 'ahead' else np.sign(ahead)
        out -= (law.barrier_gain * gate)[:, None] * v
    return out


def barrier_direction_3d(pos_k, barrier, ground, w):
    """v_k (eq. 16, b_i − r_k): the sum of the sensed directions to the barrier points and to the
    closest point of the floor z = ground, normalised; 0 where nothing is sensed."""
    v = np.zeros_like(pos_k)
    if barrier is not None and len(barrier):
        d = np.asarray(barrier, float).T[None, :, :] - pos_k[:, :, None]       # (K, 3, m): b_i − r_k
        sensed = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2] < w * w
        v += np.add.reduce(sensed[:, None, :] * d, axis=2)
    if ground is not None:
        below = float(ground) - pos_k[:, 2]                         # the floor's closest point: (x, y, h)
        v[:, 2] += np.where(np.abs(below) < w, below, 0.0)
    norm = np.linalg.norm(v, axis=1)
    return np.divide(v, norm[:, None], out=np.zeros_like(v), where=norm[:, None] > 0.0)


def natural_controls(law, pos, frames, receivers, lam, q0, leaders, steering, target, barrier, ground,
                     sums='auto'):
    """(u_k, v_k) (K, 2) of the receivers: the pair sums read in each receiver's (y, z) (compiled
    where `natural_compiled.use_compiled` says so for ``sums``), the leader's line of eq. 14
    component by component, plus the world terms."""
    x, y, z = frames
    if use_compiled(len(pos), sums):
        uv = compiled_controls_3d(law, pos, frames, receivers, lam, q0, leaders)
    else:
        uv = read_normal(pair_sums_3d(law, pos, x, receivers, lam, q0, leaders), y[receivers], z[receivers])
    if leaders is not None:
        s = np.zeros((receivers.size, 2)) if steering is None else np.asarray(steering, float).reshape(-1, 2)
        uv = np.where(leaders[receivers][:, None], (1.0 - lam) * uv + lam * s, uv)
    world = world_vector_3d(law, pos, x, receivers, target, barrier, ground)
    return uv if world is None else uv + read_normal(world, y[receivers], z[receivers])
