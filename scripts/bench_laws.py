#!/usr/bin/env python3
"""Benchmark of laws as plug-ins (no ROS): what a user's law costs per step against the
built-in ones, in the batch engine (`SwarmStepper.step`, the whole swarm) and per call of the
law for one receiver (what an agent node computes per step).

    .venv/bin/python scripts/bench_laws.py [--sizes 6,1000] [--seconds 1.0] [--out bench/laws.json]

Laws: the paper's global law (`laws.Global`, its own sums), the shipped spl_parallel (a `Law` in
numpy), the user's law of examples/laws/alignment.py, and a blend of the global law and
spl_circular.  n agents on a square grid at spacing 1.5, headings in a 90° cone, dt = 0.05.
Each number is the median over batches (a burst of load from other processes spoils a few
batches, not the median); the load average before and after is printed with them.  The
paper's laws before and after the interface: scripts/bench_core.py --compare 1f236c6.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ALIGNMENT = ROOT / 'examples' / 'laws' / 'alignment.py'

LAWS = {
    'global (paper)': {'kind': 'global'},
    'spl_parallel (shipped Law)': {'kind': 'spl_parallel', 'phase_gain': -0.1},
    'alignment (user file)': {'kind': f'{ALIGNMENT}:Alignment', 'gain': 0.3},
    'blend global → spl_circular': {'kind': 'blend', 'from': {'kind': 'global'},
                                    'to': {'kind': 'spl_circular', 'omega0': 0.2}},
}


def scenario(n, law):
    from swarm_core.scenario.loader import parse
    return parse(dict(name=f'bench_laws_{n}', seed=0, dt=0.05, duration=1.0, law=law,
                      agents=dict(count=n, positions={'rule': 'grid', 'spacing': 1.5}, headings={'rule': 'cone'}),
                      **{'lambda': {'kind': 'constant', 'value': 0.5}}))


def median_time(f, seconds, batch):
    """ms per call of f: the median over batches of ``batch`` calls for ``seconds``."""
    f()
    times = []
    start = time.perf_counter()
    while time.perf_counter() - start < seconds or len(times) < 3:
        t0 = time.perf_counter()
        for _ in range(batch):
            f()
        times.append((time.perf_counter() - t0) / batch * 1e3)
    return statistics.median(times)


def per_step(n, law, seconds):
    from swarm_core.engine.reference import SwarmStepper
    st = SwarmStepper(scenario(n, law))
    return median_time(st.step, seconds, batch=max(1, 2000 // n))


def per_agent_call(n, law, seconds):
    """ms per `swarm_control` for one receiver on the n-agent table (an agent node's step)."""
    from swarm_core.laws import swarm_control
    scn = scenario(n, law)
    c, s = np.cos(scn.theta0), np.sin(scn.theta0)
    recv = np.array([n // 2])
    return median_time(lambda: swarm_control(scn.pos0, c, s, recv, scn.law, lambda_=0.5, t=0.0), seconds,
                       batch=max(1, 2000 // n))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--sizes', default='6,1000', help='swarm sizes, a comma list (default 6,1000)')
    p.add_argument('--seconds', type=float, default=1.0, help='time per measurement (default 1)')
    p.add_argument('--out', default='bench/laws.json', help='results (default bench/laws.json)')
    a = p.parse_args(argv)
    sizes = [int(v) for v in a.sizes.split(',') if v.strip()]
    res = dict(command='scripts/bench_laws.py ' + ' '.join(sys.argv[1:] if argv is None else argv),
               load_before=os.getloadavg(), cpus=os.cpu_count(), rows=[])
    for name, law in LAWS.items():
        for n in sizes:
            row = dict(law=name, n=n, step_ms=per_step(n, law, a.seconds),
                       agent_call_ms=per_agent_call(n, law, a.seconds))
            res['rows'].append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    res['load_after'] = os.getloadavg()
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    base = {r['n']: r for r in res['rows'] if r['law'] == 'global (paper)'}
    print(f'load average {res["load_before"][0]:.2f} before, {res["load_after"][0]:.2f} after; '
          f'{res["cpus"]} CPUs\n')
    print('| law | n | batch engine, ms per step | vs global | one receiver (agent node), ms per call | vs global |')
    print('|---|---|---|---|---|---|')
    for r in res['rows']:
        b = base[r['n']]
        print(f'| {r["law"]} | {r["n"]} | {r["step_ms"]:.3g} | {r["step_ms"] / b["step_ms"]:.2g}× | '
              f'{r["agent_call_ms"]:.3g} | {r["agent_call_ms"] / b["agent_call_ms"]:.2g}× |')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
