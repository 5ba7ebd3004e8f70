#!/usr/bin/env python3
"""Are this checkout's control law and batch engine bit-identical to a git revision's?

    .venv/bin/python scripts/compare_core_bits.py REV [--quick]

Runs the same inputs through `swarm_core` of this checkout and of REV (extracted with
``git archive``, as `bench_core.py --compare` does), each in a fresh process, and compares the
results bit for bit: `swarm_control` for every law kind, λ ∈ {0, 0.37, 1}, q0 ∈ {0, 0.05, 1}, on
random tables of n = 1 … 300 agents (some with coincident agents, with and without leaders,
target and barrier terms), for the whole table, for single receivers (an agent node) and over
a KD-tree pair list; then `engine.simulate` of the shipped scenarios (positions, headings, u),
with the numpy sums (``compiled='off'``: auto takes the compiled path for long runs, which its
own tests compare with the numpy step).
Prints the number of results that differ (0 means a refactoring changed no bit).  A speed
change that keeps this at 0 cannot change any trajectory, test outcome or recorded number.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAPER_KINDS = ('global', 'local', 'leader_following', 'homotopy', 'target')
SCENARIOS = ('homotopy_global', 'homotopy_local', 'target_barrier', 'leader_failover',
             'homotopy_reunion', 'global_alignment')


def produce(out, quick):
    """Every result, into an .npz file (runs in a worker process)."""
    import numpy as np

    from swarm_core import engine, scenario
    from swarm_core.laws import from_flat_parameters, swarm_control
    try:                      # the layout with sub-packages, then older revisions' module names
        from swarm_core.engine import reference as engine
        from swarm_core.model.frenet import heading_frame
    except ImportError:
        try:
            from swarm_core.frenet import heading_frame
        except ImportError:
            from swarm_core.model import heading_frame
    try:                      # where the KD-tree pair list lives: beside the paper's law, or in the engine
        from swarm_core.laws.paper.pair_sums import neighbour_pairs
    except ImportError:
        neighbour_pairs = engine.neighbour_pairs
    res = {}
    rng = np.random.default_rng(0)
    for n in ((1, 3, 6, 40) if quick else (1, 2, 3, 6, 9, 40, 300)):
        for trial in range(6):
            pos = rng.uniform(-6, 6, (n, 2)) * (1 if n < 100 else 4)
            if trial % 3 == 1 and n > 2:
                pos[1] = pos[n - 1]
            if trial % 3 == 2 and n > 3:
                pos[0] = pos[2]
                pos[3] = pos[2]
            c, s = heading_frame(rng.uniform(-3, 3, n))
            leaders = np.zeros(n, bool)
            if n > 1 and trial != 5:
                leaders[rng.choice(n, min(2, n - 1), replace=False)] = True
            steer = rng.uniform(-0.02, 0.02, n)
            for kind in PAPER_KINDS:
                for lam in (0.0, 0.37, 1.0):
                    for q0 in (0.0, 0.05, 1.0):
                        # every parameter as flat parameters, as an agent node gets the law: one
                        # way to build the paper's law that each revision reads
                        law = from_flat_parameters(dict(
                            law=kind, alpha=0.02, eta=0.03, mu=0.025, r0=1.5, cutoff_radius=4.0, leader_gain=17.0,
                            q0=q0, target_gain=0.05 if trial % 2 else 0.0, target_normalised=trial == 4,
                            barrier_gain=4.0 if trial == 3 else 0.0, barrier_mode='ahead'))
                        kw = dict(lambda_=lam, is_leader=leaders, target=(20.0, -3.0), barrier=pos[:2] + 0.5)
                        key = f'{n}_{trial}_{kind}_{lam}_{q0}'
                        res[key] = swarm_control(pos, c, s, np.arange(n), law, steering=steer, **kw)
                        res[key + '_one'] = np.array([
                            swarm_control(pos, c, s, np.array([k]), law, steering=steer[[k]], **kw)[0]
                            for k in (0, n - 1, n // 2)])
                        if kind in ('local', 'target') or (n >= 9 and lam > 0 and q0 == 0.0):
                            pairs = neighbour_pairs(pos, law.cutoff_radius)
                            res[key + '_pairs'] = swarm_control(pos, c, s, np.arange(n), law,
                                                                steering=steer, pairs=pairs, **kw)
    numpy_only = {'compiled': 'off'} if 'compiled' in engine.simulate.__code__.co_varnames else {}
    for name in (SCENARIOS[:2] if quick else SCENARIOS):
        tr = engine.simulate(scenario.load(name), **numpy_only)
        res[f'simulate_{name}_r'], res[f'simulate_{name}_theta'], res[f'simulate_{name}_u'] = tr.r, tr.theta, tr.u
    import swarm_core
    res['_module'] = np.array(swarm_core.__file__)
    np.savez(out, **res)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('rev', help='git revision to compare with (e.g. main)')
    p.add_argument('--quick', action='store_true', help='fewer tables and two scenarios')
    p.add_argument('--worker', nargs=2, help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.worker:
        produce(a.worker[0], a.worker[1] == 'quick')
        return 0
    sys.path.insert(0, str(ROOT / 'scripts'))
    import numpy as np
    from bench_core import extract
    with tempfile.TemporaryDirectory() as tmp:
        base_src = extract(a.rev, tmp)
        outs = {}
        for side, src in (('current', None), (a.rev, base_src)):
            env = dict(os.environ)
            if src is not None:
                env['PYTHONPATH'] = src + os.pathsep + env.get('PYTHONPATH', '')
            outs[side] = str(Path(tmp) / f'{side.replace("/", "_")}.npz')
            print(f'compare_core_bits: computing with {side} …', file=sys.stderr, flush=True)
            subprocess.run([sys.executable, __file__, a.rev, '--worker', outs[side],
                            'quick' if a.quick else 'full'], env=env, check=True)
        cur, base = np.load(outs['current']), np.load(outs[a.rev])
        if not str(base['_module']).startswith(tmp):
            raise SystemExit(f'compare_core_bits: {a.rev} not imported (got {base["_module"]})')
        keys = [k for k in cur.files if k != '_module']
        differ = [k for k in keys if k not in base.files or cur[k].shape != base[k].shape
                  or not np.array_equal(cur[k].view(np.uint8), base[k].view(np.uint8))]
    print(f'{len(keys)} results compared with {a.rev}: {len(differ)} differ in any bit')
    for k in differ[:20]:
        print('  differs:', k)
    return 1 if differ else 0


if __name__ == '__main__':
    sys.exit(main())
