"""The control laws of Morgan & Schwartz as `Law`s (no ROS), written once.

One general form, the homotopy law (eq. 12-14), with the far-coupling weight q(λ) = q0 (1 − λ):

- `Global`           ``global``            eq. 4,  u_k = Σ_j u_jk               (λ = 0, q0 = 1)
- `Local`            ``local``             eq. 9,  u_k = Σ_j c(ρ_jk, 0, w) u_jk  (λ = 0, q0 = 0)
- `LeaderFollowing`  ``leader_following``  eq. 10-11                          (λ = 1, q0 = 0)
- `Homotopy`         ``homotopy``          eq. 12-14
- `Target`           ``target``            eq. 15, collision avoidance within w plus target seeking

Every one adds the target term (eq. 15, second line) when a target and a nonzero
``target_gain`` are given, and the sensed-barrier term (eq. 16, `terms`) whenever a barrier
and a nonzero ``barrier_gain`` are given.  The pair sums (`pair_sums`: dense row sums or a
neighbour list, bit-identical; `compiled_sums` for large swarms, to rounding) give every term
but the leader, target and barrier terms, added here.  The same inputs in the same mode give
bit-identical results whatever the receivers are, which is what makes an agent node's u equal
the batch engine's.
"""
from __future__ import annotations

import numpy as np

from swarm_core.laws.base import Law, LawError, param
from swarm_core.laws.paper import compiled_sums
from swarm_core.laws.paper.natural_sums import natural_controls
from swarm_core.laws.paper.pair_sums import (
    DENSE_LIMIT,
    _combine,
    _pair_sum_sparse,
    _pair_sums_dense,
    nearest_leader,
    neighbour_pairs,
    sparse_coupling,
)
from swarm_core.laws.paper.parameters import LAW_TABLE
from swarm_core.laws.paper.terms import add_world_terms

#: the parameters a ``law:`` section sets (the others are the target: and barrier: sections')
LAW_KEYS = tuple(p.name for p in LAW_TABLE if p.section == 'law' and p.name != 'law')
#: the parameters the ``target:`` and ``barrier:`` sections set (`with_world`)
WORLD_KEYS = tuple(p.name for p in LAW_TABLE if p.section != 'law')


def _param(p) -> param:
    """The `param` of a `LAW_TABLE` row."""
    if p.bound is not None:
        return param(p.default, lo=p.bound.lo, hi=p.bound.hi, doc=p.description)
    return param(p.default, doc=p.description, choices=p.choices)


class PaperLaw(Law):
    """The paper's law in its general form (eq. 4-16); each kind fixes its λ and q0."""

    #: eq. 15: the pair term is only collision avoidance within w (the target law)
    avoidance_only = False
    #: the law's code in the compiled whole run (`fast_run`); -1: none
    kernel_code = -1
    #: planar, and lifted to 3D (`natural_sums`)
    dims = (2, 3)

    @classmethod
    def param_specs(cls) -> dict[str, param]:
        return _PARAMS

    def effective_lambda_q0(self, lambda_: float) -> tuple[float, float]:
        """(λ, q0) at which the general homotopy form reproduces this law."""
        return float(lambda_), float(self.q0)

    def couples_globally(self, lambda_: float) -> bool:
        """Whether pairs beyond w can carry weight (q(λ) > 0 or leaders with q0 > 0)."""
        return self.effective_lambda_q0(lambda_)[1] > 0.0

    def evaluate(self, pos, cos_t, sin_t, receivers, *, lambda_=0.0, is_leader=None, steering=None,
                 target=None, barrier=None, pairs=None, nearest=None, t=None):
        """u_k of the receivers (eq. 4, 9, 10-14, 15, 16).

        pos (N, 2), cos_t, sin_t (N,): the table of agent states.  receivers (K,): table rows
        of the agents whose control is wanted.  is_leader (N,) bool: leader flags (read by the
        leader laws); steering (K,): s_k of each receiver (read where it is a leader).  target
        (2,), barrier (m, 2): world geometry, or None.  pairs (`pair_list`): None sums over the
        whole table, densely in blocks of rows; `compiled_sums.COMPILED` in compiled kernels on
        every core; or (receiver position, sender row) arrays, summed in that order with
        np.bincount (pairs beyond w may be left out only where they carry weight 0).  nearest
        (K,): with pairs, each receiver's nearest leader l(k) as a table row (−1: none), where
        the table is not one shared view of the swarm (a radio's beliefs); default
        `pair_sums.nearest_leader`.  t is not read."""
        pos = np.asarray(pos, dtype=float)
        receivers = np.asarray(receivers, dtype=np.intp)
        lam, q0 = self.effective_lambda_q0(lambda_)
        leaders = recv_leader = None
        if self.uses_leaders and is_leader is not None:
            is_leader = np.asarray(is_leader, dtype=bool)
            if np.count_nonzero(is_leader):
                leaders = is_leader
                recv_leader = leaders[receivers]
        frames = np.array((cos_t, sin_t, cos_t), dtype=float)
        cos_sin = frames[:2]                                        # (2, N): the table's cos θ, sin θ
        F = frames[1:].take(receivers, axis=1)                      # (2, K): the receivers' sin θ, cos θ

        if pairs is None:               # densely over the table; rows with coincident agents redone
            m, has_cs, redo = _pair_sums_dense(pos, cos_sin, receivers, self, lam, q0, leaders, recv_leader)
            sums = _combine(m, has_cs, F, cos_sin, self)
            if redo is not None:
                m, has_cs, _ = _pair_sums_dense(pos, cos_sin, receivers[redo], self, lam, q0, leaders,
                                                None if recv_leader is None else recv_leader[redo],
                                                careful=True)
                sums[redo] = _combine(m, has_cs, F[:, redo], cos_sin, self)
        elif isinstance(pairs, str):    # large swarms: compiled, to rounding
            sums = self._compiled_sums(pos, cos_sin, F, receivers, lam, q0, leaders)
        else:
            sums = _pair_sum_sparse(pos, cos_sin, F, receivers, self, lam, q0, leaders, pairs, nearest)

        if leaders is not None:
            s = np.zeros(receivers.size) if steering is None else np.asarray(steering, dtype=float)
            u = np.where(recv_leader, (1.0 - lam) * sums + lam * s, sums)
        else:
            u = sums
        return add_world_terms(u, pos, F, receivers, self, target, barrier)

    def evaluate_natural(self, pos, frames, receivers, *, lambda_=0.0, is_leader=None, steering=None,
                         target=None, barrier=None, ground=None, t=None, sums='auto', **unused):
        """(u_k, v_k) (K, 2) of the receivers in 3D: the paper's law lifted (`natural_sums`).
        pos (N, 3), frames (x, y, z) (N, 3) each, steering (K, 2), target (3,), barrier (m, 3),
        ground: the floor's height or None.  sums: 'compiled' or 'numpy' (a run's
        `compiled_sums.run_sums`), or 'auto': compiled from `compiled_sums.COMPILED_LIMIT`
        agents on (`natural_compiled.use_compiled`).  t is not read."""
        pos = np.asarray(pos, dtype=float)
        receivers = np.asarray(receivers, dtype=np.intp)
        lam, q0 = self.effective_lambda_q0(lambda_)
        leaders = None
        if self.uses_leaders and is_leader is not None and np.count_nonzero(is_leader):
            leaders = np.asarray(is_leader, dtype=bool)
        frames = tuple(np.asarray(f, dtype=float) for f in frames)
        return natural_controls(self, pos, frames, receivers, lam, q0, leaders, steering, target, barrier, ground,
                                sums)

    def _compiled_sums(self, pos, cos_sin, F, receivers, lam, q0, leaders):
        """Σ_j W_jk u_jk of the receivers from `compiled_sums.compiled_moments` (their rows
        only; numba is imported on first use only)."""
        l_of_k = None if leaders is None else nearest_leader(pos, receivers, leaders.nonzero()[0])
        m = compiled_sums.compiled_moments(pos, cos_sin[0], cos_sin[1], receivers, self, lam, q0, leaders, l_of_k)
        return _combine(m, True, F, cos_sin, self)

    def pair_list(self, pos, lambda_: float, search: str = 'auto'):
        """The compiled kernels where search is compiled, or auto from
        `compiled_sums.COMPILED_LIMIT` agents on (numba installed); the whole table where pairs
        beyond w carry weight, where search is all, or (auto, numpy) at most
        `pair_sums.DENSE_LIMIT` agents; else the KD-tree pairs within w.  numpy is auto without
        the compiled kernels (a run's `compiled_sums.run_sums` chose them off)."""
        n = len(pos)
        if search == 'compiled' or search == 'auto' and n >= compiled_sums.COMPILED_LIMIT and \
                compiled_sums.available():
            return compiled_sums.COMPILED
        if search == 'numpy':
            search = 'auto'
        if search == 'all' or self.couples_globally(lambda_):
            return None
        if search == 'auto' and (n <= DENSE_LIMIT or not sparse_coupling(n, self, lambda_)):
            return None
        return neighbour_pairs(pos, self.cutoff_radius)

    @classmethod
    def compiled_run(cls):
        """`fast_run`: the whole run in compiled code (numba, imported here, on first use)."""
        from swarm_core.laws.paper import fast_run
        return fast_run

    def believed_controls(self, pos, cos_t, sin_t, a, m, *, lambda_, is_leader, steering, target, barrier,
                          nearest, t) -> np.ndarray:
        """One call over the believed pair list (np.bincount, each receiver's senders in index
        order): a receiver's sum is its own whichever receivers are asked with it."""
        return self.evaluate(pos, cos_t, sin_t, np.arange(m), lambda_=lambda_, is_leader=is_leader, steering=steering,
                             target=target, barrier=barrier, pairs=(a, m + np.arange(a.size)), nearest=nearest, t=t)

    def with_world(self, world: dict) -> PaperLaw:
        return self.with_parameters(**{k: world[k] for k in WORLD_KEYS})

    def mapping(self) -> dict:
        return {'kind': self.kind, **{k: getattr(self, k) for k in LAW_KEYS}}

    @classmethod
    def from_mapping(cls, values: dict, base_dir=None, where: str = 'law') -> PaperLaw:
        """The law of a ``law:`` mapping ({alpha, ...}), each value checked against `LAW_TABLE`
        (the target and barrier terms are their sections' and stay off here)."""
        for key, v in values.items():
            p = _PARAMS.get(key)
            if p is None or key not in LAW_KEYS:
                raise LawError(f'{where}: unknown parameter {key!r} of the paper\'s law '
                               f'(known: kind, {", ".join(LAW_KEYS)})')
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not p.lo <= float(v) <= p.hi:
                raise LawError(f'{where}: {key} = {v!r} is outside [{p.lo:g}, {p.hi:g}]')
        return cls(**{k: float(v) for k, v in values.items()})


_PARAMS = {p.name: _param(p) for p in LAW_TABLE if p.name != 'law'}


class Global(PaperLaw):
    """Global coupling of every pair (eq. 4)."""

    kind = 'global'
    kernel_code = 0

    def effective_lambda_q0(self, lambda_):
        return 0.0, 1.0


class Local(PaperLaw):
    """Local coupling: pairs within w only (eq. 9)."""

    kind = 'local'
    kernel_code = 1

    def effective_lambda_q0(self, lambda_):
        return 0.0, 0.0


class LeaderFollowing(PaperLaw):
    """Each follower follows its nearest leader, local coupling within w (eq. 10-11)."""

    kind = 'leader_following'
    kernel_code = 2
    uses_leaders = True

    def effective_lambda_q0(self, lambda_):
        return 1.0, 0.0


class Homotopy(PaperLaw):
    """λ from one swarm (0) to subswarms that follow their leaders (1) (eq. 12-14)."""

    kind = 'homotopy'
    kernel_code = 3
    uses_leaders = True


class Target(PaperLaw):
    """Collision avoidance within w plus target seeking (eq. 15)."""

    kind = 'target'
    kernel_code = 4
    avoidance_only = True

    def effective_lambda_q0(self, lambda_):
        return 0.0, 0.0


#: the paper's laws by kind
PAPER_LAWS = {cls.kind: cls for cls in (Global, Local, LeaderFollowing, Homotopy, Target)}
