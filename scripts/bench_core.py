#!/usr/bin/env python3
"""Benchmark of the batch engine (no ROS): steps/s against swarm size, and the wall time of
the paper's homotopy_global run to t = 1000.

    .venv/bin/python scripts/bench_core.py [--quick] [--out bench/core]

Writes bench/core.json and bench/core.png (steps/s vs n, log-log) and prints a Markdown table.
Timings are medians of repeated runs on whatever else the machine is doing: compare ratios
measured in the same run, not absolute numbers across machines.
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from swarm_core import engine, scenario


def swarm(n, kind, spacing=1.5, seed=0):
    """n agents on a square grid at the paper's spacing, random headings in a 90° cone."""
    data = dict(name=f'bench_{kind}_{n}', seed=seed, dt=0.05, duration=1.0,
                agents=dict(count=n, positions={'rule': 'grid', 'spacing': spacing},
                            headings={'rule': 'cone'}),
                law=dict(kind='homotopy' if kind == 'local' else 'global', q0=0.0 if kind == 'local' else 1.0))
    if kind == 'local':        # the homotopy law at λ = 1: leader following, local coupling within w
        data['lambda'] = {'kind': 'constant', 'value': 1.0}
        data['leaders'] = {'fixed': {'agent_0': {'kind': 'constant', 'curvature': 0.01},
                                     f'agent_{n - 1}': {'kind': 'constant', 'curvature': -0.01}}}
    return scenario.parse(data)


def steps_per_second(n, kind, min_seconds=1.0):
    stepper = engine.SwarmStepper(swarm(n, kind))
    stepper.step()                                   # warm-up (caches, pair tables)
    steps, t0 = 0, time.perf_counter()
    while True:
        stepper.step()
        steps += 1
        el = time.perf_counter() - t0
        if el >= min_seconds and steps >= 3:
            return steps / el, stepper.neighbour_search


def full_run(name, dt, repeats):
    times = []
    for _ in range(repeats):
        scn = scenario.load(name, dt=dt)
        t0 = time.perf_counter()
        engine.simulate(scn)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--quick', action='store_true', help='fewer sizes, shorter timings')
    p.add_argument('--out', default='bench/core', help='output path stem (default bench/core)')
    a = p.parse_args(argv)
    sizes = {'global': [6, 24, 100, 300, 1000, 2000, 4000],
             'local': [6, 100, 1000, 3000, 10000, 30000]}
    if a.quick:
        sizes = {'global': [6, 100, 1000, 2000], 'local': [100, 1000, 10000]}
    min_s = 0.5 if a.quick else 1.5
    res = {'steps_per_second': {}, 'full_runs': {}}
    for kind, ns in sizes.items():
        res['steps_per_second'][kind] = []
        for n in ns:
            sps, search = steps_per_second(n, kind, min_s)
            res['steps_per_second'][kind].append(dict(n=n, steps_per_second=sps, search=search))
            print(f'{kind:6s} n={n:6d}: {sps:10.1f} steps/s ({search})', file=sys.stderr)
    for dt in (0.05, 0.1):
        med, times = full_run('homotopy_global', dt, 3 if not a.quick else 1)
        res['full_runs'][f'homotopy_global dt={dt}'] = dict(median_seconds=med, runs=times,
                                                             steps=int(round(1000 / dt)))
        print(f'homotopy_global to t=1000 at dt={dt}: {med:.2f} s (median of {len(times)})', file=sys.stderr)

    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix('.json').write_text(json.dumps(res, indent=1))
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    for kind, rows in res['steps_per_second'].items():
        label = 'global law (all pairs)' if kind == 'global' else 'local law, λ = 1 (KD-tree within w)'
        ax.loglog([r['n'] for r in rows], [r['steps_per_second'] for r in rows], 'o-', label=label)
    ax.axhline(10, color='k', ls=':', lw=1, label='10 steps/s')
    ax.set_xlabel('agents n')
    ax.set_ylabel('steps per second')
    ax.set_title('batch engine throughput (one core)')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend()
    fig.savefig(out.with_suffix('.png'), dpi=110)

    print('| law | n | steps/s | pair search |\n|---|---|---|---|')
    for kind, rows in res['steps_per_second'].items():
        for r in rows:
            print(f'| {kind} | {r["n"]} | {r["steps_per_second"]:.1f} | {r["search"]} |')
    print('\n| run | median wall (s) | steps |\n|---|---|---|')
    for k, v in res['full_runs'].items():
        print(f'| {k} | {v["median_seconds"]:.2f} | {v["steps"]} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
