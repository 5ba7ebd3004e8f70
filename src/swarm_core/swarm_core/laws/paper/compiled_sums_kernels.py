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


@nb.njit(cache=True)
def _coupling(rows, flags, table, any_leader, avoid, q0, lam, gain_l):
    """far, partner, gain of each receiver, as `compiled_sums.compiled_moments` forms them, with
    the nearest leader l(k) of `pair_sums.nearest_leader` (ties to the lower row)."""
    k_n, n = rows.size, flags.size
    far, partner, gain = np.empty(k_n), np.full(k_n, -1, dtype=np.int64), np.ones(k_n)
    for r in range(k_n):
        k = rows[r]
        if not any_leader:
            far[r] = 0.0 if avoid else q0 * (1.0 - lam)
            continue
        gain[r] = (gain_l - 1.0) * lam + 1.0
        if flags[k]:
            far[r] = q0
            continue
        far[r] = q0 * (1.0 - lam)
        best = np.inf
        for j in range(n):
            if flags[j]:
                dx, dy = table[k, 0] - table[j, 0], table[k, 1] - table[j, 1]
                d2 = dx * dx + dy * dy
                if d2 < best or partner[r] < 0:
                    best, partner[r] = d2, j
    return far, partner, gain


@nb.njit(cache=True)
def _move(r, u, dt, pos, theta, qz, qw, cos_t, sin_t):
    """Row r one step with u held (`integrate.zoh_step`), then its quaternion and frame
    (`agent_core.States.refresh`)."""
    half = u * (0.5 * dt)
    mid = theta[r] + half
    chord = (np.sin(half) / half if half != 0.0 else 1.0) * dt
    pos[r, 0] = np.cos(mid) * chord + pos[r, 0]
    pos[r, 1] = np.sin(mid) * chord + pos[r, 1]
    theta[r] = theta[r] + 2.0 * half
    hh = 0.5 * theta[r]
    qz[r], qw[r] = np.sin(hh), np.cos(hh)
    cos_t[r] = qw[r] * qw[r] - qz[r] * qz[r]
    sin_t[r] = 2.0 * qw[r] * qz[r]


@nb.njit(cache=True)
def row_step(x, y, qz, qw, rows, pos, theta, cos_k, sin_k, flags, steering, lam, q0, consts, target, everywhere,
             dt, u, qz_k, qw_k):
    """One lockstep step of the receivers ``rows`` (an agent container's bank, a lone agent's
    row): the paper's law as `PaperLaw.evaluate` forms it with the compiled sums, then the
    move (`integrate.zoh_step`) and the new quaternion and frame (`agent_core.States.refresh`),
    the same IEEE operations in the same order, so the same bits (no fast-math here: only the
    moments, `all_pairs` and `cell_pairs`, are the batch engine's own kernels, called as it
    calls them).

    The step's table x, y, qz, qw (N,) as received; pos (K, 2), theta, cos_k, sin_k (K,): the
    receivers' own states (rows of the table), moved in place; flags (N,) the leader flags,
    steering (N,) s_k; lam, q0: the law's effective λ and q0; consts: `compiled_step.constants`;
    target = (on, x, y, γ); everywhere: the sums over all pairs (else the cell list,
    `compiled_sums.all_pairs_wanted`).  Writes the u of
    each receiver (as the law gave it, non-finite too) into ``u`` and the new quaternions into
    qz_k, qw_k; returns the table (pos (N, 2), cos θ, sin θ) each u came from."""
    n, k_n = x.size, rows.size
    alpha, eta, mu, r0, w2, gain_l, ar02 = consts[0], consts[1], consts[2], consts[3], consts[4], consts[5], consts[6]
    avoid, normalised, leader_law, w = consts[7] != 0.0, consts[8] != 0.0, consts[9] != 0.0, consts[10]
    table = np.empty((n, 2))
    ct, st = np.empty(n), np.empty(n)
    any_leader = False
    for j in range(n):                          # frames from the quaternions (frenet.frame_from_quaternion)
        table[j, 0], table[j, 1] = x[j], y[j]
        ct[j] = qw[j] * qw[j] - qz[j] * qz[j]
        st[j] = 2.0 * qw[j] * qz[j]
        any_leader = any_leader or flags[j]
    any_leader = any_leader and leader_law
    for r in range(k_n):                        # the receivers' own rows
        k = rows[r]
        table[k, 0], table[k, 1], ct[k], st[k] = pos[r, 0], pos[r, 1], cos_k[r], sin_k[r]
    far, partner, gain = _coupling(rows, flags, table, any_leader, avoid, q0, lam, gain_l)
    xs, ys = np.ascontiguousarray(table[:, 0]), np.ascontiguousarray(table[:, 1])
    if everywhere:
        m = all_pairs(xs, ys, ct, st, rows, w2, far, partner, gain, alpha, ar02, avoid, normalised)
    else:
        m = cell_pairs(xs, ys, ct, st, rows, w, far, partner, gain, alpha, ar02, avoid, normalised)
    for r in range(k_n):
        k = rows[r]
        s, c = st[k], ct[k]                     # F = (sin θ_k, cos θ_k): `pair_sums._combine`
        if avoid:
            uk = m[3, r] * c - m[2, r] * s
        else:
            y0 = (m[4, r] * mu + m[2, r]) * s
            y1 = (m[5, r] * mu + m[3, r]) * c
            base = ((c * c - s * s) * m[0, r] + (c * s) * m[1, r]) * eta
            uk = (y1 - y0) - base
        if any_leader and flags[k]:
            uk = (1.0 - lam) * uk + lam * steering[k]
        if target[0] != 0.0:                    # `terms.target_term`
            dx, dy = target[1] - table[k, 0], target[2] - table[k, 1]
            d2 = dx * dx + dy * dy
            inv = 1.0 / d2 if d2 > 0.0 else 0.0
            across = dy * c - dx * s
            if normalised:
                across = across * np.sqrt(inv)
            uk = uk + target[3] * alpha * (1.0 - r0 * r0 * inv) * across * (1.0 if d2 > 0.0 else 0.0)
        u[r] = uk
        _move(r, uk if np.isfinite(uk) else 0.0, dt, pos, theta, qz_k, qw_k, cos_k, sin_k)
    return table, ct, st
