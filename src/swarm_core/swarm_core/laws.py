"""The control laws of Morgan & Schwartz, written once (no ROS).

`swarm_control` computes u_k for any set of receiving agents from a table of agent states:
the batch engine passes the whole swarm as receivers, the ROS agent node passes itself as the
only receiver and the neighbour states it has received as the table.  Pairs are summed with
``np.bincount`` in table order, so the two paths give bit-identical controls.

Laws (``LawConfig.kind``):
- ``global``            eq. 3,  u_k = Σ_j u_jk
- ``local``             eq. 7,  u_k = Σ_j c(ρ_jk, 0, w) u_jk          (cutoff inside the sum)
- ``leader_following``  eq. 8-9 (the homotopy law at λ = 1, q0 = 0)
- ``homotopy``          eq. 10-12 with far-coupling weight q(λ) = q0 (1 − λ)
- ``target``            eq. 13, collision avoidance within w plus target seeking
The target term (eq. 13, second line) is added to any law when a target and a nonzero
``target_gain`` are given, and the sensed-barrier term (eq. 14) whenever a barrier and a
nonzero ``barrier_gain`` are given.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .model import PairGains, avoidance_control, pair_control

LAW_KINDS = ('global', 'local', 'leader_following', 'homotopy', 'target')
BARRIER_MODES = ('ahead', 'literal')


@dataclass(frozen=True)
class LawConfig:
    """Which law and its constants.

    cutoff_radius  w, the communication/sensing radius of the cutoff c(ρ, q, w) (eq. 6)
    leader_gain    ℓc ≫ 1, the follower-to-leader coupling (eq. 8, 11)
    q0             far-coupling weight at λ = 0 (1: the paper's homotopy law, Fig. 3;
                   0: local coupling throughout, Fig. 4)
    target_gain    γ (eq. 13); target_normalised uses unit vectors in eq. 13
    barrier_gain   s_b (eq. 14); barrier_mode 'ahead' (default) or 'literal', see MODEL.md
    """

    kind: str = 'homotopy'
    gains: PairGains = field(default_factory=PairGains)
    cutoff_radius: float = 4.0
    leader_gain: float = 30.0
    q0: float = 1.0
    target_gain: float = 0.0
    target_normalised: bool = False
    barrier_gain: float = 0.0
    barrier_mode: str = 'ahead'

    def __post_init__(self):
        if self.kind not in LAW_KINDS:
            raise ValueError(f'law kind must be one of {LAW_KINDS}, got {self.kind!r}')
        if self.barrier_mode not in BARRIER_MODES:
            raise ValueError(f'barrier_mode must be one of {BARRIER_MODES}, got {self.barrier_mode!r}')

    @property
    def uses_leaders(self) -> bool:
        return self.kind in ('leader_following', 'homotopy')

    def effective_lambda_q0(self, lambda_: float) -> tuple[float, float]:
        """(λ, q0) at which the general homotopy form reproduces this law."""
        if self.kind == 'global':
            return 0.0, 1.0
        if self.kind == 'local':
            return 0.0, 0.0
        if self.kind == 'leader_following':
            return 1.0, 0.0
        return float(lambda_), float(self.q0)

    def couples_globally(self, lambda_: float) -> bool:
        """Whether pairs beyond w can carry weight (q(λ) > 0 or leaders with q0 > 0)."""
        if self.kind == 'target':
            return False
        lam, q0 = self.effective_lambda_q0(lambda_)
        return q0 > 0.0


def all_pairs(receivers, n: int):
    """Pairs (receiver position 0..K−1, sender row) for every sender j ≠ k, j ascending."""
    receivers = np.asarray(receivers, dtype=np.intp)
    k = np.repeat(np.arange(receivers.size, dtype=np.intp), n)
    j = np.tile(np.arange(n, dtype=np.intp), receivers.size)
    keep = j != receivers[k]
    return k[keep], j[keep]


def nearest_leader(pos, receivers, leader_rows):
    """l(k): the table row of the leader nearest (Euclidean) to each receiver; −1 if none.

    Ties go to the lower row (the lower agent index)."""
    leader_rows = np.asarray(leader_rows, dtype=np.intp)
    if leader_rows.size == 0:
        return np.full(len(receivers), -1, dtype=np.intp)
    ax = pos[receivers, 0][:, None] - pos[leader_rows, 0]
    ay = pos[receivers, 1][:, None] - pos[leader_rows, 1]
    return leader_rows[np.argmin(ax * ax + ay * ay, axis=1)]


def target_term(pos_k, cos_k, sin_k, target, law: LawConfig):
    """γα(1 − (r0/|r̄_k|)²)(r̄_k·y_k), r̄_k = r̄ − r_k (eq. 13, second line); 0 at the target."""
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
    """Average barrier direction v_k (eq. 14, with b_i − r_k): unit vector, 0 if none sensed."""
    d = barrier[None, :, :] - pos_k[:, None, :]               # (K, m, 2)
    sensed = (d[..., 0] ** 2 + d[..., 1] ** 2) < w * w
    v = (d * sensed[..., None]).sum(axis=1)
    norm = np.hypot(v[:, 0], v[:, 1])
    return np.divide(v, norm[:, None], out=np.zeros_like(v), where=norm[:, None] > 0.0)


def barrier_term(pos_k, cos_k, sin_k, barrier, law: LawConfig):
    """Barrier avoidance (eq. 14): ±s_b (v_k·y_k).

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


#: above this many agents, laws that couple only within w sum over a neighbour list
DENSE_LIMIT = 64


def sparse_coupling(n: int, law: LawConfig, lambda_: float) -> bool:
    """Whether u is summed over neighbours within w (np.bincount) rather than densely over the
    whole table.  The batch engine and the agent node both decide with this function, so
    they add the same terms in the same order."""
    return n > DENSE_LIMIT and not law.couples_globally(lambda_)


def own_neighbour_pairs(pos, row: int, radius: float):
    """Pairs (0, j) of one receiver with every other row within ``radius``, j ascending: what
    `engine.neighbour_pairs` gives for that receiver (up to pairs of weight 0)."""
    d = pos - pos[row]
    j = np.flatnonzero((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) <= radius * radius)
    j = j[j != row]
    return np.zeros(j.size, dtype=np.intp), j


#: row block of the dense path: about this many pair entries per block (fits in cache)
DENSE_BLOCK = 32768


def _pair_sums_dense(pos, cos_t, sin_t, receivers, law, lam, q0, leaders, l_of_k):
    """Σ_j weight_jk·u_jk for each receiver over the whole table, in blocks of receiver rows
    (no Python loop over pairs).  The self pair has ρ = 0 and contributes exactly 0; each row is
    reduced by numpy's row sum, whose result does not depend on how many rows a block holds."""
    n = pos.shape[0]
    out = np.empty(receivers.size)
    block = max(1, DENSE_BLOCK // max(1, n))
    w2 = law.cutoff_radius * law.cutoff_radius
    for a in range(0, receivers.size, block):
        rows = receivers[a:a + block]
        dx = pos[rows, 0][:, None] - pos[:, 0]
        dy = pos[rows, 1][:, None] - pos[:, 1]
        ck, sk = cos_t[rows][:, None], sin_t[rows][:, None]
        if law.kind == 'target':
            u = avoidance_control(dx, dy, ck, sk, law.gains, law.target_normalised)
            u = u * ((dx * dx + dy * dy) < w2)
        else:
            u = pair_control(dx, dy, ck, sk, cos_t, sin_t, law.gains)
            if leaders is None:
                far = q0 * (1.0 - lam)
                if far != 1.0:
                    u = u * np.where((dx * dx + dy * dy) < w2, 1.0, far)
            else:
                recv_leader = leaders[rows]
                far = np.where(recv_leader, q0, q0 * (1.0 - lam))[:, None]
                weight = np.where((dx * dx + dy * dy) < w2, 1.0, far)
                follower = np.flatnonzero(~recv_leader)
                weight[follower, l_of_k[a:a + block][follower]] *= (law.leader_gain - 1.0) * lam + 1.0
                u = u * weight
        out[a:a + block] = u.sum(axis=1)
    return out


def swarm_control(pos, cos_t, sin_t, receivers, law: LawConfig, *, lambda_=0.0,
                  is_leader=None, steering=None, target=None, barrier=None, pairs=None):
    """Curvature controls u_k of the receivers (eq. 3, 7, 8-12, 13, 14).

    pos (N, 2), cos_t, sin_t (N,): the table of agent states (frames from
    `model.heading_frame` or `model.frame_from_quaternion`).
    receivers (K,): table rows of the agents whose control is wanted.
    lambda_: the homotopy parameter λ (used by 'homotopy').
    is_leader (N,) bool: leader flags (used by 'leader_following' and 'homotopy').
    steering (K,): s_k of each receiver (read where the receiver is a leader).
    target (2,), barrier (m, 2): world geometry, or None.
    pairs: None (default) sums over the whole table, densely in blocks of rows; or
    (receiver position, sender row) arrays from a neighbour search within w, summed in that
    order with np.bincount.  Pairs beyond w may be left out only where they carry weight 0.
    The same inputs in the same mode give bit-identical results whatever K is, which is what
    makes an agent node's u equal the batch engine's.
    """
    pos = np.asarray(pos, dtype=float)
    receivers = np.asarray(receivers, dtype=np.intp)
    n_recv = receivers.size
    cos_k, sin_k = cos_t[receivers], sin_t[receivers]
    lam, q0 = law.effective_lambda_q0(lambda_) if law.kind != 'target' else (0.0, 0.0)
    leaders = None
    if law.uses_leaders and is_leader is not None and np.any(is_leader):
        leaders = np.asarray(is_leader, dtype=bool)
    l_of_k = nearest_leader(pos, receivers, np.flatnonzero(leaders)) if leaders is not None else None

    if pairs is None:
        sums = _pair_sums_dense(pos, cos_t, sin_t, receivers, law, lam, q0, leaders, l_of_k)
    else:
        k, j = pairs
        rk = receivers[k]
        dx = pos[rk, 0] - pos[j, 0]
        dy = pos[rk, 1] - pos[j, 1]
        ck, sk = cos_t[rk], sin_t[rk]
        within = (dx * dx + dy * dy) < law.cutoff_radius * law.cutoff_radius
        if law.kind == 'target':
            u_pair = avoidance_control(dx, dy, ck, sk, law.gains, law.target_normalised) * within
        else:
            u_pair = pair_control(dx, dy, ck, sk, cos_t[j], sin_t[j], law.gains)
            if leaders is None:
                u_pair = u_pair * np.where(within, 1.0, q0 * (1.0 - lam))
            else:
                # follower pairs: c(ρ, q0(1 − λ), w), times (ℓc − 1)λ + 1 for the pair with
                # l(k); leader pairs: c(ρ, q0, w)  (eq. 11, 12)
                pair_leader = leaders[rk]
                far = np.where(pair_leader, q0, q0 * (1.0 - lam))
                boost = np.where((j == l_of_k[k]) & ~pair_leader, (law.leader_gain - 1.0) * lam + 1.0, 1.0)
                u_pair = u_pair * (np.where(within, 1.0, far) * boost)
        sums = np.bincount(k, weights=u_pair, minlength=n_recv)

    if leaders is not None:
        s = np.zeros(n_recv) if steering is None else np.asarray(steering, dtype=float)
        u = np.where(leaders[receivers], (1.0 - lam) * sums + lam * s, sums)
    else:
        u = sums
    if target is not None and law.target_gain != 0.0:
        u = u + target_term(pos[receivers], cos_k, sin_k, np.asarray(target, float), law)
    if barrier is not None and law.barrier_gain != 0.0 and len(barrier):
        u = u + barrier_term(pos[receivers], cos_k, sin_k, np.asarray(barrier, float), law)
    return u
