"""The paper's behaviours as checks on metric time series (no ROS).

A scenario's ``expect`` mapping names the checks; each returns (passed, details).  `swarm
simulate` reports them, `swarm sweep` counts how often they pass over seeds, and the tests
assert them.  Checks:

- ``one_cluster_at: [a, b]``      one cluster at every sample in [a, b]
- ``polarisation_above: {at, value}``
- ``split_between: [a, b]``       at some t in [a, b]: as many clusters as leaders (two),
                                  one leader in each (Figs. 3, 4)
- ``one_cluster_at_end: true``    one cluster at the end (Fig. 3 reforms)
- ``stays_split_from: t0``        at least two clusters at every sample from t0 on (Fig. 4)
- ``no_intrusion: true``          no agent inside the barrier's hull at any recorded step
- ``split_near_x: [x0, x1]``      ≥ 2 clusters while the centroid's x is in [x0, x1] (Fig. 5)
- ``rejoins_after_x: [x0, x1]``   one cluster again at some sample with centroid x in [x0, x1]
- ``arrives_within: d``           the centroid comes within d of the target
- ``split_at: t``                 at least two clusters at the sample nearest t
- ``one_cluster_from: t0``        one cluster at every sample from t0 to the end (reunion)
- ``follows_program: {slot, from, to, tolerance}``  (faults.py, needs the trajectory and its
                                  events) the lost leader's subswarm — the agents in the
                                  cluster of the leader of ``slot`` at the last sample before it
                                  was killed, minus it — turns, over [from, to], at the rate of
                                  that slot's steering program s (constant curvature):
                                  |turn rate − s| ≤ tolerance·|s|; the turn rate is the slope
                                  of the group's mean heading (a line fit).  Without a leader
                                  the subswarm flies straight (turn rate ≈ 0) and fails.
- ``circular_formation: {at, omega0, spread_below, turn_rate_within}``  (needs the trajectory)
                                  the Sepulchre-Paley-Leonard circular formation at the sample
                                  nearest ``at``: the centres c_k = r_k + i e^{iθ_k}/ω0 gather,
                                  max_k |c_k − mean c|·ω0 < spread_below (relative to the radius
                                  1/ω0), and every agent turns at ω0, max_k |u_k − ω0| <
                                  turn_rate_within (rad per unit time); ``omega0`` defaults to
                                  the ω0 of the scenario's spl_circular law (or a blend's).
                                  t_formed: from when both held at every sample up to ``at``.
- ``splay_state: {at, below}``    (needs the trajectory) the phases are evenly spread: at the
                                  sample nearest ``at``, max over m = 1..N−1 of
                                  |(1/N) Σ_j e^{imθ_j}| (= m |p_mθ|) < below; harmonic: that m,
                                  t_splay: from when it held at every sample up to ``at``.
Dead agents (NaN rows) are left out of every sample (metrics.time_series).

A run that ends before the scenario's duration (``--duration``, Ctrl-C) cannot settle every
check: a check that needs time the run did not reach is reported ``passed: None`` with
``not_judged`` saying why, unless what ran already settles it (a split that happened, an
intrusion or a second cluster inside a window that must have one cluster).
"""
from __future__ import annotations

import warnings

import numpy as np

from swarm_core.analysis.metrics import cluster_labels

TRAJECTORY_CHECKS = ('follows_program', 'circular_formation', 'splay_state')


def _window(series, a, b):
    t = series['t']
    return (t >= a - 1e-9) & (t <= b + 1e-9)


def _first_t(series, mask):
    idx = np.flatnonzero(mask)
    return None if idx.size == 0 else float(series['t'][idx[0]])


def check(name, arg, series, n_leaders_max=2):
    c = series['clusters']
    t = series['t']
    if name == 'one_cluster_at':
        win = _window(series, *arg)
        return bool(win.any() and np.all(c[win] == 1)), {'max_clusters': int(c[win].max()) if win.any() else None}
    if name == 'polarisation_above':
        i = int(np.argmin(np.abs(t - arg['at'])))
        p = float(series['polarisation'][i])
        return p > arg['value'], {'polarisation': round(p, 6)}
    if name == 'split_between':
        win = _window(series, *arg)
        ok = win & (c == n_leaders_max) & series['one_leader_per_cluster']
        return bool(ok.any()), {'t_split': _first_t(series, ok)}
    if name == 'one_cluster_at_end':
        ok = bool(c[-1] == 1) == bool(arg)
        not_one = np.flatnonzero(c != 1)
        t_reform = None
        if c[-1] == 1:
            t_reform = float(t[not_one[-1] + 1]) if not_one.size else float(t[0])
        return ok, {'final_clusters': int(c[-1]), 't_reform': t_reform}
    if name == 'stays_split_from':
        win = t >= arg - 1e-9
        return bool(win.any() and np.all(c[win] >= 2)), {'min_clusters_after': int(c[win].min()) if win.any() else None,
                                                         'final_clusters': int(c[-1])}
    if name == 'no_intrusion':
        total = int(series.get('intrusions_total', 0))
        return (total == 0) == bool(arg), {'intrusions_total': total,
                                           'barrier_clearance': series.get('barrier_clearance')}
    if name in ('split_near_x', 'rejoins_after_x'):
        x = series['centroid'][:, 0]
        near = (x >= arg[0]) & (x <= arg[1])
        ok = near & ((c >= 2) if name == 'split_near_x' else (c == 1))
        key = 'max_clusters_near' if name == 'split_near_x' else 't_rejoin'
        val = int(c[near].max()) if (name == 'split_near_x' and near.any()) else _first_t(series, ok)
        return bool(ok.any()), {key: val}
    if name == 'arrives_within':
        d = series['centroid_target_distance']
        ok = d < arg
        return bool(ok.any()), {'t_arrival': _first_t(series, ok), 'closest': round(float(d.min()), 3)}
    if name == 'split_at':
        i = int(np.argmin(np.abs(t - arg)))
        return bool(c[i] >= 2), {'clusters': int(c[i])}
    if name == 'one_cluster_from':
        win = t >= arg - 1e-9
        bad = np.flatnonzero(win & (c != 1))
        return bool(win.any() and bad.size == 0), {
            'last_not_one': float(t[bad[-1]]) if bad.size else None,
            'max_clusters_after': int(c[win].max()) if win.any() else None}
    raise ValueError(f'unknown expectation {name!r}')


def group_turn_rate(traj, group, a, b):
    """Slope (rad per unit time) of the circular-mean heading of ``group`` over [a, b]."""
    sel = (traj.t >= a - 1e-9) & (traj.t <= b + 1e-9)
    th = traj.theta[sel][:, group]
    ang = np.unwrap(np.arctan2(np.nanmean(np.sin(th), axis=1), np.nanmean(np.cos(th), axis=1)))
    if ang.size < 2:
        return float('nan')
    return float(np.polyfit(traj.t[sel], ang, 1)[0])


def lost_leader_group(traj, w, slot=None, agent=None):
    """(killed leader index, its subswarm (indices), kill time) from the trajectory's events:
    the agents in the leader's cluster at the last sample before the kill, minus the leader."""
    names = list(traj.names)
    for ev in traj.meta.get('events') or []:
        if ev.get('kind') != 'kill':
            continue
        if (slot is not None and ev.get('slot') == slot) or (agent is not None and ev.get('agent') == agent):
            k = names.index(ev['agent'])
            before = np.flatnonzero(traj.t < ev['t'] - 1e-9)
            if before.size == 0:
                return k, [], ev['t']
            r = traj.r[before[-1]]
            ok = np.flatnonzero(np.isfinite(r).all(axis=1))
            _, labels = cluster_labels(r[ok], w)
            lab = dict(zip(ok, labels))
            group = [int(j) for j in ok if lab[j] == lab[k] and j != k]
            return k, group, float(ev['t'])
    return None, [], None


def circular_law_omega0(law):
    """ω0 of a law whose agents fly one circle (its ``circle_turn_rate``: spl_circular), or of
    the first one in a blend (the to-law first); None if none."""
    for side in (law, getattr(law, 'to_law', None), getattr(law, 'from_law', None)):
        rate = getattr(side, 'circle_turn_rate', None)
        if rate is not None:
            return rate()
    return None


def circle_centres(r, theta, omega0):
    """c_k = r_k + i e^{iθ_k}/ω0, the centre of the circle agent k would fly at u_k = ω0."""
    return r[..., 0] + 1j * r[..., 1] + 1j * np.exp(1j * theta) / omega0


#: the history of `circular_formation` and `splay_state` (t_formed, t_splay) is judged on at
#: most this many samples up to ``at`` (evenly spaced; the sample nearest ``at`` always)
HISTORY_SAMPLES = 2000


def _history(traj, at):
    """Sample indices up to the one nearest ``at`` (the last), at most HISTORY_SAMPLES + 1."""
    i = int(np.argmin(np.abs(traj.t - at)))
    idx = np.arange(0, i + 1, max(1, -(-(i + 1) // HISTORY_SAMPLES)))
    return idx if idx[-1] == i else np.append(idx, i)


def circular_formation_series(traj, omega0, idx):
    """(spread, turn rate error) of the samples ``idx``: max_k |c_k − mean c|·ω0 and
    max_k |u_k − ω0| over the agents alive at each sample (NaN where none is)."""
    r, th, u = traj.r[idx], traj.theta[idx], traj.u[idx]
    alive = np.isfinite(r).all(axis=2) & np.isfinite(th)
    c = circle_centres(np.where(alive[..., None], r, 0.0), np.where(alive, th, 0.0), omega0)
    n = alive.sum(axis=1)
    with np.errstate(all='ignore'), warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)       # samples with nobody alive: NaN
        mean = np.where(alive, c, 0.0).sum(axis=1) / n
        spread = np.nanmax(np.where(alive, np.abs(c - mean[:, None]), np.nan), axis=1) * omega0
        turn = np.nanmax(np.where(alive & np.isfinite(u), np.abs(u - omega0), np.nan), axis=1)
    return spread, turn


def splay_order_series(traj, idx):
    """(order, harmonic) of the samples ``idx``: max over m = 1..N−1 of |(1/N) Σ_j e^{imθ_j}|
    over the N agents alive at each sample, and the lowest m where it is largest (0 for N < 2)."""
    th = traj.theta[idx]
    alive = np.isfinite(traj.r[idx]).all(axis=2) & np.isfinite(th)
    n = alive.sum(axis=1)
    m = np.arange(1, th.shape[1])
    order, worst = np.zeros(len(idx)), np.zeros(len(idx), dtype=int)
    if not m.size:
        return order, worst
    block = max(1, 1_000_000 // (m.size * th.shape[1]))
    for a in range(0, len(idx), block):
        z = np.exp(1j * m[None, :, None] * np.where(alive, th, 0.0)[a:a + block, None, :])
        with np.errstate(all='ignore'):
            val = np.abs((z * alive[a:a + block, None, :]).sum(axis=2)) / n[a:a + block, None]
        val = np.where(m[None, :] < n[a:a + block, None], val, -np.inf)   # m = 1..N−1 of the alive
        top = val.max(axis=1)
        order[a:a + block] = np.maximum(top, 0.0)
        first = np.argmax(val >= top[:, None] - 1e-12, axis=1)        # the lowest m of a tie
        worst[a:a + block] = np.where(n[a:a + block] >= 2, m[first], 0)
    return order, worst


def _held_from(t, ok):
    """The first t from which ``ok`` holds at every sample to the last given; None if not at the last."""
    if not ok.size or not ok[-1]:
        return None
    bad = np.flatnonzero(~ok)
    return round(float(t[bad[-1] + 1] if bad.size else t[0]), 6)


def _sig(x, digits=4):
    """``x`` to ``digits`` significant digits (the small numbers these checks report)."""
    return float(f'{float(x):.{digits}g}')


def check_trajectory(name, arg, traj, scn):
    if name == 'circular_formation':
        omega0 = arg.get('omega0')
        if omega0 is None:
            omega0 = None if scn is None else circular_law_omega0(scn.law)
        if omega0 is None:
            raise ValueError('circular_formation: give omega0 (the law is not spl_circular nor a blend with one)')
        omega0 = float(omega0)
        idx = _history(traj, arg['at'])
        spread, turn = circular_formation_series(traj, omega0, idx)
        ok = (spread < arg['spread_below']) & (turn < arg['turn_rate_within'])
        return bool(ok[-1]), {'spread': _sig(spread[-1]), 'turn_rate_error': _sig(turn[-1]),
                              'omega0': omega0, 't_formed': _held_from(traj.t[idx], ok)}
    if name == 'splay_state':
        idx = _history(traj, arg['at'])
        order, worst = splay_order_series(traj, idx)
        ok = order < arg['below']
        return bool(ok[-1]), {'order': _sig(order[-1]), 'harmonic': int(worst[-1]),
                              't_splay': _held_from(traj.t[idx], ok)}
    if name == 'follows_program':
        slot = int(arg.get('slot', 0))
        progs = scn.spec.leaders.programs or list(scn.spec.leaders.fixed.values())
        prog = progs[slot] if slot < len(progs) else None
        if prog is None or prog.kind != 'constant':
            raise ValueError(f'follows_program: slot {slot} needs a constant steering program')
        s = float(prog.curvature)
        k, group, t_kill = lost_leader_group(traj, scn.law.cutoff_radius, slot=slot)
        if k is None or not group:
            return False, {'turn_rate': None, 'program': s, 'group': None}
        rate = group_turn_rate(traj, group, arg['from'], arg['to'])
        tol = float(arg.get('tolerance', 0.3)) * abs(s)
        successor = [ev.get('agent') for ev in traj.meta.get('events') or []
                     if ev.get('kind') == 'failover' and ev.get('slot') == slot]
        return bool(abs(rate - s) <= tol), {'turn_rate': round(rate, 6), 'program': s,
                                            'group_size': len(group), 't_kill': t_kill,
                                            'successor': successor[0] if successor else None}
    raise ValueError(f'unknown expectation {name!r}')


#: checks settled by one sample (a pass stands once seen) and checks that a single sample
#: can break (a failure stands once seen), when the run is shorter than the scenario
_PASS_STANDS = ('split_between', 'split_near_x', 'rejoins_after_x', 'arrives_within')
_FAIL_STANDS = {'one_cluster_at': 'max_clusters', 'stays_split_from': 'min_clusters_after',
                'one_cluster_from': 'max_clusters_after', 'no_intrusion': 'intrusions_total'}


def needs_until(name, arg, duration):
    """The time up to which a check looks at the run (the scenario's ``duration`` for the
    checks about the end, and for the spatial ones, whose time is not known beforehand)."""
    if name in ('one_cluster_at', 'split_between'):
        return float(arg[1])
    if name == 'polarisation_above':
        return float(arg['at'])
    if name == 'split_at':
        return float(arg)
    if name == 'follows_program':
        return float(arg['to'])
    if name in ('circular_formation', 'splay_state'):
        return float(arg['at'])
    if name in ('stays_split_from', 'one_cluster_from'):
        return max(float(arg), float(duration))     # a run that ends before t0 cannot judge it
    return float(duration)


def evaluate(expect: dict, series, traj=None, scn=None) -> dict:
    """{check name: {'passed': bool or None, ...details}} for every check in ``expect``;
    checks in TRAJECTORY_CHECKS need the trajectory (with its events) and the scenario.  With
    the scenario given, a run that ends before its duration leaves unsettled checks
    ``passed: None`` (module docstring)."""
    out = {}
    t_end = float(series['t'][-1]) if len(series['t']) else 0.0
    if traj is not None and len(traj.t):
        t_end = float(traj.t[-1])
    for name, arg in expect.items():
        if name in TRAJECTORY_CHECKS:
            if traj is None:
                continue
            passed, details = check_trajectory(name, arg, traj, scn)
        else:
            passed, details = check(name, arg, series)
        res = {'passed': bool(passed), **details}
        if scn is not None:
            need = needs_until(name, arg, scn.duration)
            settled = ((passed and name in _PASS_STANDS) or           # seen in the samples that ran
                       (not passed and details.get(_FAIL_STANDS.get(name)) is not None))
            if need > t_end + 0.5 * scn.dt and not settled:
                res = {'passed': None, 'not_judged': f'the run ends at t = {t_end:g}, the check needs t = {need:g}'}
        out[name] = res
    return out
