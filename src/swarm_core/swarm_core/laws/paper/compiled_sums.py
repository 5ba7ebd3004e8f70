"""Pair sums of large swarms, compiled (numba) and on every core (no ROS).

The moments (A, B, Hx, Hy, C, S) of `paper.pair_sums._pair_sums_sparse`, one receiver per
iteration of a ``prange`` loop (the receivers are shared among the cores): over every other
agent where pairs beyond w carry weight (eq. 4, 8, 13-14 with q > 0), or over the agents of
the 3 × 3 cells of side w around the receiver (a cell list; eq. 9-11, 15), where only pairs
within w do.  The same terms as the reference, summed in another order: the results equal
the reference to rounding (the tests ask for 1e-9), not bit for bit.  The self pair is left
out (its alignment term c·s_k − s·c_k is 0 up to rounding), and so are coincident pairs
(weight 0, as in the reference's careful pass).

Chosen by the paper's law for the batch engine from COMPILED_LIMIT agents on
(`PaperLaw.pair_list` gives ``pairs=COMPILED``); ROS lockstep runs are smaller, so they keep the reference, and numba is
imported here only, on first use: no agent process pays for it.
"""
from __future__ import annotations

import importlib.util

import numpy as np

#: from this many receivers on, the batch engine sums pairs with the compiled kernels
COMPILED_LIMIT = 4096
#: what `PaperLaw.evaluate` takes as ``pairs`` for the compiled kernels
COMPILED = 'compiled'


def available() -> bool:
    """Whether numba is installed (without it the reference runs); looked up, not imported."""
    return importlib.util.find_spec('numba') is not None


def compiled_moments(pos, cos_t, sin_t, law, lam, q0, leaders, l_of_k):
    """The moments (6, N) of every agent of the table as receiver (see the module doc);
    l_of_k (N,): each receiver's nearest leader row, or None without leaders."""
    from swarm_core.laws.paper.compiled_sums_kernels import all_pairs, cell_pairs
    n = pos.shape[0]
    g = law
    target = law.avoidance_only
    if leaders is None:
        far = np.full(n, 0.0 if target else q0 * (1.0 - lam))
        partner = np.full(n, -1, dtype=np.int64)
        gain = np.ones(n)
    else:                           # q0 beyond w for leaders, q0(1 − λ) for followers (eq. 13)
        far = np.where(leaders, q0, q0 * (1.0 - lam))
        partner = np.where(leaders, -1, l_of_k).astype(np.int64)
        gain = np.full(n, (law.leader_gain - 1.0) * lam + 1.0)
    x, y = np.ascontiguousarray(pos[:, 0]), np.ascontiguousarray(pos[:, 1])
    args = (np.ascontiguousarray(cos_t, dtype=float), np.ascontiguousarray(sin_t, dtype=float))
    consts = (far, partner, gain, g.alpha, g.alpha * g.r0 * g.r0, target, bool(law.target_normalised))
    if np.any(far != 0.0):
        return all_pairs(x, y, *args, law.cutoff_radius ** 2, *consts)
    return cell_pairs(x, y, *args, float(law.cutoff_radius), *consts)
