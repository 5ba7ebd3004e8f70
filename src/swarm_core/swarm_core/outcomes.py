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
"""
from __future__ import annotations

import numpy as np


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
    raise ValueError(f'unknown expectation {name!r}')


def evaluate(expect: dict, series) -> dict:
    """{check name: {'passed': bool, ...details}} for every check in ``expect``."""
    out = {}
    for name, arg in expect.items():
        passed, details = check(name, arg, series)
        out[name] = {'passed': bool(passed), **details}
    return out
