"""Pair sums of large swarms, compiled (numba) and on every core (no ROS).

The moments (A, B, Hx, Hy, C, S) of `pair_sums._pair_sums_sparse`, one receiver per
iteration of a ``prange`` loop (the receivers are shared among the cores): over every other
agent where pairs beyond w carry weight (eq. 4, 8, 13-14 with q > 0), or over the agents of
the 3 × 3 cells of side w around the receiver (a cell list; eq. 9-11, 15), where only pairs
within w do.  The same terms as the reference, summed in another order: the results equal
the reference to rounding (the tests ask for 1e-9), not bit for bit.  The self pair is left
out (its alignment term c·s_k − s·c_k is 0 up to rounding), and so are coincident pairs
(weight 0, as in the reference's careful pass).

Used by the batch engine from COMPILED_LIMIT agents on (`laws.swarm_control` with
``pairs=COMPILED``); ROS lockstep runs are smaller, so they keep the reference, and numba is
imported here only, on first use: no agent process pays for it.
"""
from __future__ import annotations

import functools

import numpy as np

#: from this many receivers on, the batch engine sums pairs with the compiled kernels
COMPILED_LIMIT = 4096
#: what `laws.swarm_control` takes as ``pairs`` for the compiled kernels
COMPILED = 'compiled'


def available() -> bool:
    """Whether numba can be imported (it is optional: without it the reference runs)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


@functools.lru_cache(maxsize=None)
def _kernels():
    """The compiled kernels (numba imported and the code compiled on first call; cached on
    disk, so later processes load it)."""
    import numba as nb

    # sums may be reassociated (SIMD), products fused; no other fast-math liberty (the self
    # pair and coincident pairs rely on ρ² == 0 being seen)
    fm = {'reassoc', 'contract'}

    @nb.njit(inline='always', fastmath=fm)
    def pair(dx, dy, cj, sj, partner, w2, far, gain, alpha, ar02, target, normalised):
        """The six weighted terms of one pair, branch-free (0 for the self pair and coincident
        pairs: ρ² = 0, as a careful pass of the reference gives them)."""
        rr = dx * dx + dy * dy
        weight = 1.0 if rr < w2 else far
        weight = weight * gain if partner else weight
        weight = 0.0 if rr == 0.0 else weight
        inv = 1.0 / (1.0 if rr == 0.0 else rr)
        h = inv * ar02 - alpha
        hn = h * np.sqrt(inv)
        h = (h if not normalised else hn) if target else hn
        inv *= weight
        h *= weight
        if target:                                      # eq. 15: h·r_jk within w only
            return 0.0, 0.0, h * dx, h * dy, 0.0, 0.0
        return dx * dy * inv, (dy * dy - dx * dx) * inv, dx * h, dy * h, cj * weight, sj * weight

    @nb.njit(parallel=True, cache=True, fastmath=fm)
    def all_pairs(x, y, cos_t, sin_t, w2, far, partner, gain, alpha, ar02, target, normalised):
        n = x.size
        m = np.empty((6, n))
        for k in nb.prange(n):
            a = b = hx = hy = c = s = 0.0
            xk, yk, fk, pk, gk = x[k], y[k], far[k], partner[k], gain[k]
            for j in range(n):
                t = pair(xk - x[j], yk - y[j], cos_t[j], sin_t[j], j == pk, w2, fk, gk, alpha, ar02,
                         target, normalised)
                a += t[0]
                b += t[1]
                hx += t[2]
                hy += t[3]
                c += t[4]
                s += t[5]
            m[0, k], m[1, k], m[2, k], m[3, k], m[4, k], m[5, k] = a, b, hx, hy, c, s
        return m

    @nb.njit(cache=True)
    def cells(x, y, w):
        """A cell list of side w: the agents in cell order, their keys cx·ny + cy (one empty
        cell all round), ny, and the first position of each cell (None: binary search)."""
        cx = np.floor((x - x.min()) / w).astype(np.int64) + 1
        cy = np.floor((y - y.min()) / w).astype(np.int64) + 1
        ny = cy.max() + 2
        key = cx * ny + cy
        order = np.argsort(key, kind='mergesort')
        sorted_key = key[order]
        ncells = (cx.max() + 2) * ny
        start = np.zeros(ncells + 1 if ncells <= 8 * x.size + 64 else 0, dtype=np.int64)
        if start.size:
            for i in range(x.size):
                start[sorted_key[i] + 1] += 1
            start = np.cumsum(start)                    # start[c]: first position of cell c
        return order, sorted_key, ny, start

    @nb.njit(parallel=True, cache=True, fastmath=fm)
    def cell_pairs(x, y, cos_t, sin_t, w, far, partner, gain, alpha, ar02, target, normalised):
        order, sorted_key, ny, start = cells(x, y, w)
        xs, ys, cs, ss = x[order], y[order], cos_t[order], sin_t[order]
        where = np.empty(x.size, dtype=np.int64)
        where[order] = np.arange(x.size)
        m = np.empty((6, x.size))
        for i in nb.prange(x.size):
            k = order[i]
            a = b = hx = hy = c = s = 0.0
            xk, yk, fk, gk = xs[i], ys[i], far[k], gain[k]
            pk = where[partner[k]] if partner[k] >= 0 else -1
            for col in range(-1, 2):                    # cells (cx + col, cy − 1 … cy + 1)
                first = sorted_key[i] + col * ny - 1
                if start.size:
                    lo, hi = start[first], start[first + 3]
                else:
                    lo = np.searchsorted(sorted_key, first)
                    hi = np.searchsorted(sorted_key, first + 3)
                for jj in range(lo, hi):
                    t = pair(xk - xs[jj], yk - ys[jj], cs[jj], ss[jj], jj == pk, w * w, fk, gk, alpha,
                             ar02, target, normalised)
                    a += t[0]
                    b += t[1]
                    hx += t[2]
                    hy += t[3]
                    c += t[4]
                    s += t[5]
            m[0, k], m[1, k], m[2, k], m[3, k], m[4, k], m[5, k] = a, b, hx, hy, c, s
        return m

    return all_pairs, cell_pairs


def compiled_moments(pos, cos_t, sin_t, law, lam, q0, leaders, l_of_k):
    """The moments (6, N) of every agent of the table as receiver (see the module doc);
    l_of_k (N,): each receiver's nearest leader row, or None without leaders."""
    all_pairs, cell_pairs = _kernels()
    n = pos.shape[0]
    g = law.gains
    target = law.kind == 'target'
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
