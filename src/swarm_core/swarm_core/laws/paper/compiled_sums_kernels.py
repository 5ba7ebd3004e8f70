"""The compiled kernels of `paper.compiled_sums` (numba; this module is imported only from there, on
first use, so no agent process pays for numba).  Compiled code is cached on disk
(``cache=True``): later processes load it."""
import numba as nb
import numpy as np

# sums may be reassociated (SIMD), products fused; no other fast-math liberty (the self
# pair and coincident pairs rely on ρ² == 0 being seen)
FASTMATH = {'reassoc', 'contract'}


@nb.njit(inline='always', fastmath=FASTMATH)
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


@nb.njit(inline='always', fastmath=FASTMATH)
def add_moments(acc, t):
    """The six moment sums ``acc`` plus one pair's six terms ``t`` (`pair`), in that order."""
    return acc[0] + t[0], acc[1] + t[1], acc[2] + t[2], acc[3] + t[3], acc[4] + t[4], acc[5] + t[5]


@nb.njit(parallel=True, cache=True, fastmath=FASTMATH)
def all_pairs(x, y, cos_t, sin_t, receivers, w2, far, partner, gain, alpha, ar02, target, normalised):
    """Moments (6, K): each receiver k (a table row; far, partner, gain per receiver) against
    every agent j.  A row's sum is the same whichever receivers are asked with it (one body,
    one order, whatever the threads)."""
    n = x.size
    m = np.empty((6, receivers.size))
    for r in nb.prange(receivers.size):
        k = receivers[r]
        a = b = hx = hy = c = s = 0.0
        xk, yk, fk, pk, gk = x[k], y[k], far[r], partner[r], gain[r]
        for j in range(n):
            a, b, hx, hy, c, s = add_moments((a, b, hx, hy, c, s), pair(
                xk - x[j], yk - y[j], cos_t[j], sin_t[j], j == pk, w2, fk, gk, alpha, ar02, target, normalised))
        m[0, r], m[1, r], m[2, r], m[3, r], m[4, r], m[5, r] = a, b, hx, hy, c, s
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


@nb.njit(parallel=True, cache=True, fastmath=FASTMATH)
def cell_pairs(x, y, cos_t, sin_t, receivers, w, far, partner, gain, alpha, ar02, target, normalised):
    """Moments (6, K): each receiver (a table row) against the agents of its 3 × 3 cells
    (pairs within w), the cells of the whole table: a row's sum is the same whichever
    receivers are asked with it."""
    order, sorted_key, ny, start = cells(x, y, w)
    xs, ys, cs, ss = x[order], y[order], cos_t[order], sin_t[order]
    where = np.empty(x.size, dtype=np.int64)
    where[order] = np.arange(x.size)
    m = np.empty((6, receivers.size))
    for r in nb.prange(receivers.size):
        k = receivers[r]
        i = where[k]
        a = b = hx = hy = c = s = 0.0
        xk, yk, fk, gk = xs[i], ys[i], far[r], gain[r]
        pk = where[partner[r]] if partner[r] >= 0 else -1
        for col in range(-1, 2):                    # cells (cx + col, cy − 1 … cy + 1)
            first = sorted_key[i] + col * ny - 1
            if start.size:
                lo, hi = start[first], start[first + 3]
            else:
                lo = np.searchsorted(sorted_key, first)
                hi = np.searchsorted(sorted_key, first + 3)
            for jj in range(lo, hi):
                a, b, hx, hy, c, s = add_moments((a, b, hx, hy, c, s), pair(
                    xk - xs[jj], yk - ys[jj], cs[jj], ss[jj], jj == pk, w * w, fk, gk, alpha, ar02, target, normalised))
        m[0, r], m[1, r], m[2, r], m[3, r], m[4, r], m[5, r] = a, b, hx, hy, c, s
    return m
