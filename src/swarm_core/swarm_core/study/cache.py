"""The study cache (no ROS): one JSON file per finished run, checked before it is used.

A cached file is a row of the study's table only if it passes `check_row`: a mapping with the
run's own cell and seed and a ``result`` of the row schema (`run_task`'s row: ``ok`` and every
check True/False/None; every other value None, a bool or a finite number; cluster counts whole
numbers from 1 to the run's agents; ``ok`` the verdict of the checks).  A file that fails
(hand-edited, truncated, ``[]``, ``1e999``) is run again with one warning.  What the check
cannot catch is a forged row that passes it (docs/studies.md)."""
from __future__ import annotations

import json
import math
import numbers
from pathlib import Path

from swarm_core.checks import json_value
from swarm_core.files import write_atomic

#: metrics taken from `analysis.summary_of` into every row
ROW_METRICS = ('final_clusters', 'max_clusters', 'min_distance', 'final_polarisation',
               'intrusions_total', 'closest_centroid_target_distance')
#: metrics of a run on the robot engine (`swarm_robots.engine`, ``meta['robots']``) in its row
ROBOT_METRICS = ('contacts', 'collisions', 'turn_limit_fraction', 'iae_mean')
#: the times of a row (`study.run_task`)
ROW_TIMES = ('t_first_split', 't_last_one')
#: longest cache file (a row is a few kB)
MAX_ROW_CHARS = 1 << 20
#: row values that count clusters (1 … the number of agents)
CLUSTER_COUNTS = ('final_clusters', 'max_clusters')
#: row values that are never negative (distances, counts, times), and polarisation in [0, 1]
NON_NEGATIVE = ('min_distance', 'intrusions_total', 'closest_centroid_target_distance', 't_first_split',
                't_last_one') + ROBOT_METRICS


def _scalar(v) -> bool:
    return v is None or isinstance(v, bool) or (isinstance(v, numbers.Real) and math.isfinite(v))


def _verdict(checks: dict):
    """The row's ``ok`` from its checks' verdicts (as `analysis.behaviour_ok`)."""
    if not checks or any(v is False for v in checks.values()):
        return False if checks else None
    return None if any(v is None for v in checks.values()) else True


def row_error(doc, cell: dict, seed: int, agents: int):
    """Why ``doc`` (a cached file's value) is not the row of the run (``cell``, ``seed``) of a
    scenario with ``agents`` agents, or None if it is."""
    if not isinstance(doc, dict) or not isinstance(doc.get('result'), dict):
        return 'not a mapping with a result'
    if doc.get('cell') != cell or doc.get('seed') != seed or isinstance(doc.get('seed'), bool):
        return 'the cell or seed of another run'
    res = doc['result']
    bad = next((k for k, v in res.items() if not isinstance(k, str) or not _scalar(v)), None)
    if bad is not None:
        return f'{bad}: {res[bad]!r} is not a finite number, a bool or null'
    checks = {k: v for k, v in res.items()
              if '.' not in k and k not in ('ok',) + ROW_METRICS + ROW_TIMES + ROBOT_METRICS}
    if any(not (v is None or isinstance(v, bool)) for v in checks.values()):
        return 'a check whose verdict is not true, false or null'
    if 'ok' not in res or res['ok'] != _verdict(checks) or not (res['ok'] is None or isinstance(res['ok'], bool)):
        return f'ok: {res.get("ok")!r} is not the verdict of the checks'
    for k in CLUSTER_COUNTS:
        v = res.get(k)
        if v is not None and (isinstance(v, bool) or v != int(v) or not 1 <= v <= agents):
            return f'{k}: {v!r} is not a count of clusters of {agents} agents'
    for k in NON_NEGATIVE:
        v = res.get(k)
        if v is not None and (isinstance(v, bool) or v < 0):
            return f'{k}: {v!r} is negative'
    pol = res.get('final_polarisation')
    if pol is not None and (isinstance(pol, bool) or not 0.0 <= pol <= 1.0 + 1e-9):
        return f'final_polarisation: {pol!r} is not in [0, 1]'
    return None


class Cache:
    """One JSON file per finished run under ``root`` (written atomically)."""

    def __init__(self, root):
        self.root = Path(root)
        self.root.mkdir(parents=True, exist_ok=True)

    def path(self, key):
        return self.root / f'{key}.json'

    def get(self, key):
        """The file's JSON value; None if there is none or it is not JSON (or too long)."""
        p = self.path(key)
        try:
            with open(p, encoding='utf-8') as fh:
                return json_value(fh.read(MAX_ROW_CHARS + 1), MAX_ROW_CHARS)
        except (OSError, ValueError):
            return None

    def put(self, key, doc):
        write_atomic(self.path(key), json.dumps(doc))
