"""The compiled kernels of the study fast path (numba): a whole run of a small swarm as one
loop (`_run`), the law over all pairs, and the radio model (`radio`) on beliefs.
`fast_run` prepares their arguments and runs them; no ROS process imports this module.

Every kernel lives in this one file: numba's on-disk cache (``cache=True``) is keyed by the
file that defines a function, so a change in a kernel called from another file would not
recompile `_run`.

**The radio** (`radio_receive`, `radio_control`), each step n, as the reference engine
does it (`swarm_core.radio.CommModel.decide`, `Beliefs.receive`, `belief_controls`):

- every agent sends its state of t_n (x, y, the planar quaternion, the u it held over the
  step that ended at t_n); the fate of the message j → k is drawn from the same
  counter-based hash (`swarm_core.radio.link_uniforms`: splitmix64 over seed, n, k, j,
  stream), so a message is lost, cut by a partition or the radio range, or delayed by the very
  same numbers as in the reference and in every agent process;
- each receiver folds in the messages that arrive at step n (newest stamp wins), forgets
  senders older than the timeout and dead-reckons the others to t_n (each message
  (sender, age) once per step, as `Beliefs.known_pairs` does for large tables);
- its u is the law over its believed senders, summed one after the other in sender order
  (the reference's ``np.bincount`` over the pair list), its nearest leader the believed
  leader nearest to its true position (ties to the lower row).

The radio's kernels are inlined into `_run` (``inline='always'``): as calls, once per step
and receiver with their tuples of arrays, they cost about as much as their work at n = 6.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from swarm_core.radio import (
    GOLDEN,
    MIX_M1,
    MIX_M2,
    SHIFT_11,
    SHIFT_27,
    SHIFT_30,
    SHIFT_31,
    STREAM_DELAY,
    STREAM_LOSS,
)
from swarm_core.radio import splitmix as _mix_array

_UNIT = 1.0 / 9007199254740992.0            # 2⁻⁵³, as `swarm_core.radio.link_uniforms`
#: dead-reckoned messages kept per sender and step: those up to this many steps old
PREDICTED_AGES = 64
#: mix(stream + G) of the two streams (`swarm_core.radio.link_uniforms`' last key)
_KEY_LOSS, _KEY_DELAY = _mix_array(np.array([STREAM_LOSS, STREAM_DELAY], dtype=np.uint64) + GOLDEN)


# ------------------------------------------------------------------ the law and the run

@njit(cache=True, inline='always')
def _pairwise(a, lo, hi):
    """numpy's pairwise sum of a[lo:hi] (its add.reduce: the first item plus the pairwise sum
    of the rest, 8 accumulators up to 128 items), so a row sums as the reference's."""
    m = hi - lo - 1
    first = a[lo]
    lo += 1
    if m < 8:
        res = 0.0
        for i in range(lo, hi):
            res += a[i]
        return first + res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < m - (m % 8):
        b = lo + i
        r0 += a[b]
        r1 += a[b + 1]
        r2 += a[b + 2]
        r3 += a[b + 3]
        r4 += a[b + 4]
        r5 += a[b + 5]
        r6 += a[b + 6]
        r7 += a[b + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < m:
        res += a[lo + i]
        i += 1
    return first + res


@njit(cache=True)
def _control(x, y, c, s, lam, q0, is_leader, steer, alpha, eta, mu, r0, w, leader_gain, mom, u):
    """u_k of every agent (eq. 4-5, 8, 10-14), as `laws.swarm_control` over the whole table:
    the six moments of `pair_sums._pair_sums_dense` per receiver, then `_combine`."""
    n = x.size
    any_leader = False
    for j in range(n):
        any_leader = any_leader or is_leader[j]
    ar2 = alpha * r0 * r0
    w2 = w * w
    gain_f = (leader_gain - 1.0) * lam + 1.0
    for k in range(n):
        if any_leader and is_leader[k]:
            far, partner = q0, -1
        else:
            far = q0 * (1.0 - lam)
            partner = -1
            if any_leader:                       # l(k): nearest leader by ρ², ties to the lower row
                best = np.inf
                for j in range(n):
                    if is_leader[j] and j != k:
                        dx = x[k] - x[j]
                        dy = y[k] - y[j]
                        d2 = dx * dx + dy * dy
                        if d2 < best:
                            best, partner = d2, j
        for j in range(n):
            dx = x[k] - x[j]
            dy = y[k] - y[j]
            dx2 = dx * dx
            dy2 = dy * dy
            rr = dx2 + dy2
            if j == k:
                rr = np.inf
            wm = 1.0 if rr < w2 else far         # c(ρ, q, w), eq. 8
            if j == partner:
                wm = wm * gain_f                 # (ℓc − 1)λ + 1 on (k, l(k)), eq. 13
            rr = 1.0 / rr
            h = (rr * ar2 - alpha) * math.sqrt(rr)
            rr = rr * wm
            h = h * wm
            mom[0, j] = dx * dy * rr
            mom[1, j] = (dy2 - dx2) * rr
            mom[2, j] = dx * h
            mom[3, j] = dy * h
            mom[4, j] = c[j] * wm
            mom[5, j] = s[j] * wm
        A = _pairwise(mom[0], 0, n)
        B = _pairwise(mom[1], 0, n)
        Hx = _pairwise(mom[2], 0, n)
        Hy = _pairwise(mom[3], 0, n)
        C = _pairwise(mom[4], 0, n)
        S = _pairwise(mom[5], 0, n)
        ck, sk = c[k], s[k]
        y0 = (C * mu + Hx) * sk
        y1 = (S * mu + Hy) * ck
        base = ((ck * ck - sk * sk) * A + (ck * sk) * B) * eta
        uk = y1 - y0 - base
        if any_leader and is_leader[k]:
            uk = (1.0 - lam) * uk + lam * steer[k]
        u[k] = uk


@njit(cache=True)
def _target_control(x, y, c, s, alpha, r0, w, normalised, u):
    """u_k of the target law's collision avoidance within w (eq. 15, first line), as
    `pair_sums._pair_sums_dense` and `_combine` form it: c·Hy − s·Hx."""
    n = x.size
    ar2 = alpha * r0 * r0
    hx, hy = np.empty(n), np.empty(n)
    for k in range(n):
        for j in range(n):
            dx = x[k] - x[j]
            dy = y[k] - y[j]
            rr = dx * dx + dy * dy
            if j == k:
                rr = np.inf
            within = rr < w * w
            rr = 1.0 / rr
            h = rr * ar2 - alpha
            if normalised:
                h = h * math.sqrt(rr)
            h = h * within
            hx[j], hy[j] = dx * h, dy * h
        u[k] = _pairwise(hy, 0, n) * c[k] - _pairwise(hx, 0, n) * s[k]


@njit(cache=True)
def _world_terms(x, y, c, s, world, barrier, alpha, r0, w, u):
    """u plus the target term (eq. 15, `laws.target_term`) and the barrier term (eq. 16,
    `swarm_core.laws.paper.terms.barrier_term`); world = (target on, x, y, γ, normalised, barrier
    on, s_b, literal)."""
    for k in range(x.size):
        if world[0] != 0.0:
            dx, dy = world[1] - x[k], world[2] - y[k]
            d2 = dx * dx + dy * dy
            inv = 1.0 / d2 if d2 > 0.0 else 0.0
            across = dy * c[k] - dx * s[k]
            if world[4] != 0.0:
                across = across * math.sqrt(inv)
            u[k] = u[k] + world[3] * alpha * (1.0 - r0 * r0 * inv) * across * (1.0 if d2 > 0.0 else 0.0)
        if world[5] != 0.0:
            vx = vy = 0.0
            for i in range(barrier.shape[0]):
                bx, by = barrier[i, 0] - x[k], barrier[i, 1] - y[k]
                if bx * bx + by * by < w * w:
                    vx += bx
                    vy += by
            norm = math.hypot(vx, vy)
            if norm > 0.0:
                vx, vy = vx / norm, vy / norm
            else:
                vx = vy = 0.0
            ahead = vx * c[k] + vy * s[k]
            side = vy * c[k] - vx * s[k]
            if world[7] != 0.0:
                gate = 1.0 if ahead > 0.0 else -1.0 if ahead < 0.0 else 0.0
            else:
                gate = 1.0 if ahead > 0.0 else 0.0
            u[k] = u[k] + -world[6] * gate * side


@njit(cache=True)
def _frames(theta, c, s, q):
    """(cos θ, sin θ) through the planar quaternion q = (qz, qw), as `frenet.heading_frame`."""
    for k in range(theta.size):
        half = 0.5 * theta[k]
        qz, qw = math.sin(half), math.cos(half)
        q[0, k], q[1, k] = qz, qw
        c[k] = qw * qw - qz * qz
        s[k] = 2.0 * qw * qz


@njit(cache=True)
def _lateral_extremes(x, y, c, s):
    """(left, right) as `swarm_core.command.plan.lateral_extremes`."""
    n = x.size
    hx = _pairwise(c, 0, n) / n
    hy = _pairwise(s, 0, n) / n
    norm = math.hypot(hx, hy)
    if norm == 0.0:
        hx, hy = 1.0, 0.0
    else:
        hx, hy = hx / norm, hy / norm
    mx, my = x[0], y[0]
    for k in range(1, n):
        mx += x[k]
        my += y[k]
    mx, my = mx / n, my / n
    left = right = 0
    lmax = lmin = 0.0
    for k in range(n):
        lat = -(x[k] - mx) * hy + (y[k] - my) * hx
        if k == 0 or lat > lmax:
            lmax, left = lat, k
        if k == 0 or lat < lmin:
            lmin, right = lat, k
    return left, right


@njit(cache=True)
def _steering(prog, t):
    """s_k of a program row (kind, a, b, c, d): 0 constant a; 1 sinusoid d + a sin(2πt/b + c)."""
    if prog[0] == 0.0:
        return prog[1]
    return prog[4] + prog[1] * math.sin(2.0 * math.pi * t / prog[2] + prog[3])


@njit(cache=True)
def _run(x, y, theta, dt, lams, code, q0, gains, leader_prog, progs, rule, choose_at, choose_rise,
         world, barrier, noise, radio, every, r_rec, th_rec, u_rec, lead_rec):
    """Every step of a run (the commander's plan, the radio, the law, the zoh step, the noise)
    with the records of every ``every``-th step filled in place; returns the step at which
    the rule chose the leaders (−1: none).  radio: `swarm_core.laws.paper.fast_run.radio_arguments`."""
    n = x.size
    steps = lams.size - 1
    alpha, eta, mu, r0, w, leader_gain = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5]
    c, s, u, steer = np.empty(n), np.empty(n), np.zeros(n), np.zeros(n)   # u: the last step's, sent
    on = radio[0][0] != 0.0
    ring = max(1, radio[4].size - 2)
    held = 1                                     # a power of two: slot = step & (held − 1)
    while held < max(ring, min(int(radio[0][4]), steps) + 1):
        held *= 2
    state = radio_state(n if on else 0, ring, held)
    mom, q, no_leader = np.empty((6, n)), np.empty((2, n)), np.zeros(n, np.bool_)
    is_leader = leader_prog >= 0
    pending = rule and not is_leader.any()
    chosen = -1
    lam_low = np.inf
    for i in range(steps + 1):
        t = i * dt
        _frames(theta, c, s, q)
        lam = lams[i]
        lam_low = min(lam_low, lam)
        if pending and (t >= choose_at or lam - lam_low >= choose_rise):
            left, right = _lateral_extremes(x, y, c, s)
            leader_prog[left] = 0
            if right != left and progs.shape[0] > 1:
                leader_prog[right] = 1
            is_leader = leader_prog >= 0
            pending, chosen = False, i
        for k in range(n):
            steer[k] = _steering(progs[leader_prog[k]], t) if is_leader[k] else 0.0
        eff_lam, eff_q0 = (0.0, 1.0) if code == 0 else (0.0, 0.0) if code == 1 else \
            (1.0, 0.0) if code == 2 else (lam, q0)
        lead = is_leader if code == 2 or code == 3 else no_leader
        if on:
            radio_receive(i, x, y, q, c, s, u, radio, state)
            radio_control(i, x, y, c, s, eff_lam, eff_q0, lead, steer, code, gains, world[4] != 0.0,
                          radio[0], state, u)
        elif code == 4:
            _target_control(x, y, c, s, alpha, r0, w, world[4] != 0.0, u)
        else:
            _control(x, y, c, s, eff_lam, eff_q0, lead, steer, alpha, eta, mu, r0, w, leader_gain, mom, u)
        _world_terms(x, y, c, s, world, barrier, alpha, r0, w, u)
        if i % every == 0:
            row = i // every
            for k in range(n):
                r_rec[row, k, 0], r_rec[row, k, 1] = x[k], y[k]
                th_rec[row, k], u_rec[row, k], lead_rec[row, k] = theta[k], u[k], is_leader[k]
        if i == steps:
            break
        for k in range(n):                       # the exact arc of `integrate.zoh_step`
            half = u[k] * (0.5 * dt)
            mid = theta[k] + half
            chord = (math.sin(half) / half if half != 0.0 else 1.0) * dt
            x[k] = math.cos(mid) * chord + x[k]
            y[k] = math.sin(mid) * chord + y[k]
            theta[k] = theta[k] + 2.0 * half
        if noise.shape[0]:
            for k in range(n):
                x[k] = x[k] + noise[i, k, 0]
                y[k] = y[k] + noise[i, k, 1]
                theta[k] = theta[k] + noise[i, k, 2]
    return chosen


@njit(cache=True)
def _tanh_window(t, rise_at, fall_at, tau, low, high):
    """`schedules.TanhWindow.value` at every t."""
    out = np.empty(t.size)
    for i in range(t.size):
        bump = 0.5 * (math.tanh((t[i] - rise_at) / tau) - math.tanh((t[i] - fall_at) / tau))
        out[i] = low + (high - low) * bump
    return out


# ------------------------------------------------------------------ the radio
@njit(cache=True, inline='always')
def _mix(z):
    """splitmix64 finaliser (`swarm_core.radio.splitmix`), wrapping uint64 arithmetic."""
    z = (z ^ (z >> SHIFT_30)) * MIX_M1
    z = (z ^ (z >> SHIFT_27)) * MIX_M2
    return z ^ (z >> SHIFT_31)


@njit(cache=True, inline='always')
def _fold(h, key):
    """One key of `swarm_core.radio.link_uniforms`: mix(h XOR mix(key + G))."""
    return _mix(h ^ _mix(np.uint64(key) + GOLDEN))


@njit(cache=True, inline='always')
def _uniform(h):
    return float(h >> SHIFT_11) * _UNIT


@njit(cache=True)
def _decide(i, x, y, seed, rf, link, labels, keys, harr, stats):
    """Arrival step of the messages of step i (`CommModel.decide`) into harr (n, n): −1 where
    lost; a receiver's own message arrives at once.  keys: mix(k + G) of the rows k.  Counts
    the messages sent, delivered and their delays into stats."""
    n = x.size
    h_step = _fold(_fold(GOLDEN, seed), i)
    dt = rf[3]
    got = 0
    for k in range(n):
        h_k = _mix(h_step ^ keys[k])
        for j in range(n):
            if j == k:
                harr[k, j] = i
                continue
            h = _mix(h_k ^ keys[j])
            ok = labels[k] == labels[j]                 # & rather than branches: fates are random
            if link[0, k, j] > 0.0:
                ok = ok & (_uniform(_mix(h ^ _KEY_LOSS)) >= link[0, k, j])
            if rf[1] != 0.0:
                dx, dy = x[k] - x[j], y[k] - y[j]
                ok = ok & (dx * dx + dy * dy <= rf[2])
            if link[2, k, j] > 0.0:
                delay_t = link[1, k, j] + link[2, k, j] * _uniform(_mix(h ^ _KEY_DELAY))
                delay = max(math.ceil(delay_t / dt - 1e-9), 0)
            else:
                delay = int(link[3, k, j])
            harr[k, j] = i + delay if ok else -1
            stats[2 + delay] += ok
            got += ok
    stats[0] += n * (n - 1)
    stats[1] += got


@njit(cache=True)
def radio_state(n, ring, held):
    """The kernel's beliefs: stamp (n, n), the step of the newest state receiver k holds of
    sender j (−1: none), and no copy of it: the states of the last ``held`` sends (held a
    power of two ≥ the ring and the oldest age a belief is used at, so a stamp s finds its
    state in slot s & (held − 1): (held, 7, n) of x, y, qz, qw, u, cos θ, sin θ); the
    arrival steps of the last ``ring`` sends (ring, n, n); the dead-reckoned messages of the
    step (sender, age); a receiver's believed table (x, y, cos θ, sin θ, sender) and the
    hash keys mix(k + G) of the rows."""
    stamp = np.full((n, n), -1, np.int64)
    sent_at = np.full((ring, n, n), -2, np.int64)
    ages = min(held, PREDICTED_AGES)
    predicted_at = np.full((n, ages), -1, np.int64)
    keys = np.empty(n, np.uint64)
    for k in range(n):
        keys[k] = _mix(np.uint64(k) + GOLDEN)
    return (stamp, np.zeros((held, 7, n)), sent_at, np.zeros((n, ages, 4)), predicted_at,
            np.zeros((4, n)), np.zeros(n, np.int64), keys)


@njit(cache=True, inline='always')
def radio_receive(i, x, y, q, c, s, u_prev, radio, state):
    """Send the states of step i (q, c, s: their quaternions and frames), decide their fates
    and fold what arrives at step i into the beliefs (`Beliefs.receive`, newest stamp
    winning), counting what the radio did."""
    rf, seed, link, labels, stats = radio
    stamp, sent, harr = state[0], state[1], state[2]
    n, ring = x.size, harr.shape[0]
    at = i & (sent.shape[0] - 1)
    for j in range(n):
        sent[at, 0, j], sent[at, 1, j], sent[at, 2, j], sent[at, 3, j] = x[j], y[j], q[0, j], q[1, j]
        sent[at, 4, j], sent[at, 5, j], sent[at, 6, j] = u_prev[j], c[j], s[j]
    slot = i % ring
    back = min(i, ring - 1)                          # the sends still in the ring: slot − d
    _decide(i, x, y, seed[0], rf, link, labels, state[7], harr[slot], stats)
    for k in range(n):
        for j in range(n):
            newest = -1                              # the newest message due now
            for d in range(back, -1, -1):
                sl = slot - d if d <= slot else slot - d + ring
                newest = i - d if harr[sl, k, j] == i else newest
            stamp[k, j] = max(newest, stamp[k, j])   # a select, not a branch: fates are random


# ------------------------------------------------------------------ beliefs and the law

@njit(cache=True, inline='always')
def _believed(i, k, rf, state):
    """The senders receiver k knows at step i (heard within the timeout), ascending, their
    (x, y, cos θ, sin θ) dead-reckoned to t_i if the model says so (`Beliefs.known_pairs`);
    returns how many (into state's table)."""
    stamp, sent, pred, pred_at, table, rows = state[0], state[1], state[3], state[4], state[5], state[6]
    mask = sent.shape[0] - 1
    m = 0
    for j in range(stamp.shape[1]):
        age = i - stamp[k, j]
        if j == k or stamp[k, j] < 0 or age > rf[4]:
            continue
        at = stamp[k, j] & mask                      # its state: sent[at, :, j]
        if rf[5] != 0.0 and age > 0:
            if age >= pred_at.shape[1]:              # an old message: not kept
                xp, yp, cp, sp = _dead_reckon(sent, at, j, age * rf[3])
            else:
                if pred_at[j, age] != i:             # each message (j, age) once per step
                    pred[j, age, 0], pred[j, age, 1], pred[j, age, 2], pred[j, age, 3] = \
                        _dead_reckon(sent, at, j, age * rf[3])
                    pred_at[j, age] = i
                xp, yp, cp, sp = pred[j, age, 0], pred[j, age, 1], pred[j, age, 2], pred[j, age, 3]
        else:
            xp, yp, cp, sp = sent[at, 0, j], sent[at, 1, j], sent[at, 5, j], sent[at, 6, j]
        table[0, m], table[1, m], table[2, m], table[3, m] = xp, yp, cp, sp
        rows[m] = j
        m += 1
    return m


@njit(cache=True, inline='always')
def _dead_reckon(sent, at, j, horizon):
    """(x, y, cos θ, sin θ) of the state sent[at, :, j] (x, y, qz, qw, u, cos θ, sin θ)
    ``horizon`` sim s ahead on the exact arc, with the sums of
    `swarm_core.radio.dead_reckon` (sin and cos of uh/2 only)."""
    qz, qw, c, s = sent[at, 2, j], sent[at, 3, j], sent[at, 5, j], sent[at, 6, j]
    half = sent[at, 4, j] * (0.5 * horizon)
    sh, ch = math.sin(half), math.cos(half)
    chord = (sh / half if half != 0.0 else 1.0) * horizon
    qz, qw = qz * ch + qw * sh, qw * ch - qz * sh
    return ((c * ch - s * sh) * chord + sent[at, 0, j], (s * ch + c * sh) * chord + sent[at, 1, j],
            qw * qw - qz * qz, 2.0 * qw * qz)


@njit(cache=True, inline='always')
def radio_control(i, x, y, c, s, lam, q0, is_leader, steer, code, gains, normalised, rf, state, u):
    """u_k of every receiver from its true state and its beliefs
    (`swarm_core.step.belief_controls`, the sparse pair sums of
    `pair_sums._pair_sums_sparse` and `_combine`): eq. 4-5, 8, 10-15 over the believed senders,
    in sender order; a coincident pair adds nothing (the reference's careful redo)."""
    alpha, eta, mu, r0, w, leader_gain = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5]
    ar2, w2 = alpha * r0 * r0, w * w
    far, gain_f = q0 * (1.0 - lam), (leader_gain - 1.0) * lam + 1.0
    table, rows = state[5], state[6]
    for k in range(x.size):
        m = _believed(i, k, rf, state)
        xk, yk, ck, sk, lead_k = x[k], y[k], c[k], s[k], is_leader[k]
        partner, best = -1, np.inf                   # l(k): the nearest believed leader
        if not lead_k:
            for p in range(m):
                if is_leader[rows[p]]:
                    dx, dy = xk - table[0, p], yk - table[1, p]
                    d2 = dx * dx + dy * dy
                    if d2 < best:
                        best, partner = d2, rows[p]
        A = B = Hx = Hy = C = S = 0.0
        for p in range(m):
            dx, dy = xk - table[0, p], yk - table[1, p]
            dx2, dy2 = dx * dx, dy * dy
            rr = dx2 + dy2
            if rr == 0.0:
                continue
            within = rr < w2
            rr = 1.0 / rr
            h = rr * ar2 - alpha
            if code == 4:                            # eq. 15: h·r_jk within w
                if normalised:
                    h = h * math.sqrt(rr)
                h = h * (1.0 if within else 0.0)
                Hx += dx * h
                Hy += dy * h
                continue
            h = h * math.sqrt(rr)
            wgt = 1.0 if within else (0.0 if q0 == 0.0 else q0 if lead_k else far)
            if rows[p] == partner:
                wgt = wgt * gain_f
            rr = rr * wgt
            h = h * wgt
            A += (dx * dy) * rr
            B += (dy2 - dx2) * rr
            Hx += dx * h
            Hy += dy * h
            C += table[2, p] * wgt
            S += table[3, p] * wgt
        if code == 4:
            u[k] = Hy * ck - Hx * sk
            continue
        uk = (S * mu + Hy) * ck - (C * mu + Hx) * sk - ((ck * ck - sk * sk) * A + (ck * sk) * B) * eta
        u[k] = (1.0 - lam) * uk + lam * steer[k] if lead_k else uk
