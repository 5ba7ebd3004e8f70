#!/usr/bin/env python3
"""Runs per second of a study grid: local processes against a Dask cluster, equal worker count.

    .venv/bin/python scripts/bench_study.py [--study studies/fig3_ramp.yaml] [--seeds 2]
                                            [--workers 2] [--rounds 2] [--json FILE]

Both executors run the same grid from an empty cache, alternating (local, Dask, local, ...)
so that the machine's load hits both alike.  The Dask cluster (N single-threaded worker
processes on 127.0.0.1) is started once before the rounds: its start-up time is reported on
its own, not in the runs per second.  The local pool is started inside each timed round (it
is part of that executor's cost).  The overhead is (local runs/s ÷ Dask runs/s − 1), from the
median round of each; the tables of both executors are checked to be equal.  Each round
also gives the time per run outside the engine: (wall × workers − Σ engine seconds) / runs,
the engine seconds measured inside the workers (idle workers at the end of a round count too).
The parent imports `swarm_tools.simulate` first, as `swarm sweep` does, so the local
pool's forked workers start with the engine imported.

``--engines``: instead, the fast engine against the reference, side by side in one run (local
processes, the study's seeds unless --seeds is given): wall time and CPU seconds per run (this
process and its workers, `resource.getrusage`), the kernel's compile/load time, and whether the
per-run outcomes (every check) are the same.  ``--radio LOSS`` adds the same study with
``comms.loss LOSS`` on both engines, interleaved with the perfect radio, and the ratios
(fast radio ÷ fast perfect radio, fast radio ÷ reference radio).
"""
from __future__ import annotations

import argparse
import copy
import json
import operator
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


#: a task that returns at once: the run's key (importable on the workers, like run_task)
echo = operator.attrgetter('key')


def per_task_ms(study_tasks, workers, scheduler=None, repeat=3):
    """Executor cost per task (ms of worker time): ``echo`` over the study's own tasks (each
    carries its scenario), in a warm pool of ``workers`` processes or on the Dask cluster."""
    times = []
    if scheduler is None:
        from concurrent.futures import ProcessPoolExecutor, as_completed
        with ProcessPoolExecutor(max_workers=workers) as pool:
            list(pool.map(echo, study_tasks[:workers]))
            for _ in range(repeat):
                t0 = time.perf_counter()
                for f in as_completed([pool.submit(echo, t) for t in study_tasks]):
                    f.result()
                times.append(time.perf_counter() - t0)
    else:
        from distributed import Client, as_completed
        with Client(scheduler) as client:
            client.gather([client.submit(echo, t, pure=False) for t in study_tasks[:workers]])
            for _ in range(repeat):
                t0 = time.perf_counter()
                for f in as_completed([client.submit(echo, t, pure=False) for t in study_tasks]):
                    f.result()
                times.append(time.perf_counter() - t0)
    return round(1000 * statistics.median(times) * workers / len(study_tasks), 2)


def cpu_seconds():
    """CPU seconds of this process and of its finished children (the pool's workers)."""
    import resource
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def outcomes(rows):
    """The per-run outcomes of a table: every check's verdict and the cluster count at the end."""
    return [{k: v for k, v in r.items() if isinstance(v, bool) or v is None or k == 'final_clusters'}
            for r in rows]


def engines_main(a, s) -> int:
    """The fast engine against the reference on the same study (see the module's doc)."""
    from swarm_core import study as st
    from swarm_core.engine import fast
    n = len(s.cells()) * len(s.seeds)
    t0 = time.perf_counter()
    compile_s = fast.warm_up()          # in this process: the forked workers inherit the kernels
    res = {'study': s.name, 'runs': n, 'workers': a.workers, 'import_s': round(t0 - _T_START, 2),
           'warm_up_s': round(compile_s, 2)}
    studies = {'': s}
    if a.radio is not None:             # the same study over a lossy radio
        studies['_radio'] = copy.deepcopy(s)
        studies['_radio'].fixed['comms.loss'] = a.radio
        res['radio'] = {'comms.loss': a.radio}
    tables = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.rounds):
            for radio, study in studies.items():
                for eng in ('reference', 'fast'):
                    key = eng + radio
                    w0, c0 = time.perf_counter(), cpu_seconds()
                    rows, counts = st.run_study(study, Path(tmp) / f'{key}{r}', jobs=a.workers, engine=eng)
                    wall, cpu = time.perf_counter() - w0, cpu_seconds() - c0
                    res.setdefault(f'{key}_wall_s', []).append(round(wall, 2))
                    res.setdefault(f'{key}_cpu_ms_per_run', []).append(round(1000 * cpu / n, 1))
                    tables[key] = rows
                    print(f'round {r}: {key:15s} {n} runs in {wall:.1f} s wall, {1000 * cpu / n:.1f} ms CPU per run',
                          flush=True)
    for radio in studies:
        fast_t, ref_t = outcomes(tables['fast' + radio]), outcomes(tables['reference' + radio])
        diff = [i for i, (x, y) in enumerate(zip(fast_t, ref_t)) if x != y]
        res['outcomes_differ' + radio] = [{**tables['fast' + radio][i], 'reference': ref_t[i]} for i in diff]
        for eng in ('reference', 'fast'):
            res[f'{eng}{radio}_cpu_ms_per_run_median'] = statistics.median(res[f'{eng}{radio}_cpu_ms_per_run'])
            res[f'{eng}{radio}_wall_s_median'] = statistics.median(res[f'{eng}{radio}_wall_s'])
    med = {key: res[f'{key}_cpu_ms_per_run_median'] for key in tables}
    res['speed_up_cpu'] = round(med['reference'] / med['fast'], 1)
    if a.radio is not None:
        res['fast_radio_over_fast_perfect_cpu'] = round(med['fast_radio'] / med['fast'], 2)
        res['fast_radio_over_reference_radio_cpu'] = round(med['fast_radio'] / med['reference_radio'], 4)
    print(json.dumps(res, indent=1))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1) + '\n')
    return 0


_T_START = time.perf_counter()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--study', default=str(ROOT / 'studies' / 'fig3_ramp.yaml'))
    p.add_argument('--seeds', type=int, default=None, help='seeds per cell (default 2; --engines: the study\'s)')
    p.add_argument('--workers', type=int, default=2)
    p.add_argument('--rounds', type=int, default=2)
    p.add_argument('--duration', type=float,
                   help="override the runs' duration (shorter runs: a larger share of overhead)")
    p.add_argument('--json', help='also write the numbers here')
    p.add_argument('--engines', action='store_true', help='the fast engine against the reference (local processes)')
    p.add_argument('--radio', type=float, metavar='LOSS',
                   help='--engines: also the study with comms.loss LOSS on both engines, and the ratios')
    a = p.parse_args(argv)
    if a.engines:
        from swarm_core import study as st
        s = st.load_study(a.study)
        if a.seeds is not None:
            s.seeds = list(range(a.seeds))
        if a.duration:
            s.fixed['duration'] = a.duration
        st.validate(s)
        return engines_main(a, s)

    from distributed import LocalCluster

    from swarm_core import study as st

    s = st.load_study(a.study)
    s.seeds = list(range(2 if a.seeds is None else a.seeds))
    if a.duration:
        s.fixed['duration'] = a.duration
    st.validate(s)
    n = len(s.cells()) * len(s.seeds)
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                           dashboard_address=None, host='127.0.0.1')
    startup = time.perf_counter() - t0
    res = {'study': s.name, 'runs': n, 'duration': a.duration, 'workers': a.workers,
           'dask_startup_s': round(startup, 2),
           'local_s': [], 'dask_s': [], 'local_outside_ms': [], 'dask_outside_ms': []}
    tables = {}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for r in range(a.rounds):
                for kind in ('local', 'dask'):
                    cache = Path(tmp) / f'{kind}{r}'
                    t0 = time.perf_counter()
                    rows, counts = st.run_study(s, cache, jobs=a.workers,
                                                scheduler=cluster.scheduler_address if kind == 'dask' else None)
                    dt = time.perf_counter() - t0
                    assert counts['ran'] == n
                    res[f'{kind}_s'].append(round(dt, 2))
                    engine_s = sum(json.loads(f.read_text())['wall'] for f in cache.glob('*.json'))
                    res[f'{kind}_outside_ms'].append(round(1000 * (dt * a.workers - engine_s) / n, 1))
                    tables[kind] = st.to_csv(s, rows)
                    print(f'round {r}: {kind:5s} {n} runs in {dt:.1f} s = {n / dt:.2f} runs/s, '
                          f'{res[f"{kind}_outside_ms"][-1]:.0f} ms per run outside the engine', flush=True)
            # the executors alone, without the runs (robust to a loaded machine)
            many = st.tasks(s) * max(1, 200 // n)
            res['echo_tasks'] = len(many)
            res['local_ms_per_task'] = per_task_ms(many, a.workers)
            res['dask_ms_per_task'] = per_task_ms(many, a.workers, cluster.scheduler_address)
            res['engine_s_per_run'] = round(statistics.median(
                json.loads(f.read_text())['wall'] for f in (Path(tmp) / 'local0').glob('*.json')), 3)
            print(f'executor cost per task: local {res["local_ms_per_task"]} ms, Dask {res["dask_ms_per_task"]} ms; '
                  f'median engine time per run {res["engine_s_per_run"]} s', flush=True)
    finally:
        cluster.close()
    res['same_table'] = tables['local'] == tables['dask']
    loc, dsk = statistics.median(res['local_s']), statistics.median(res['dask_s'])
    res['local_runs_per_s'] = round(n / loc, 3)
    res['dask_runs_per_s'] = round(n / dsk, 3)
    res['dask_overhead_pct'] = round(100 * (dsk / loc - 1), 1)
    res['dask_overhead_per_run_ms'] = round(1000 * (dsk - loc) * a.workers / n, 1)
    res['local_outside_ms_median'] = statistics.median(res['local_outside_ms'])
    res['dask_outside_ms_median'] = statistics.median(res['dask_outside_ms'])
    print(json.dumps(res, indent=1))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1) + '\n')
    return 0 if res['same_table'] else 1


if __name__ == '__main__':
    sys.exit(main())
