"""The control laws of Morgan & Schwartz, written once (no ROS).

`swarm_control` computes u_k for any set of receiving agents from a table of agent states:
the batch engine passes the whole swarm as receivers, the ROS agent node passes itself as the
only receiver and the neighbour states it has received as the table.  The pair sums
(`swarm_core.laws.pair_sums`: dense row sums or a neighbour list, bit-identical) give every term but the
leader, target and barrier terms added here.

Laws (``LawConfig.kind``):
- ``global``            eq. 4,  u_k = Σ_j u_jk
- ``local``             eq. 9,  u_k = Σ_j c(ρ_jk, 0, w) u_jk          (cutoff inside the sum)
- ``leader_following``  eq. 10-11 (the homotopy law at λ = 1, q0 = 0)
- ``homotopy``          eq. 12-14 with far-coupling weight q(λ) = q0 (1 − λ)
- ``target``            eq. 15, collision avoidance within w plus target seeking
The target term (eq. 15, second line) is added to any law when a target and a nonzero
``target_gain`` are given, and the sensed-barrier term (eq. 16) whenever a barrier and a
nonzero ``barrier_gain`` are given.
"""
from __future__ import annotations

import numpy as np

from swarm_core.laws.base import Law
from swarm_core.laws.compiled_sums import compiled_moments
from swarm_core.laws.config import LawConfig
from swarm_core.laws.pair_sums import _combine, _pair_sum_sparse, _pair_sums_dense, nearest_leader


def target_term(pos_k, cos_k, sin_k, target, law: LawConfig):
    """γα(1 − (r0/|r̄_k|)²)(r̄_k·y_k), r̄_k = r̄ − r_k (eq. 15, second line); 0 at the target."""
    dx = target[0] - pos_k[:, 0]
    dy = target[1] - pos_k[:, 1]
    d2 = dx * dx + dy * dy
    inv_d2 = np.divide(1.0, d2, out=np.zeros_like(d2), where=d2 > 0.0)
    across = dy * cos_k - dx * sin_k
    if law.target_normalised:
        across = across * np.sqrt(inv_d2)
    g = law.gains
    return law.target_gain * g.alpha * (1.0 - g.r0 * g.r0 * inv_d2) * across * (d2 > 0.0)


def barrier_direction(pos_k, barrier, w):
    """Average barrier direction v_k (eq. 16, with b_i − r_k): unit vector, 0 if none sensed."""
    d = barrier[None, :, :] - pos_k[:, None, :]               # (K, m, 2)
    sensed = (d[..., 0] ** 2 + d[..., 1] ** 2) < w * w
    v = (d * sensed[..., None]).sum(axis=1)
    norm = np.hypot(v[:, 0], v[:, 1])
    return np.divide(v, norm[:, None], out=np.zeros_like(v), where=norm[:, None] > 0.0)


def barrier_term(pos_k, cos_k, sin_k, barrier, law: LawConfig):
    """Barrier avoidance (eq. 16): ±s_b (v_k·y_k).

    'ahead' (default): −s_b [v_k·x_k > 0] (v_k·y_k), steering away only while the barrier is
    ahead.  'literal': −s_b sign(v_k·x_k)(v_k·y_k), the paper's sign of v_k·y_k^⊥ with
    y^⊥ = −x."""
    v = barrier_direction(pos_k, barrier, law.cutoff_radius)
    ahead = v[:, 0] * cos_k + v[:, 1] * sin_k
    side = v[:, 1] * cos_k - v[:, 0] * sin_k
    if law.barrier_mode == 'ahead':
        gate = (ahead > 0.0).astype(float)
    else:
        gate = np.sign(ahead)
    return -law.barrier_gain * gate * side



def swarm_control(pos, cos_t, sin_t, receivers, law: LawConfig | Law, *, lambda_=0.0,
                  is_leader=None, steering=None, target=None, barrier=None, pairs=None, nearest=None, t=None):
    """Curvature controls u_k of the receivers (eq. 4, 9, 10-14, 15, 16), or of any `Law`.

    Every engine calls a law here.  A `Law` (shipped, a blend or a user's) gets a view of the
    table (`Law.evaluate`, which checks what it returns); the paper's law (`LawConfig`) runs
    the code below, with its compiled paths.

    pos (N, 2), cos_t, sin_t (N,): the table of agent states (frames from
    `swarm_core.model.frenet.heading_frame` or `frame_from_quaternion`).
    receivers (K,): table rows of the agents whose control is wanted.
    lambda_: the homotopy parameter λ (used by 'homotopy').
    is_leader (N,) bool: leader flags (used by 'leader_following' and 'homotopy').
    steering (K,): s_k of each receiver (read where the receiver is a leader).
    target (2,), barrier (m, 2): world geometry, or None.
    pairs: None (default) sums over the whole table, densely in blocks of rows; 'compiled'
    (`large_swarms.COMPILED`) the same terms in compiled kernels on every core; or
    (receiver position, sender row) arrays from a neighbour search within w, summed in that
    order with np.bincount.  Pairs beyond w may be left out only where they carry weight 0.
    nearest (K,): with pairs, each receiver's nearest leader l(k) as a table row (−1: none),
    where the table is not one shared view of the swarm (`comms.belief_controls`); default:
    `pair_sums.nearest_leader` on the table.
    t: the sim time, for a `Law`'s view (the paper's law does not read it).
    The same inputs in the same mode give bit-identical results whatever K is, which is what
    makes an agent node's u equal the batch engine's.
    """
    if not isinstance(law, LawConfig):
        return law.evaluate(pos, cos_t, sin_t, receivers, lambda_=lambda_, is_leader=is_leader, steering=steering,
                            t=t, target=target, barrier=barrier, pairs=pairs, nearest=nearest)
    pos = np.asarray(pos, dtype=float)
    receivers = np.asarray(receivers, dtype=np.intp)
    n_recv = receivers.size
    lam, q0 = law.effective_lambda_q0(lambda_) if law.kind != 'target' else (0.0, 0.0)
    leaders = recv_leader = None
    if law.uses_leaders and is_leader is not None:
        is_leader = np.asarray(is_leader, dtype=bool)
        if np.count_nonzero(is_leader):
            leaders = is_leader
            recv_leader = leaders[receivers]
    frames = np.array((cos_t, sin_t, cos_t), dtype=float)
    cos_sin = frames[:2]                                        # (2, N): the table's cos θ, sin θ
    F = frames[1:].take(receivers, axis=1)                      # (2, K): the receivers' sin θ, cos θ

    if pairs is None:               # densely over the table; rows with coincident agents redone
        m, has_cs, redo = _pair_sums_dense(pos, cos_sin, receivers, law, lam, q0, leaders, recv_leader)
        sums = _combine(m, has_cs, F, cos_sin, law)
        if redo is not None:
            m, has_cs, _ = _pair_sums_dense(pos, cos_sin, receivers[redo], law, lam, q0, leaders,
                                            None if recv_leader is None else recv_leader[redo],
                                            careful=True)
            sums[redo] = _combine(m, has_cs, F[:, redo], cos_sin, law)
    elif isinstance(pairs, str):    # 'compiled': large swarms, numba (`large_swarms`), to rounding
        sums = _compiled_sums(pos, cos_sin, F, receivers, law, lam, q0, leaders)
    else:
        sums = _pair_sum_sparse(pos, cos_t, sin_t, cos_sin, F, receivers, law, lam, q0, leaders, pairs, nearest)

    if leaders is not None:
        s = np.zeros(n_recv) if steering is None else np.asarray(steering, dtype=float)
        u = np.where(recv_leader, (1.0 - lam) * sums + lam * s, sums)
    else:
        u = sums
    return _add_world_terms(u, pos, F, receivers, law, target, barrier)


def _compiled_sums(pos, cos_sin, F, receivers, law, lam, q0, leaders):
    """Σ_j W_jk u_jk of the receivers from `large_swarms.compiled_moments` (every table row
    is summed; numba is imported on first use only)."""
    l_of_k = None if leaders is None else nearest_leader(pos, np.arange(len(pos)), leaders.nonzero()[0])
    m = compiled_moments(pos, cos_sin[0], cos_sin[1], law, lam, q0, leaders, l_of_k)
    return _combine(m[:, receivers], True, F, cos_sin, law)


def _add_world_terms(u, pos, F, receivers, law, target, barrier):
    """u plus the target term (eq. 15) and the barrier term (eq. 16) where they apply."""
    if target is not None and law.target_gain != 0.0:
        u = u + target_term(pos[receivers], F[1], F[0], np.asarray(target, float), law)
    if barrier is not None and law.barrier_gain != 0.0 and len(barrier):
        u = u + barrier_term(pos[receivers], F[1], F[0], np.asarray(barrier, float), law)
    return u
