"""The study cache (no ROS): one JSON file per finished run, checked before it is used.

A cached file is a row of the study's table only if it is a regular file (not a symbolic
link, a directory, a FIFO, a device or a socket: `Cache.read` never opens one, so a FIFO
cannot hang the study) and passes `row_error`: a mapping with the run's own key, cell and seed
and a ``result`` of the row schema (`run_task`'s row: ``ok`` and every check True/False/None;
every other value None, a bool or a finite number; cluster counts whole numbers from 1 to the
run's agents; ``ok`` the verdict of the checks).  An entry that fails (hand-edited, truncated,
``[]``, ``1e999``, another key's file, a planted link) is run again with one warning; a result
is written over a regular file only (`Cache.put`).  What the check cannot catch is a forged
row that passes it (docs/studies.md)."""
from __future__ import annotations

import errno
import json
import math
import numbers
import os
import stat
from pathlib import Path

from swarm_core.checks import json_value
from swarm_core.files import _KINDS, write_atomic

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
    """The row's ``ok`` from its checks' verdicts (as `swarm_core.analysis.outputs.behaviour_ok`)."""
    if not checks or any(v is False for v in checks.values()):
        return False if checks else None
    return None if any(v is None for v in checks.values()) else True


def row_error(doc, cell: dict, seed: int, agents: int, key=None):
    """Why ``doc`` (a cached file's value) is not the row of the run (``cell``, ``seed``, cache
    ``key`` if given) of a scenario with ``agents`` agents, or None if it is."""
    if not isinstance(doc, dict) or not isinstance(doc.get('result'), dict):
        return 'not a mapping with a result'
    if key is not None and doc.get('key') != key:
        return 'the file of another run (its key is not this one)'
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

    def read(self, key):
        """(the entry's JSON value, None), (None, None) if there is no entry, or (None, why it
        is not one): not a regular file (never opened: a FIFO would block; opened without
        following a link and without blocking, so one planted meanwhile is refused too), not
        readable, too long or not JSON."""
        p = self.path(key)
        try:
            why = _not_regular(os.lstat(p).st_mode)
            if why:
                return None, why
            fd = os.open(p, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
        except FileNotFoundError:
            return None, None
        except OSError as err:
            return None, 'a symbolic link' if err.errno == errno.ELOOP else f'not readable ({err.strerror})'
        try:
            why = _not_regular(os.fstat(fd).st_mode)
            if why:
                return None, why
            with os.fdopen(fd, encoding='utf-8') as fh:
                fd = None
                return json_value(fh.read(MAX_ROW_CHARS + 1), MAX_ROW_CHARS), None
        except (OSError, ValueError) as err:
            return None, f'not JSON ({err})' if isinstance(err, ValueError) else f'not readable ({err.strerror})'
        finally:
            if fd is not None:
                os.close(fd)

    def get(self, key):
        """The entry's JSON value; None if there is none or it is not one (`read`)."""
        return self.read(key)[0]

    def writable(self, key) -> bool:
        """Whether `put` can write the entry: absent or a regular file (not a link, a
        directory, a FIFO ...: those are never written through or replaced)."""
        try:
            return not _not_regular(os.lstat(self.path(key)).st_mode)
        except FileNotFoundError:
            return True

    def put(self, key, doc):
        """Write the entry (with its key, `row_error`) atomically; OSError (`files.write_atomic`)
        if something that is not a regular file is at its path."""
        write_atomic(self.path(key), json.dumps(dict(doc, key=key)))


def _not_regular(mode: int):
    """What a cache entry of ``mode`` (lstat) is if it is not a regular file (else None)."""
    if stat.S_ISREG(mode):
        return None
    return next((kind for test, kind in _KINDS if test(mode)), 'not a regular file')
