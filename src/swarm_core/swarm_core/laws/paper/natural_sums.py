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


def _block_sum(law, pos, x, recv, lam, q0, recv_leader, leader_rows):
    """Σ_j W_jk g_jk (b, 3) of the receivers ``recv`` (table rows); recv_leader: which of them
    lead, leader_rows: the leaders' rows (or None); l(k) from the same ρ² as
    `nearest_leader_3d` (ties to the lower row)."""
    d = pos[recv][:, None, :] - pos[None, :, :]                  # r_jk = r_k − r_j
    rr = np.einsum('bnc,bnc->bn', d, d)
    partner = None
    if leader_rows is not None:                                    # before the self pair is masked
        partner = np.where(recv_leader, -1, leader_rows[rr[:, leader_rows].argmin(axis=1)])
    rr[rr == 0.0] = np.inf                                         # the self pair, coincident agents: 0
    inv = 1.0 / rr
    f = law.alpha * (1.0 - law.r0 * law.r0 * inv)
    if law.avoidance_only:                                         # eq. 15: −f r_jk within w
        h = -f * (rr < law.cutoff_radius * law.cutoff_radius)
        if law.target_normalised:
            h *= np.sqrt(inv)
        return np.einsum('bn,bnc->bc', h, d)
    W = _weights(law, rr, recv_leader, lam, q0, partner)
    unit = d * np.sqrt(inv)[:, :, None]                           # r̂
    along = np.einsum('bnc,bc->bn', unit, x[recv])                 # r̂·x_k
    radial = np.einsum('bn,bnc->bc', W * (-law.eta * along - f), unit)
    return radial + law.mu * (W @ x)                              # + μ Σ_j W_jk x_j


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
    np.einsum('kc,kc->k', vec, yk, out=out[:, 0])
    np.einsum('kc,kc->k', vec, zk, out=out[:, 1])
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
        d2 = np.einsum('kc,kc->k', rbar, rbar)
        inv = np.divide(1.0, d2, out=np.zeros_like(d2), where=d2 > 0.0)
        scale = law.target_gain * law.alpha * (1.0 - law.r0 * law.r0 * inv) * (d2 > 0.0)
        if law.target_normalised:
            scale = scale * np.sqrt(inv)
        out += scale[:, None] * rbar
    if senses:
        v = barrier_direction_3d(pos_k, barrier, ground, law.cutoff_radius)
        ahead = np.einsum('kc,kc->k', v, x_k)
        gate = (ahead > 0.0).astype(float) if law.barrier_mode == 'ahead' else np.sign(ahead)
        out -= (law.barrier_gain * gate)[:, None] * v
    return out


def barrier_direction_3d(pos_k, barrier, ground, w):
    """v_k (eq. 16, b_i − r_k): the sum of the sensed directions to the barrier points and to the
    closest point of the floor z = ground, normalised; 0 where nothing is sensed."""
    v = np.zeros_like(pos_k)
    if barrier is not None and len(barrier):
        d = np.asarray(barrier, float)[None, :, :] - pos_k[:, None, :]
        sensed = np.einsum('kmc,kmc->km', d, d) < w * w
        v += np.einsum('km,kmc->kc', sensed.astype(float), d)
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
