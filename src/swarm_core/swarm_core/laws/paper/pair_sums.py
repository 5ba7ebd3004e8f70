"""The pair sums of the control laws (no ROS): Σ_j c(ρ_jk, q, w) u_jk for every receiver k,
formed from a few per-receiver "moments" of the pair geometry (eq. 4-5, 8, 13-15).

Two paths give bit-identical sums, both in table order and independent of how many receivers
are asked for: dense (`_pair_sums_dense`: numpy row sums over the whole table, in row blocks
held in reused scratch arrays) and sparse (`_pair_sums_sparse`: ``np.bincount`` over a
neighbour list, `neighbour_pairs`).  No Python loop runs over pairs.  `PaperLaw.evaluate`
chooses the path and adds the leader, target and barrier terms; the speed-ups are measured in
BENCHMARKS.md (`scripts/bench_core.py`).  ``law`` is a `PaperLaw` (its gains, w, ℓc and
``avoidance_only``, eq. 15); lam, q0 its effective λ and q0."""
from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass

import numpy as np


def nearest_leader(pos, receivers, leader_rows):
    """l(k): the table row of the leader nearest (Euclidean) to each receiver; −1 if none.

    Ties go to the lower row (the lower agent index)."""
    leader_rows = np.asarray(leader_rows, dtype=np.intp)
    if leader_rows.size == 0:
        return np.full(len(receivers), -1, dtype=np.intp)
    d = pos[receivers][:, None, :] - pos[leader_rows]
    d *= d
    return leader_rows[(d[..., 0] + d[..., 1]).argmin(axis=1)]


#: above this many agents, laws that couple only within w sum over a neighbour list
DENSE_LIMIT = 64


def sparse_coupling(n: int, law, lambda_: float) -> bool:
    """Whether u is summed over neighbours within w (np.bincount) rather than densely over the
    whole table.  The batch engine and the agent node both decide with this function, so
    they add the same terms in the same order."""
    return n > DENSE_LIMIT and not law.couples_globally(lambda_)


def neighbour_pairs(pos, radius):
    """(k, j) pairs with |r_k − r_j| ≤ radius, both directions, sorted by (k, j): a KD-tree
    neighbour search (not all pairs), for laws that couple only within w."""
    from scipy.spatial import cKDTree  # the batch engine's only: no agent process pays for it
    n = len(pos)
    ij = cKDTree(pos).query_pairs(radius, output_type='ndarray')
    if ij.size == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    # one sort of the keys k·n + j (both directions) orders the pairs by (k, j)
    ij = ij.astype(np.intp, copy=False)
    key = np.empty(2 * len(ij), dtype=np.intp)
    np.multiply(ij[:, 0], n, out=key[:len(ij)])
    key[:len(ij)] += ij[:, 1]
    np.multiply(ij[:, 1], n, out=key[len(ij):])
    key[len(ij):] += ij[:, 0]
    key.sort()
    k = key // n
    return k, key - k * n


#: row block of the dense path: about this many pair entries per block (the block's scratch
#: arrays stay in the L2 cache)
DENSE_BLOCK = 8192


class _Block:
    """Scratch arrays of one row block of the dense path (b rows of n pairs) and named views of
    them, made once: at n = 6 the cost of a step is numpy's per-call overhead, so the loop body
    makes only same-shape calls on ready views (a broadcast call costs several plain ones)."""

    __slots__ = ('d', 'dx', 'dy', 'd2', 'd2x', 'd2y', 'rr', 'h', 'wm', 'wb', 'mom', 'A', 'B',
                 'Hx', 'Hy', 'C', 'S', 'consts', 'd_flat', 'cs_flat')

    def __init__(self, d, d2, rr, h, wm, wb, mom):
        self.d, self.dx, self.dy = d, d[0], d[1]               # r_jk = (dx, dy)
        self.d2, self.d2x, self.d2y = d2, d2[0], d2[1]         # dx², dy² (then work space)
        self.rr, self.h, self.wm, self.wb = rr, h, wm, wb      # ρ² → 1/ρ², h, weights, ρ < w
        self.mom = mom                                          # the six moments' terms
        self.A, self.B, self.Hx, self.Hy, self.C, self.S = mom
        self.consts = {}
        self.d_flat = self.cs_flat = None                       # (2, rows·n) views, whole blocks

    def const(self, value: float):
        """A (rows, n) array filled with ``value`` (numpy's call with a Python number and out=
        costs about three times one with two arrays)."""
        a = self.consts.get(value)
        if a is None:
            if len(self.consts) >= 16:
                self.consts.clear()
            a = self.consts[value] = np.full(self.rr.shape, value)
            a.flags.writeable = False
        return a

    @classmethod
    def new(cls, rows: int, n: int):
        block = cls(np.empty((2, rows, n)), np.empty((2, rows, n)), np.empty((rows, n)),
                    np.empty((rows, n)), np.empty((rows, n)), np.empty((rows, n), dtype=bool),
                    np.empty((6, rows, n)))
        block.d_flat = block.d.view()
        block.d_flat.shape = (2, rows * n)                      # a view, never a copy
        block.cs_flat = block.mom[4:6].view()
        block.cs_flat.shape = (2, rows * n)
        return block

    def head(self, b: int):
        """The same views on the first b rows (a partial last block)."""
        return _Block(self.d[:, :b], self.d2[:, :b], self.rr[:b], self.h[:b], self.wm[:b],
                      self.wb[:b], self.mom[:, :b])


class _Scratch(threading.local):
    """Per-thread scratch blocks of the dense path, kept from call to call (no allocation per
    step; an agent node and the batch engine each keep their own shape)."""

    def __init__(self):
        self.blocks = {}

    def get(self, rows: int, n: int) -> _Block:
        key = (rows, n)
        block = self.blocks.get(key)
        if block is None:
            if len(self.blocks) >= 4:
                self.blocks.clear()
            block = self.blocks[key] = _Block.new(rows, n)
        return block


_scratch = _Scratch()


@functools.lru_cache(maxsize=8)
def _row_starts(rows: int, n: int):
    """0, n, 2n, …: flat index of the first entry of each row of a (rows, n) block."""
    starts = np.arange(0, rows * n, n)
    starts.flags.writeable = False
    return starts


#: at most this many pairs: the dense path gathers r_j and the frames of the senders with
#: take() (cheaper than numpy's broadcasting machinery on tiny arrays)
GATHER_LIMIT = 512


@functools.lru_cache(maxsize=8)
def _gather_rows(n: int, receivers: bytes):
    """Of a gathered block of the receivers (intp bytes; an agent node or the batch asks for the
    same every step): the receiver row k and the sender row j of each entry, and the flat
    index of each self pair (k, k)."""
    k = np.frombuffer(receivers, dtype=np.intp)
    rows, senders = k.repeat(n), np.tile(np.arange(n), k.size)
    self_pair = k + _row_starts(k.size, n)
    rows.flags.writeable = senders.flags.writeable = self_pair.flags.writeable = False
    return rows, senders, self_pair


def _pair_weights(law, lam, q0, leaders, recv_leader, careful):
    """The weights of eq. 8, 13, 14, or None where every weight is 1 (then no weight matrix is
    built): (far, gain, leader rows) with far the weight q of c(ρ, q, w) beyond w (a number, or
    (K, 1) per receiver) and, for leader laws, gain (K,) the factor of the pair with the
    nearest leader l(k), (ℓc − 1)λ + 1 for a follower and 1 for a leader."""
    if leaders is None:
        far = q0 * (1.0 - lam)
        if far == 1.0 and not careful:
            return None
        return far, None, None
    if q0 == 1.0 and lam == 0.0 and not careful:
        return None                     # every cutoff weight and the leader gain are 1
    if recv_leader.size == 1:           # one receiver (an agent node): plain numbers
        if recv_leader[0]:
            return q0, 1.0, leaders.nonzero()[0]
        return q0 * (1.0 - lam), (law.leader_gain - 1.0) * lam + 1.0, leaders.nonzero()[0]
    # (far, gain) of a follower and of a leader, picked per receiver (exact copies)
    far_gain = np.array(((q0 * (1.0 - lam), (law.leader_gain - 1.0) * lam + 1.0), (q0, 1.0)))
    far_gain = far_gain.take(recv_leader.astype(np.intp), axis=0)
    return far_gain[:, :1], far_gain[:, 1], leaders.nonzero()[0]


@dataclass(frozen=True)
class _Terms:
    """What a dense call forms, in place of mode flags (one instance per combination: `_terms`)."""
    target: bool      # eq. 15: only (Hx, Hy), from h within w (·1/ρ if target_normalised)
    weighted: bool    # the weights W_jk of eq. 8, 13, 14 (else every W_jk = 1)
    leader: bool      # W with the gain (ℓc − 1)λ + 1 on the pair with the nearest leader (eq. 13)
    gather: bool      # one small block, its operands gathered with take() (`_DenseLayout`)
    careful: bool     # coincident pairs (ρ = 0, j ≠ k) get W = 0, else their rows are redone
    frames: bool      # C, S formed per row (weighted or gathered), else table sums (`_combine`)
    look: bool        # ρ = 0 looked for before dividing (gathered or careful), else rows after


@functools.lru_cache(maxsize=None)
def _terms(target: bool, weighted: bool, leader: bool, gather: bool, careful: bool) -> _Terms:
    return _Terms(target, weighted, leader, gather, careful, weighted or gather, gather or careful)


class _DenseLayout:
    """The receivers' rows in blocks of about DENSE_BLOCK pairs over the whole table.  At n = 6
    the cost is numpy's per-call overhead, not arithmetic: one small block (at most
    GATHER_LIMIT pairs) gathers r_k, r_j (and the senders' frames, into C, S) with take()
    instead of broadcasting, and ``const`` makes numbers constant arrays."""

    __slots__ = ('n', 'n_recv', 'block', 'full', 'gather', 'xy_recv', 'xy_table', 'self_pair',
                 'const', 'table_cos', 'table_sin')

    def __init__(self, pos, cos_sin, receivers, gather_frames: bool):
        self.n, self.n_recv = n, n_recv = pos.shape[0], receivers.size
        self.block = block = min(n_recv, max(1, DENSE_BLOCK // max(1, n)))
        self.full = full = _scratch.get(block, n)
        self.gather = gather = block == n_recv and n_recv * n <= GATHER_LIMIT
        xy = pos.T                                              # (2, N): x and y rows
        if gather:                                              # r_k, r_j: (2, K·N)
            recv_rows, senders, self.self_pair = _gather_rows(n, receivers.tobytes())
            self.xy_recv, self.xy_table = xy.take(recv_rows, axis=1), xy.take(senders, axis=1)
            if gather_frames:                                   # cos θ_j, sin θ_j (weighted later)
                cos_sin.take(senders, axis=1, out=full.cs_flat)
        else:                                                   # r_k (2, K, 1), r_j (2, 1, N)
            self.xy_recv, self.xy_table = xy.take(receivers, axis=1)[:, :, None], xy[:, None, :]
            self.table_cos, self.table_sin = cos_sin[:, None, :]   # cos θ_j, sin θ_j: (1, N)
            self.self_pair = receivers + _row_starts(n_recv, n)  # flat index of (k, k) in a block
        self.const = full.const if gather else float


def _pair_sums_dense(pos, cos_sin, receivers, law, lam, q0, leaders, recv_leader, careful=False):
    """Per-receiver moments (6, K) over the whole table, in blocks of receiver rows, from which
    `_combine` forms Σ_j W_jk u_jk: eq. 4-5 with the weights of eq. 8, 13, 14 (or eq. 15).

    u_jk (eq. 5) is linear in pair moments whose coefficients depend only on the receiver's
    frame (c, s) = (cos θ_k, sin θ_k).  With r_jk = (dx, dy), (r_jk·x_k)(r_jk·y_k) =
    (c² − s²)·dx·dy + c·s·(dy² − dx²) and r_jk·y_k = c·dy − s·dx, so

        Σ_j W_jk u_jk = −η[(c² − s²)·A + c·s·B] + (c·Hy − s·Hx) + μ(c·S − s·C)

    A = Σ W dx dy/ρ², B = Σ W (dy² − dx²)/ρ², (Hx, Hy) = Σ W h·(dx, dy), h = −α(1 − r0²/ρ²)/ρ,
    C = Σ W cos θ_j, S = Σ W sin θ_j: the result's rows.  The self pair adds 0 (its ρ² is set
    to ∞) but to C, S, where its alignment c·s_k − s·c_k cancels.  Each moment is numpy's
    reduction of one contiguous row, whatever a block holds, so one receiver alone (an agent
    node) gets the batch value bit for bit.  cos_sin (2, N): the table's cos θ, sin θ.
    Returns (moments, whether the C, S rows are formed, redo: None or the receiver positions
    with a coincident pair (ρ = 0, j ≠ k), for the caller to redo with ``careful``).
    """
    sums = np.empty((6, receivers.size))
    target = law.avoidance_only
    weights = None if target else _pair_weights(law, lam, q0, leaders, recv_leader, careful)
    if receivers.size == 0:
        return sums, weights is not None, None
    lay = _DenseLayout(pos, cos_sin, receivers, gather_frames=not target)
    terms = _terms(target, weights is not None, weights is not None and weights[1] is not None,
                   lay.gather, careful)
    if terms.look:                  # each block looks for ρ = 0 before dividing
        return sums, terms.frames, _sum_blocks(lay, terms, law, weights, sums)
    with np.errstate(divide='ignore', invalid='ignore'):
        _sum_blocks(lay, terms, law, weights, sums)
    moments = sums[2:4] if target else sums[:4]     # large blocks divide anyway: redo the rows
    if math.isfinite(np.add.reduce(moments, axis=None)):          # that are not finite
        return sums, terms.frames, None
    return sums, terms.frames, np.flatnonzero(~np.isfinite(moments).all(axis=0))


def _sum_blocks(lay, terms, law, weights, sums):
    """`_block_moments` of every block; returns the positions of rows with a coincident pair
    (None if there is none)."""
    redo = None
    for a in range(0, lay.n_recv, lay.block):
        bad = _block_moments(lay, terms, law, weights, a, sums)
        if bad is not None:
            redo = bad if redo is None else np.concatenate((redo, bad))
    return redo


def _block_moments(lay, terms, law, weights, a, sums):
    """The moments of the receivers a … a + b − 1 (one block) into sums; returns the positions
    of rows with a coincident pair (to redo), or None."""
    b = min(lay.block, lay.n_recv - a)
    z = lay.full if b == lay.block else lay.full.head(b)
    rows = None if b == lay.n_recv else slice(a, a + b)     # None: every receiver, one block
    rr, h, const, g = z.rr, z.h, lay.const, law
    _block_geometry(lay, z, a, rows)
    leader_pairs = coincident = bad = None
    if terms.leader:
        leader_pairs = _nearest_leader_pairs(rr, weights[2], _row_starts(b, lay.n))
    if terms.target or terms.weighted:
        np.less(rr, const(law.cutoff_radius * law.cutoff_radius), out=z.wb)  # ρ < w
    if terms.look and np.count_nonzero(rr) != rr.size:         # a coincident pair
        coincident, bad = _coincident_pairs(rr, a, terms.careful)
    np.reciprocal(rr, out=rr)                                   # 1/ρ²
    np.multiply(rr, const(g.alpha * g.r0 * g.r0), out=h)
    np.subtract(h, const(g.alpha), out=h)                       # −α(1 − r0²/ρ²), eq. 5-6
    if terms.target:                                            # eq. 15: h·r_jk within w
        if law.target_normalised:
            np.multiply(h, np.sqrt(rr, out=z.d2x), out=h)       # unit vectors: h/ρ
        np.multiply(h, z.wb, out=h)
        np.multiply(z.dx, h, out=z.Hx)
        np.multiply(z.dy, h, out=z.Hy)
        np.add.reduce(z.mom[2:4], axis=2, out=sums[2:4] if rows is None else sums[2:4, rows])
        return bad
    np.subtract(z.d2y, z.d2x, out=z.B)                          # dy² − dx²
    np.multiply(h, np.sqrt(rr, out=z.d2x), out=h)               # h = −α(1 − r0²/ρ²)/ρ
    if terms.weighted:
        _weigh(z, lay, terms, weights, rows, leader_pairs, coincident)
    np.multiply(z.dx, z.dy, out=z.A)
    np.multiply(z.A, rr, out=z.A)
    np.multiply(z.B, rr, out=z.B)
    np.multiply(z.dx, h, out=z.Hx)
    np.multiply(z.dy, h, out=z.Hy)
    mom, out = (z.mom, sums) if terms.frames else (z.mom[:4], sums[:4])
    np.add.reduce(mom, axis=2, out=out if rows is None else out[:, rows])
    return bad


def _block_geometry(lay, z, a, rows):
    """r_jk = r_k − r_j, dx², dy² and ρ² of a block's pairs; the self pair's ρ² is ∞."""
    if lay.gather:
        np.subtract(lay.xy_recv, lay.xy_table, out=z.d_flat)
    else:
        np.subtract(lay.xy_recv if rows is None else lay.xy_recv[:, rows], lay.xy_table, out=z.d)
    np.multiply(z.d, z.d, out=z.d2)
    np.add(z.d2x, z.d2y, out=z.rr)                              # ρ²
    z.rr.put(lay.self_pair if rows is None else lay.self_pair[rows] - a * lay.n, np.inf)


def _nearest_leader_pairs(rr, leader_rows, starts):
    """Flat index in the block of each receiver's pair with its nearest leader l(k) (eq. 10),
    read off ρ² (as `nearest_leader` finds it; ties to the lower row)."""
    flat = leader_rows.take(rr.take(leader_rows, axis=1).argmin(axis=1))
    flat += starts                                              # 0, n, 2n, …
    return flat


def _coincident_pairs(rr, a, careful):
    """(mask, rows to redo) of a block's coincident pairs (ρ = 0, j ≠ k), looked for before
    dividing, their ρ² set to ∞; no rows to redo in a careful pass (`_weigh` gives them W = 0)."""
    coincident = rr == 0.0
    rr[coincident] = np.inf
    return coincident, None if careful else a + np.flatnonzero(coincident.any(axis=1))


def _weigh(z, lay, terms, weights, rows, leader_pairs, coincident):
    """1/ρ², h and the C, S terms of a block times W_jk: c(ρ, q, w) (eq. 8) with q beyond w,
    the leader gain on the pair (k, l(k)) (eq. 13), 0 on coincident pairs of a careful pass."""
    far, gain, _ = weights
    wm = z.wm
    if gain is None:                                            # one q for every receiver
        np.copyto(wm, lay.const(far))
    else:                                                       # q per receiver: a number, or (K, 1)
        np.copyto(wm, far if rows is None else far[rows])
    np.copyto(wm, lay.const(1.0), where=z.wb)                   # c(ρ, q, w), eq. 8
    if terms.leader:                                            # (ℓc − 1)λ + 1 with l(k), eq. 13
        wm.put(leader_pairs, wm.take(leader_pairs) * (gain if rows is None else gain[rows]))
    if coincident is not None and terms.careful:
        wm[coincident] = 0.0
    np.multiply(z.rr, wm, out=z.rr)
    np.multiply(z.h, wm, out=z.h)
    if lay.gather:                                              # the senders' frames are in C, S
        np.multiply(z.C, wm, out=z.C)
        np.multiply(z.S, wm, out=z.S)
    else:
        np.multiply(wm, lay.table_cos, out=z.C)
        np.multiply(wm, lay.table_sin, out=z.S)


def _combine(m, weighted, F, cos_sin, law):
    """Σ_j W_jk u_jk of each receiver from its moments m (6, K) (see `_pair_sums_dense`);
    F (2, K): the receivers' (sin θ_k, cos θ_k); cos_sin (2, N): the table's (cos θ, sin θ)."""
    if law.avoidance_only:
        p = m[2:4] * F                                           # s·Hx, c·Hy
        return p[1] - p[0]
    g = law
    if weighted:
        y = m[4:6] * g.mu                                        # μC, μS
        y += m[2:4]
    else:
        y = m[2:4] + (np.add.reduce(cos_sin, axis=1) * g.mu)[:, None]
    y *= F                                                       # s(Hx + μC), c(Hy + μS)
    q = F * F                                                    # s², c²
    np.subtract(q[1], q[0], out=q[0])                            # c² − s²
    np.multiply(F[1], F[0], out=q[1])                            # c·s
    q *= m[0:2]
    base = (q[0] + q[1]) * g.eta
    u = y[1] - y[0]                                              # c(Hy + μS) − s(Hx + μC)
    u -= base
    return u


def _pair_sums_sparse(pos, cos_t, sin_t, receivers, law, lam, q0, leaders, l_of_k, k, j, careful=False):
    """The moments of `_pair_sums_dense` over a pair list (receiver position k, sender row j)
    instead of the whole table, each summed with np.bincount in pair order."""
    n_recv = receivers.size
    g = law
    rk = receivers[k]
    x, y = pos.T.copy()
    dx = x[rk]
    dx -= x[j]
    dy = y[rk]
    dy -= y[j]
    dx2 = dx * dx
    dy2 = dy * dy
    rr = dx2 + dy2                                              # ρ²
    within = rr < law.cutoff_radius * law.cutoff_radius
    if careful:
        coincident = rr == 0.0
        rr[coincident] = np.inf
    np.divide(1.0, rr, out=rr)                                  # 1/ρ²
    h = rr * (g.alpha * g.r0 * g.r0)
    h -= g.alpha                                                # −α(1 − r0²/ρ²)
    m = np.empty((6, n_recv))
    if law.avoidance_only:
        if law.target_normalised:
            h *= np.sqrt(rr)
        h *= within
        m[2] = np.bincount(k, weights=h * dx, minlength=n_recv)
        m[3] = np.bincount(k, weights=h * dy, minlength=n_recv)
        return m, False
    h *= np.sqrt(rr)                                            # h = −α(1 − r0²/ρ²)/ρ
    # c(ρ, q, w) with q = q0(1 − λ) (followers, none) or q0 (leaders), eq. 8, 13, 14
    if q0 == 0.0:
        weight = within.astype(float)
    elif leaders is None:
        weight = np.where(within, 1.0, q0 * (1.0 - lam))
    else:
        weight = np.where(within, 1.0, np.where(leaders[rk], q0, q0 * (1.0 - lam)))
    if leaders is not None:                                     # (ℓc − 1)λ + 1 with l(k), eq. 13
        partner = np.where(leaders[receivers], -1, l_of_k)
        weight[(j == partner[k]).nonzero()[0]] *= (law.leader_gain - 1.0) * lam + 1.0
    if careful:
        weight[coincident] = 0.0
    rr *= weight
    h *= weight
    np.subtract(dy2, dx2, out=dx2)
    dx2 *= rr
    np.multiply(dx, dy, out=dy2)
    dy2 *= rr
    dx *= h
    dy *= h
    for i, w in enumerate((dy2, dx2, dx, dy)):
        m[i] = np.bincount(k, weights=w, minlength=n_recv)
    for i, t in ((4, cos_t), (5, sin_t)):
        w = t[j]
        w *= weight
        m[i] = np.bincount(k, weights=w, minlength=n_recv)
    return m, True


def _pair_sum_sparse(pos, cos_sin, F, receivers, law, lam, q0, leaders, pairs, nearest=None):
    """Σ_j weight_jk·u_jk of each receiver over a pair list; a row with coincident agents
    (non-finite in the fast form) is redone with explicit masks.  nearest: l(k) of each
    receiver (default: `nearest_leader` on the table)."""
    cos_t, sin_t = cos_sin
    l_of_k = None
    if leaders is not None:
        l_of_k = nearest_leader(pos, receivers, leaders.nonzero()[0]) if nearest is None else nearest
    with np.errstate(divide='ignore', invalid='ignore'):
        m, weighted = _pair_sums_sparse(pos, cos_t, sin_t, receivers, law, lam, q0, leaders,
                                        l_of_k, *pairs)
        sums = _combine(m, weighted, F, cos_sin, law)
    if not math.isfinite(np.add.reduce(sums)):
        idx = np.flatnonzero(~np.isfinite(sums))
        lk = None if l_of_k is None else l_of_k[idx]
        keep = np.isin(pairs[0], idx)
        k_sub = np.searchsorted(idx, pairs[0][keep])
        m, weighted = _pair_sums_sparse(pos, cos_t, sin_t, receivers[idx], law, lam, q0, leaders,
                                        lk, k_sub, pairs[1][keep], careful=True)
        sums[idx] = _combine(m, weighted, F[:, idx], cos_sin, law)
    return sums
