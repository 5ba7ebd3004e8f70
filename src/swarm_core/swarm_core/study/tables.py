"""The tables of a parameter study (no ROS): the tidy table of its runs, pass rates per cell
with Wilson confidence intervals, as CSV or Markdown, and their figure (`study.run_study`
makes the rows: one per run, every parameter, the seed, every check and metric)."""
from __future__ import annotations

import csv
import io
import math

import numpy as np

from swarm_core.files import atomic_path
from swarm_core.study.cache import ROBOT_METRICS, ROW_METRICS
from swarm_core.study.grid import Study


def table_columns(study: Study, rows) -> list:
    cols = study.params + ['seed', 'ok']
    for r in rows:
        for k in r:
            if k not in cols:
                cols.append(k)
    return cols


def _cell_str(v):
    if v is None:
        return ''
    if isinstance(v, float):
        return repr(v)
    return str(v)


def to_csv(study: Study, rows) -> str:
    """The tidy table: one row per run, every parameter, the seed, every check and metric."""
    cols = table_columns(study, rows)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator='\n')
    w.writerow(cols)
    for r in rows:
        w.writerow([_cell_str(r.get(c)) for c in cols])
    return buf.getvalue()


def to_parquet(study: Study, rows, path):
    """The tidy table of `to_csv` as Parquet at ``path`` (written atomically): the same
    columns and rows, each column typed (bool, int64, double or string; missing values null)."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    cols = table_columns(study, rows)
    arrays = []
    for c in cols:
        vals = [r.get(c) for r in rows]
        try:
            arrays.append(pa.array(vals))
        except (pa.ArrowInvalid, pa.ArrowTypeError):    # mixed kinds: as the CSV writes them
            arrays.append(pa.array([None if v is None else _cell_str(v) for v in vals], pa.string()))
    with atomic_path(path, '.parquet') as tmp:
        pq.write_table(pa.Table.from_arrays(arrays, names=cols), tmp)
    return path


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval (95 % by default) of a binomial rate k/n."""
    if n == 0:
        return (float('nan'), float('nan'))
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def check_names(rows, params=()) -> list:
    """'ok' and the checks' names (the boolean columns that are not parameters nor metrics)."""
    names = ['ok']
    for r in rows:
        for k, v in r.items():
            if '.' not in k and k not in names and k not in params and k != 'seed' \
                    and (isinstance(v, bool) or v is None) \
                    and k not in ('t_first_split', 't_last_one') and k not in ROW_METRICS + ROBOT_METRICS:
                names.append(k)
    return names


def rates(study: Study, rows) -> list[dict]:
    """Per cell and check ('ok': all checks): passed, judged n, rate and its 95 % Wilson CI.
    A run whose check was not judged (None) is left out of n."""
    out = []
    names = check_names(rows, study.params)
    for cell in study.cells():
        sel = [r for r in rows if all(r.get(k) == v for k, v in cell.items())]
        for c in names:
            vals = [r.get(c) for r in sel if r.get(c) is not None]
            k, n = sum(bool(v) for v in vals), len(vals)
            lo, hi = wilson(k, n)
            out.append({**cell, 'check': 'all' if c == 'ok' else c, 'passed': k, 'n': n,
                        'rate': k / n if n else float('nan'), 'ci_low': lo, 'ci_high': hi})
    return out


def rates_csv(study: Study, rates_rows) -> str:
    cols = study.params + ['check', 'passed', 'n', 'rate', 'ci_low', 'ci_high']
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator='\n')
    w.writerow(cols)
    for r in rates_rows:
        w.writerow([_cell_str(round(r[c], 4) if isinstance(r[c], float) else r[c]) for c in cols])
    return buf.getvalue()


def rates_markdown(study: Study, rates_rows, checks=None) -> str:
    """A Markdown table: one row per cell, one column per check with 'k/n (lo–hi)'."""
    names = list(dict.fromkeys(r['check'] for r in rates_rows))
    if checks:
        names = [c for c in names if c in checks]
    head = study.params + [f'{c}' for c in names]
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for cell in study.cells():
        sel = {r['check']: r for r in rates_rows if all(r.get(k) == v for k, v in cell.items())}
        vals = [f'{v:g}' if isinstance(v, float) else str(v) for v in cell.values()]
        for c in names:
            r = sel[c]
            vals.append(f'{r["passed"]}/{r["n"]} ({r["ci_low"]:.2f}–{r["ci_high"]:.2f})' if r['n'] else 'n/a')
        lines.append('| ' + ' | '.join(vals) + ' |')
    return '\n'.join(lines)


def robot_metrics_markdown(study: Study, rows) -> str:
    """Per cell, the robot engine's metrics over its seeds (`swarm_core.study.cache.ROBOT_METRICS`): the
    mean of each, and the smallest min_distance; '' when no row has them."""
    if not any('iae_mean' in r for r in rows):
        return ''
    head = study.params + ['runs', 'min distance (least, mean)', 'collisions', 'contacts', 'time at ω limit',
                           'IAE of u']
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for cell in study.cells():
        sel = [r for r in rows if all(r.get(k) == v for k, v in cell.items())]
        mean = {k: np.mean([r[k] for r in sel if r.get(k) is not None] or [np.nan]) for k in ROBOT_METRICS}
        dist = [r['min_distance'] for r in sel if r.get('min_distance') is not None] or [np.nan]
        vals = [f'{v:g}' if isinstance(v, float) else str(v) for v in cell.values()]
        vals += [str(len(sel)), f'{min(dist):.3g}, {np.mean(dist):.3g}', f'{mean["collisions"]:.2g}',
                 f'{mean["contacts"]:.2g}', f'{100 * mean["turn_limit_fraction"]:.2g} %', f'{mean["iae_mean"]:.3g}']
        lines.append('| ' + ' | '.join(vals) + ' |')
    return '\n'.join(lines)


def plot_rates(study: Study, rates_rows, path, check='all', title=None):
    """Rate of ``check`` per cell: a heatmap for two parameters, rate ± 95 % CI for one
    (with more, one line per value of the other parameters)."""
    import matplotlib
    import matplotlib.pyplot as plt
    matplotlib.use('Agg')
    rr = [r for r in rates_rows if r['check'] == check]
    params = study.params
    title = title or f'{study.name}: {check} rate ({len(study.seeds)} seeds per cell)'
    if len(params) == 2:
        a, b = params
        xs, ys = study.grid[b], study.grid[a]
        z = np.full((len(ys), len(xs)), np.nan)
        txt = {}
        for r in rr:
            i, j = ys.index(r[a]), xs.index(r[b])
            z[i, j] = r['rate']
            txt[i, j] = f'{r["passed"]}/{r["n"]}'
        dense = max(len(xs), len(ys)) > 10          # a phase diagram: no counts, fewer ticks
        size = (9.0, 7.0) if dense else (1.2 * len(xs) + 2.5, 0.8 * len(ys) + 1.8)
        fig, ax = plt.subplots(figsize=size)
        im = ax.imshow(z, origin='lower', cmap='viridis', vmin=0, vmax=1, aspect='auto')
        for (i, j), s in ({} if dense else txt).items():
            ax.text(j, i, s, ha='center', va='center', color='w' if z[i, j] < 0.6 else 'k', fontsize=9)
        for axis, vals in ((ax.set_xticks, xs), (ax.set_yticks, ys)):
            ticks = range(0, len(vals), max(1, len(vals) // 10))
            axis(ticks, [f'{vals[i]:g}' if isinstance(vals[i], float) else str(vals[i]) for i in ticks])
        ax.set_xlabel(b)
        ax.set_ylabel(a)
        fig.colorbar(im, ax=ax, label=f'{check} rate')
    else:
        fig, ax = plt.subplots(figsize=(6, 4))
        x = params[0]
        others = params[1:]
        groups = {}
        for r in rr:
            groups.setdefault(tuple(r[o] for o in others), []).append(r)
        xs = study.grid[x]
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in xs)
        for g, sel in groups.items():
            xv = np.array([r[x] if numeric else xs.index(r[x]) for r in sel], float)
            y = np.array([r['rate'] for r in sel])
            err = np.array([[r['rate'] - r['ci_low'] for r in sel], [r['ci_high'] - r['rate'] for r in sel]])
            lab = ', '.join(f'{o}={v}' for o, v in zip(others, g)) or None
            ax.errorbar(xv, y, yerr=err, marker='o', capsize=3, label=lab)
        if not numeric:
            ax.set_xticks(range(len(xs)), [str(v) for v in xs])
            ax.set_xlim(-0.5, len(xs) - 0.5)
        ax.set_xlabel(x)
        ax.set_ylabel(f'{check} rate (95 % CI)')
        ax.set_ylim(-0.05, 1.05)
        if others:
            ax.legend(fontsize=8)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format='png')
    plt.close(fig)
    return path
