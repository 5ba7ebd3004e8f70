"""The radio model (`comms`) in the study fast path: fates, beliefs and the law on beliefs,
compiled (numba), for `fast._run`.  No ROS process imports this module.

Each step n, as the reference engine does it (`comms.CommModel.decide`, `Beliefs.receive`,
`belief_controls`):

- every agent sends its state of t_n (x, y, the planar quaternion, the u it held over the
  step that ended at t_n); the fate of the message j → k is drawn from the same
  counter-based hash (`comms.link_uniforms`: splitmix64 over seed, n, k, j, stream), so a
  message is lost, cut by a partition or the radio range, or delayed by the very same
  numbers as in the reference and in every agent process;
- each receiver folds in the messages that arrive at step n (newest stamp wins), forgets
  senders older than the timeout and dead-reckons the others to t_n (each message
  (sender, age) once per step, as `Beliefs.known_pairs` does for large tables);
- its u is the law over its believed senders, summed one after the other in sender order
  (the reference's ``np.bincount`` over the pair list), its nearest leader the believed
  leader nearest to its true position (ties to the lower row).

Covered: loss, latency, jitter, radio range, partitions, per-link values (``links``),
timeout, dead reckoning.  Not covered (`fast.fallback_reason` says 'radio events' and the
reference runs): scheduled ``events`` (changes of loss, latency, bursts, partitions in time).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .comms import _GOLDEN, _M1, _M2, STREAM_DELAY, STREAM_LOSS, delay_stats

_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_UNIT = 1.0 / 9007199254740992.0            # 2⁻⁵³, as `comms.link_uniforms`

#: rf (the kernel's radio numbers): on, has range, R², dt, max age (steps), dead reckoning
RF_FIELDS = 6


def radio_arguments(model, n: int):
    """The radio arguments of `fast._run` for a `comms.CommModel` (None: the perfect radio):
    (rf, seed (1,) uint64, link (3, n, n) loss/latency/jitter, partition labels (n,), stats
    (2 + ring,) int64 filled by the kernel: sent, delivered, the histogram of delays)."""
    if model is None:
        return (np.zeros(RF_FIELDS), np.zeros(1, np.uint64), np.zeros((3, 0, 0)),
                np.zeros(0, np.int64), np.zeros(2, np.int64))
    rows = np.arange(n)
    link = np.stack([np.broadcast_to(np.asarray(model._param(key, rows, rows), float), (n, n))
                     for key in ('loss', 'latency', 'jitter')])
    # U₁ < 1, so no delay exceeds ceil((L + J)/dt − 1e-9) steps: a ring of that many + 1 sends
    ring = int(max(0.0, math.ceil(float(((link[1] + link[2]) / model.dt - 1e-9).max())))) + 1
    r = model.radio_range
    rf = np.array([1.0, float(r is not None), 0.0 if r is None else r * r, model.dt,
                   float(model.max_age_steps()), float(model.dead_reckoning)])
    return (rf, np.array([model.seed], np.uint64), link, model.labels.astype(np.int64),
            np.zeros(2 + ring, np.int64))


def radio_stats(stats, dt: float) -> dict:
    """``meta['comms']`` of a run (as `engine.SwarmStepper.comms_stats`)."""
    sent, got = int(stats[0]), int(stats[1])
    return dict(sent=sent, delivered=got, delivered_fraction=got / sent if sent else None,
                **delay_stats(stats[2:], dt))


# ------------------------------------------------------------------ fates

@njit(cache=True, inline='always')
def _mix(z):
    """splitmix64 finaliser (`comms._mix`), wrapping uint64 arithmetic."""
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@njit(cache=True, inline='always')
def _fold(h, key):
    """One key of `comms.link_uniforms`: mix(h XOR mix(key + G))."""
    return _mix(h ^ _mix(np.uint64(key) + _GOLDEN))


@njit(cache=True, inline='always')
def _uniform(h):
    return float(h >> _S11) * _UNIT


@njit(cache=True)
def _decide(i, x, y, seed, rf, link, labels, harr):
    """Arrival step of the messages of step i (`CommModel.decide`) into harr (n, n): −1 where
    lost; a receiver's own message arrives at once."""
    n = x.size
    h_step = _fold(_fold(_GOLDEN, seed), i)
    dt = rf[3]
    for k in range(n):
        h_k = _fold(h_step, k)
        for j in range(n):
            if j == k:
                harr[k, j] = i
                continue
            h = _fold(h_k, j)
            ok = _uniform(_fold(h, STREAM_LOSS)) >= link[0, k, j] and labels[k] == labels[j]
            if rf[1] != 0.0:
                dx, dy = x[k] - x[j], y[k] - y[j]
                ok = ok and dx * dx + dy * dy <= rf[2]
            if not ok:
                harr[k, j] = -1
                continue
            delay_t = link[1, k, j]
            if link[2, k, j] > 0.0:
                delay_t = delay_t + link[2, k, j] * _uniform(_fold(h, STREAM_DELAY))
            harr[k, j] = i + max(math.ceil(delay_t / dt - 1e-9), 0)


@njit(cache=True)
def radio_state(n, ring, max_age):
    """The kernel's beliefs: stamp (n, n) of the newest state held (−1: none), its state
    (5, n, n: x, y, qz, qw, u), the last ``ring`` sends (states (ring, 5, n), arrivals
    (ring, n, n)), the dead-reckoned messages of the step (sender, age) and a receiver's
    believed table (x, y, cos θ, sin θ, sender)."""
    stamp = np.full((n, n), -1, np.int64)
    sent_at = np.full((ring, n, n), -2, np.int64)
    predicted_at = np.full((n, max_age + 1), -1, np.int64)
    return (stamp, np.zeros((5, n, n)), np.zeros((ring, 5, n)), sent_at, np.zeros((n, max_age + 1, 4)),
            predicted_at, np.zeros((4, n)), np.zeros(n, np.int64))


@njit(cache=True)
def radio_receive(i, x, y, theta, u_prev, radio, state):
    """Send the states of step i, decide their fates and fold what arrives at step i into the
    beliefs (`Beliefs.receive`, newest stamp winning), counting what the radio did."""
    rf, seed, link, labels, stats = radio
    stamp, belief, hist, harr = state[0], state[1], state[2], state[3]
    n, ring = x.size, hist.shape[0]
    slot = i % ring
    for j in range(n):
        half = 0.5 * theta[j]
        hist[slot, 0, j], hist[slot, 1, j] = x[j], y[j]
        hist[slot, 2, j], hist[slot, 3, j], hist[slot, 4, j] = math.sin(half), math.cos(half), u_prev[j]
    _decide(i, x, y, seed[0], rf, link, labels, harr[slot])
    for k in range(n):
        for j in range(n):
            if j == k:
                continue
            stats[0] += 1
            if harr[slot, k, j] >= 0:
                stats[1] += 1
                stats[2 + harr[slot, k, j] - i] += 1
            for d in range(min(i, ring - 1) + 1):    # the newest message due now
                m = i - d
                if harr[m % ring, k, j] == i:
                    if m > stamp[k, j]:
                        stamp[k, j] = m
                        for f in range(5):
                            belief[f, k, j] = hist[m % ring, f, j]
                    break


# ------------------------------------------------------------------ beliefs and the law

@njit(cache=True)
def _believed(i, k, rf, state):
    """The senders receiver k knows at step i (heard within the timeout), ascending, their
    (x, y, cos θ, sin θ) dead-reckoned to t_i if the model says so (`Beliefs.known_pairs`);
    returns how many (into state's table)."""
    stamp, belief, pred, pred_at, table, rows = state[0], state[1], state[4], state[5], state[6], state[7]
    m = 0
    for j in range(stamp.shape[1]):
        age = i - stamp[k, j]
        if j == k or stamp[k, j] < 0 or age > rf[4]:
            continue
        if rf[5] != 0.0 and age > 0:
            if pred_at[j, age] != i:                 # each message (j, age) once per step
                _dead_reckon(belief[:, k, j], age * rf[3], pred[j, age])
                pred_at[j, age] = i
            for f in range(4):
                table[f, m] = pred[j, age, f]
        else:
            qz, qw = belief[2, k, j], belief[3, k, j]
            table[0, m], table[1, m] = belief[0, k, j], belief[1, k, j]
            table[2, m], table[3, m] = qw * qw - qz * qz, 2.0 * qw * qz
        rows[m] = j
        m += 1
    return m


@njit(cache=True)
def _dead_reckon(st, horizon, out):
    """(x, y, cos θ, sin θ) of a state (x, y, qz, qw, u) ``horizon`` sim s ahead on the exact
    arc (`comms.dead_reckon`: yaw, `zoh_step`, quaternion, frame)."""
    theta = 2.0 * math.atan2(st[2], st[3])
    half = st[4] * (0.5 * horizon)
    mid = theta + half
    chord = (math.sin(half) / half if half != 0.0 else 1.0) * horizon
    out[0] = math.cos(mid) * chord + st[0]
    out[1] = math.sin(mid) * chord + st[1]
    h2 = 0.5 * (theta + 2.0 * half)
    qz, qw = math.sin(h2), math.cos(h2)
    out[2], out[3] = qw * qw - qz * qz, 2.0 * qw * qz


@njit(cache=True)
def radio_control(i, x, y, c, s, lam, q0, is_leader, steer, code, gains, normalised, rf, state, u):
    """u_k of every receiver from its true state and its beliefs (`comms.belief_controls`,
    the sparse pair sums of `pair_sums._pair_sums_sparse` and `_combine`): eq. 4-5, 8,
    10-15 over the believed senders, in sender order; a coincident pair adds nothing (the
    reference's careful redo)."""
    alpha, eta, mu, r0, w, leader_gain = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5]
    ar2, w2 = alpha * r0 * r0, w * w
    far, gain_f = q0 * (1.0 - lam), (leader_gain - 1.0) * lam + 1.0
    table, rows = state[6], state[7]
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
