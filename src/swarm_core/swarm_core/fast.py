"""The study fast path: a whole run of a small swarm as one compiled loop (numba), no ROS.

`simulate` takes the runs the kernel covers and hands every other run to the reference
engine (`engine.simulate`, today's numpy engine, which the ROS nodes are checked against bit
for bit); `fallback_reason` says why a run is not covered.  Covered: the zoh integrator; the
laws global, local, leader_following, homotopy and target (eq. 4, 9, 10-15) with the target
and barrier terms (eq. 15, 16) over all pairs of at most
`pair_sums.DENSE_LIMIT` agents; fixed leaders or the lateral_extremes rule; constant and
sinusoid steering programs; any λ schedule (evaluated ahead by the schedule itself, as the
commander does); per-agent noise (the same streams, drawn ahead).  Not covered (the reference
runs): faults, failover, reunion, a radio model, waypoint steering, rk4, live commands, more
than DENSE_LIMIT agents.

The kernel forms each receiver's pair sums as the reference does (`pair_sums._pair_sums_dense`
and `_combine`: the same moments, products and numpy's pairwise summation order), so it agrees
with the reference to rounding (tests/test_fast.py: 1e-9 to t = 50 on every shipped scenario).
Compiled once per machine (``cache=True`` keeps the machine code in __pycache__); no ROS
process imports this module.
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from .command_plan import CHOOSE_RISE
from .faults import event_names
from .fast_radio import radio_arguments, radio_control, radio_receive, radio_state, radio_stats
from .pair_sums import DENSE_LIMIT
from .schedules import ConstantLambda, ConstantSteering, SinusoidSteering, TanhWindow
from .trajectory import Trajectory

#: law kinds the kernel covers → code (effective λ, q0 as `LawConfig.effective_lambda_q0`)
LAW_CODES = {'global': 0, 'local': 1, 'leader_following': 2, 'homotopy': 3, 'target': 4}


def fallback_reason(scn, integrator=None, commands=None) -> str | None:
    """None if the fast kernel covers this run, else why the reference engine runs it."""
    spec = scn.spec
    checks = (
        ((integrator or spec.integrator) != 'zoh', 'integrator rk4'),
        (bool(commands), 'live commands'),
        (scn.law.kind not in LAW_CODES, f'law {scn.law.kind}'),
        (len(scn.names) > DENSE_LIMIT, f'more than {DENSE_LIMIT} agents'),
        (bool(spec.faults) or spec.failover is not None, 'faults or failover'),
        (bool(spec.reunion), 'reunion'),
        (spec.comms is not None and _has_radio_events(scn), 'radio events'),
    )
    for bad, why in checks:
        if bad:
            return why
    plan = scn.command_plan()
    progs = list(plan.fixed_leaders.values()) + list(plan.rule_programs)
    if any(not isinstance(p, (ConstantSteering, SinusoidSteering)) for p in progs):
        return 'steering program other than constant or sinusoid'
    return None


def _has_radio_events(scn) -> bool:
    """Whether the scenario's radio changes in time (scheduled ``comms.events``: not covered)."""
    model = scn.comm_model()
    return model is not None and bool(model.events)


# ------------------------------------------------------------------ kernels

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
    `laws.barrier_term`); world = (target on, x, y, γ, normalised, barrier on, s_b, literal)."""
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
def _frames(theta, c, s):
    """(cos θ, sin θ) through the planar quaternion, as `frenet.heading_frame`."""
    for k in range(theta.size):
        half = 0.5 * theta[k]
        qz, qw = math.sin(half), math.cos(half)
        c[k] = qw * qw - qz * qz
        s[k] = 2.0 * qw * qz


@njit(cache=True)
def _lateral_extremes(x, y, c, s):
    """(left, right) as `command_plan.lateral_extremes`."""
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
    the rule chose the leaders (−1: none).  radio: `fast_radio.radio_arguments`."""
    n = x.size
    steps = lams.size - 1
    alpha, eta, mu, r0, w, leader_gain = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5]
    c, s, u, steer = np.empty(n), np.empty(n), np.zeros(n), np.zeros(n)   # u: the last step's, sent
    on = radio[0][0] != 0.0
    state = radio_state(n if on else 0, max(1, radio[4].size - 2), int(radio[0][4]))
    mom = np.empty((6, n))
    is_leader = leader_prog >= 0
    pending = rule and not is_leader.any()
    chosen = -1
    lam_low = np.inf
    for i in range(steps + 1):
        t = i * dt
        _frames(theta, c, s)
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
        lead = is_leader if code == 2 or code == 3 else np.zeros(n, np.bool_)
        if on:
            radio_receive(i, x, y, theta, u, radio, state)
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


# ------------------------------------------------------------------ the run

def _lambdas(schedule, steps, dt):
    """λ(t_i) of every step i, as the commander evaluates it (t_i = i·dt)."""
    t = np.arange(steps + 1) * dt
    if isinstance(schedule, TanhWindow):
        s = schedule
        return _tanh_window(t, s.rise_at, s.fall_at, s.tau, s.low, s.high)
    if isinstance(schedule, ConstantLambda):
        return np.full(steps + 1, float(schedule.value(0.0)))
    return np.array([float(schedule.value(i * dt)) for i in range(steps + 1)])


def _program_rows(progs):
    """(P, 5) rows (kind, a, b, c, d) of steering programs (see `_steering`)."""
    rows = np.zeros((max(1, len(progs)), 5))
    for i, p in enumerate(progs):
        if isinstance(p, ConstantSteering):
            rows[i, :2] = (0.0, p.curvature)
        else:
            rows[i] = (1.0, p.amplitude, p.period, p.phase, p.offset)
    return rows


def _world(scn):
    """(world, barrier points) of `_world_terms`: the target and barrier terms where the
    scenario has them and their gains are not 0 (as `laws._add_world_terms`)."""
    law = scn.law
    world, barrier = np.zeros(8), np.zeros((0, 2))
    if scn.target is not None and law.target_gain != 0.0:
        world[:5] = (1.0, *scn.target, law.target_gain, float(law.target_normalised))
    if scn.barrier is not None and law.barrier_gain != 0.0 and len(scn.barrier):
        world[5:] = (1.0, law.barrier_gain, float(law.barrier_mode == 'literal'))
        barrier = scn.barrier
    return world, barrier


def _noise(scn, steps):
    """(steps, n, 3) noise of every step, from each agent's own stream (as the reference draws
    it, three numbers per step), or an empty array without noise."""
    noise = scn.spec.noise
    scale = np.array([noise.position, noise.position, noise.heading])
    n = len(scn.names)
    if not np.any(scale > 0):
        return np.zeros((0, n, 3))
    draws = np.stack([scn.noise_rng(i).uniform(-1.0, 1.0, size=(steps, 3)) for i in range(n)], axis=1)
    return draws * scale


def simulate(scn, *, integrator=None, record_every: int = 1, neighbour_search: str = 'auto',
             progress=None, commands=None) -> Trajectory:
    """`engine.simulate` on the fast kernel where it covers the run (`fallback_reason`), else
    the reference engine; ``meta['engine']`` says which ran (and ``meta['fallback']`` why)."""
    reason = fallback_reason(scn, integrator, commands)
    if reason is not None:
        from . import engine
        traj = engine.simulate(scn, integrator=integrator, record_every=record_every,
                               neighbour_search=neighbour_search, progress=progress, commands=commands)
        traj.meta.update(engine='reference', fallback=reason)
        return traj
    wall = time.perf_counter()
    law, plan, steps, n = scn.law, scn.command_plan(), scn.steps, len(scn.names)
    g = law.gains
    gains = np.array([g.alpha, g.eta, g.mu, g.r0, law.cutoff_radius, law.leader_gain])
    rule = plan.rule is not None
    leader_prog = np.full(n, -1, dtype=np.int64)
    if rule:
        progs = list(plan.rule_programs)
    else:
        progs = list(plan.fixed_leaders.values())
        leader_prog[list(plan.fixed_leaders)] = np.arange(len(progs))
    rows = steps // record_every + 1
    r, th, u = np.empty((rows, n, 2)), np.empty((rows, n)), np.empty((rows, n))
    lead = np.empty((rows, n), dtype=bool)
    lams = _lambdas(plan.schedule, steps, scn.dt)
    model = scn.comm_model()
    radio = radio_arguments(model, n)
    chosen = _run(scn.pos0[:, 0].copy(), scn.pos0[:, 1].copy(), scn.theta0.astype(float),
                  float(scn.dt), lams, LAW_CODES[law.kind], float(law.q0), gains, leader_prog,
                  _program_rows(progs), rule, float(plan.choose_at), CHOOSE_RISE, *_world(scn), _noise(scn, steps),
                  radio, int(record_every), r, th, u, lead)
    events = []
    if chosen >= 0:
        slots = [int(k) for k in sorted(np.flatnonzero(leader_prog >= 0), key=lambda k: leader_prog[k])]
        events.append(event_names(dict(t=chosen * scn.dt, kind='leaders_chosen',
                                       leaders=sorted(slots), slots=slots), scn.names))
    if progress is not None:
        progress(steps, steps)
    every = slice(None, None, record_every)
    meta = dict(scenario=scn.name, seed=scn.seed, dt=scn.dt, duration=scn.duration,
                integrator='zoh', steps=steps, record_every=record_every,
                wall_seconds=time.perf_counter() - wall, neighbour_search=neighbour_search,
                interrupted=False, events=events, engine='fast')
    if model is not None:
        meta['comms'] = radio_stats(radio[4], scn.dt)
    return Trajectory(scn.names, (np.arange(steps + 1) * scn.dt)[every], r, th, u, lams[every], lead, meta)


def warm_up() -> float:
    """Compile the kernels (or load them from numba's cache) on a two-agent, two-step run;
    returns the seconds it took.  A study calls it once before forking its workers."""
    t0 = time.perf_counter()
    n, steps = 2, 2
    r, th, u = np.empty((steps + 1, n, 2)), np.empty((steps + 1, n)), np.empty((steps + 1, n))
    _run(np.array([0.0, 1.0]), np.zeros(n), np.zeros(n), 0.1, _tanh_window(np.arange(steps + 1) * 0.1,
         400.0, 600.0, 30.0, 0.0, 1.0), 3, 1.0, np.array([0.02, 0.02, 0.02, 1.5, 4.0, 30.0]),
         np.full(n, -1, dtype=np.int64), _program_rows([ConstantSteering(0.01)]), True, 0.0, CHOOSE_RISE,
         np.zeros(8), np.zeros((0, 2)), np.zeros((0, n, 3)), radio_arguments(None, n), 1, r, th, u, np.empty((steps + 1, n), dtype=bool))
    return time.perf_counter() - t0
