"""The compiled kernels of `paper.natural_compiled` (numba; imported only from there, on first use,
so no agent process pays for numba).  Compiled code is cached on disk (``cache=True``).

The table comes as twelve coordinate arrays (N,): r (px, py, pz), then x, y, z of the frames."""
import numba as nb
import numpy as np

# sums may be reassociated (SIMD), products fused; no other fast-math liberty (the self
# pair and coincident pairs rely on ρ² == 0 being seen)
FASTMATH = {'reassoc', 'contract'}


@nb.njit(inline='always', fastmath=FASTMATH)
def pair_vector(dx, dy, dz, hx, hy, hz, ax, ay, az, partner, w2, far, gain, c):
    """W_jk g_jk of one pair (3 components), branch-free; r_jk = (dx, dy, dz), x_j = (hx, hy, hz),
    x_k = (ax, ay, az); c = (α, α r0², η, μ, target, normalised).  0 for the self pair and
    coincident pairs (ρ² = 0), as the numpy sums give them.  The target law (eq. 15): −f r_jk
    within w (over ρ if normalised)."""
    alpha, ar02, eta, mu, target, normalised = c
    rr = dx * dx + dy * dy + dz * dz
    weight = 1.0 if rr < w2 else far
    weight = weight * gain if partner else weight
    weight = 0.0 if rr == 0.0 else weight
    inv = 1.0 / (1.0 if rr == 0.0 else rr)
    root = np.sqrt(inv)
    if target:                                      # −f = α r0²/ρ² − α
        h = weight * (inv * ar02 - alpha)
        h = h * root if normalised else h
        return h * dx, h * dy, h * dz
    # (−η (r̂·x_k) − f) r̂ = (−η (r_jk·x_k)/ρ² − f/ρ) r_jk, eq. 5-6
    radial = weight * (-eta * (dx * ax + dy * ay + dz * az) * inv - (alpha - ar02 * inv) * root)
    mw = mu * weight
    return radial * dx + mw * hx, radial * dy + mw * hy, radial * dz + mw * hz


@nb.njit(inline='always', fastmath=FASTMATH)
def range_sum(lo, hi, t, own, partner, w2, far, gain, c, acc):
    """``acc`` plus W_jk g_jk of the agents lo … hi − 1 of the table ``t`` (twelve coordinate
    arrays); own = (r_k, x_k), partner: the index of l(k) in ``t``."""
    sx, sy, sz = acc
    rx, ry, rz, ax, ay, az = own
    px, py, pz, hx, hy, hz = t[0], t[1], t[2], t[3], t[4], t[5]
    for j in range(lo, hi):
        gx, gy, gz = pair_vector(rx - px[j], ry - py[j], rz - pz[j], hx[j], hy[j], hz[j], ax, ay, az,
                                 j == partner, w2, far, gain, c)
        sx += gx
        sy += gy
        sz += gz
    return sx, sy, sz


@nb.njit(inline='always')
def read_normal(out, i, t, k, acc):
    """out[i] = (a·y_k, a·z_k) of the sum a = ``acc`` of agent k of the table ``t``."""
    out[i, 0] = acc[0] * t[6][k] + acc[1] * t[7][k] + acc[2] * t[8][k]
    out[i, 1] = acc[0] * t[9][k] + acc[1] * t[10][k] + acc[2] * t[11][k]


@nb.njit(parallel=True, cache=True, fastmath=FASTMATH)
def all_pairs_3d(px, py, pz, xx, xy, xz, yx, yy, yz, zx, zy, zz, receivers, w2, far, partner, gain, c):
    """(u, v) (K, 2) of the pair term: every receiver k (a table row) against every agent j."""
    t = (px, py, pz, xx, xy, xz, yx, yy, yz, zx, zy, zz)
    out = np.empty((receivers.size, 2))
    for i in nb.prange(receivers.size):
        k = receivers[i]
        own = (px[k], py[k], pz[k], xx[k], xy[k], xz[k])
        acc = range_sum(0, px.size, t, own, partner[i], w2, far[i], gain[i], c, (0.0, 0.0, 0.0))
        read_normal(out, i, t, k, acc)
    return out


@nb.njit(parallel=True, cache=True)
def nearest_rows_3d(px, py, pz, receivers, leader_rows):
    """l(k) (K,): the table row of the leader nearest to each receiver (ties to the lower row)."""
    out = np.empty(receivers.size, dtype=np.int64)
    for i in nb.prange(receivers.size):
        k = receivers[i]
        best, best_d = -1, np.inf
        for leader in leader_rows:
            dx, dy, dz = px[k] - px[leader], py[k] - py[leader], pz[k] - pz[leader]
            d = dx * dx + dy * dy + dz * dz
            if d < best_d or best < 0:
                best, best_d = leader, d
        out[i] = best
    return out


@nb.njit(cache=True)
def cells_3d(px, py, pz, w):
    """A cell list of side w: the agents in cell order (stable), their keys (cx·ny + cy)·nz + cz
    (one empty cell all round), ny, nz, and the first position of each cell (empty: binary
    search; then the order comes from a merge sort, else from counting)."""
    cx = np.floor((px - px.min()) / w).astype(np.int64) + 1
    cy = np.floor((py - py.min()) / w).astype(np.int64) + 1
    cz = np.floor((pz - pz.min()) / w).astype(np.int64) + 1
    ny, nz = cy.max() + 2, cz.max() + 2
    key = (cx * ny + cy) * nz + cz
    ncells = (cx.max() + 2) * ny * nz
    if ncells > 8 * px.size + 64:
        order = np.argsort(key, kind='mergesort')
        return order, key[order], ny, nz, np.zeros(0, dtype=np.int64)
    start = np.zeros(ncells + 1, dtype=np.int64)
    for i in range(px.size):
        start[key[i] + 1] += 1
    start = np.cumsum(start)                        # start[c]: first position of cell c
    fill = start[:-1].copy()
    order = np.empty(px.size, dtype=np.int64)
    for i in range(px.size):                        # counting sort: stable, as the merge sort
        order[fill[key[i]]] = i
        fill[key[i]] += 1
    return order, key[order], ny, nz, start


@nb.njit(cache=True)
def cell_order(where, receivers):
    """The receivers' indices in the cell order of their agents (``where``: an agent's place in
    it): by marking each place, or by sorting where a receiver is asked twice."""
    mark = np.full(where.size, -1, dtype=np.int64)
    for i in range(receivers.size):
        mark[where[receivers[i]]] = i
    visit = mark[mark >= 0]
    return visit if visit.size == receivers.size else np.argsort(where[receivers])


@nb.njit(parallel=True, cache=True, fastmath=FASTMATH)
def cell_pairs_3d(px, py, pz, xx, xy, xz, yx, yy, yz, zx, zy, zz, receivers, w, far, partner, gain, c):
    """(u, v) (K, 2) of the pair term: every receiver against the agents of its 3 × 3 × 3 cells
    (pairs within w only carry weight).  The receivers are visited in cell order; the nine runs
    of three cells are joined where they meet in cell order (a flat swarm: three runs)."""
    order, sorted_key, ny, nz, start = cells_3d(px, py, pz, w)
    t = (px, py, pz, xx, xy, xz, yx, yy, yz, zx, zy, zz)
    s = (px[order], py[order], pz[order], xx[order], xy[order], xz[order])
    where = np.empty(px.size, dtype=np.int64)
    where[order] = np.arange(px.size)
    visit = cell_order(where, receivers)
    out = np.empty((receivers.size, 2))
    for v in nb.prange(receivers.size):
        i = visit[v]
        k = receivers[i]
        at = where[k]
        own = (px[k], py[k], pz[k], xx[k], xy[k], xz[k])
        pk = where[partner[i]] if partner[i] >= 0 else -1
        acc = (0.0, 0.0, 0.0)
        run_lo = run_hi = 0
        for block in range(9):                      # cells (cx + col, cy + row, cz − 1 … cz + 1)
            first = sorted_key[at] + ((block // 3 - 1) * ny + block % 3 - 1) * nz - 1
            if start.size:
                lo, hi = start[first], start[first + 3]
            else:
                lo = np.searchsorted(sorted_key, first)
                hi = np.searchsorted(sorted_key, first + 3)
            if lo != run_hi:                        # a new run: sum the one before
                acc = range_sum(run_lo, run_hi, s, own, pk, w * w, far[i], gain[i], c, acc)
                run_lo = lo
            run_hi = hi
        acc = range_sum(run_lo, run_hi, s, own, pk, w * w, far[i], gain[i], c, acc)
        read_normal(out, i, t, k, acc)
    return out
