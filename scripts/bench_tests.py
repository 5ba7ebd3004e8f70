#!/usr/bin/env python3
"""Wall and CPU time of single tests, this checkout against an older commit, interleaved.

Each named test runs alone in a fresh ``pytest`` process, first in its form at ``--compare``
(its file taken from that commit with ``git show`` and put beside the current tests as
``tests/_bench_before_<file>``, so that it sees the same conftest and installed packages),
then in this checkout's form, ``--repeats`` times over.  CPU is user + system of pytest and
every process it waited for (the swarm's processes included).  The load average is printed
with each run: on a shared machine compare the columns of one run, not runs apart.

    .venv/bin/python scripts/bench_tests.py --compare 953c611 \\
        tests/test_ros_e2e.py::test_realtime_lambda_from_the_cli_splits_the_swarm
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def before_copy(node: str, commit: str) -> tuple[str, Path]:
    """The node id of ``node`` in its file as of ``commit`` (written beside the tests)."""
    path, _, name = node.partition('::')
    text = subprocess.run(['git', 'show', f'{commit}:{path}'], cwd=ROOT, check=True, capture_output=True,
                          text=True).stdout
    copy = ROOT / 'tests' / f'_bench_before_{Path(path).name}'
    copy.write_text(text)
    return f'{copy.relative_to(ROOT)}::{name}', copy


def run_one(node: str) -> dict:
    """One pytest process running ``node``: exit code, wall s, CPU s, load average before."""
    load = os.getloadavg()[0]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', node],
                       cwd=ROOT, capture_output=True, text=True)
    wall = time.monotonic() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return dict(ok=p.returncode == 0, wall=round(wall, 1), cpu=round(cpu, 1), load=round(load, 1),
                tail='' if p.returncode == 0 else p.stdout[-2000:])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('tests', nargs='+', help='pytest node ids (tests/FILE.py::NAME[PARAM])')
    ap.add_argument('--compare', required=True, help='the commit whose form of each test runs first')
    ap.add_argument('--repeats', type=int, default=1)
    ap.add_argument('--out', help='also write the rows as JSON here')
    args = ap.parse_args(argv)
    rows, copies = [], set()
    try:
        for _ in range(args.repeats):
            for node in args.tests:
                old, copy = before_copy(node, args.compare)
                copies.add(copy)
                b, a = run_one(old), run_one(node)
                rows.append(dict(test=node, before=b, after=a))
                print(f"{node}\n  before: {b['wall']:6.1f} s wall {b['cpu']:6.1f} s CPU (load {b['load']}) "
                      f"{'ok' if b['ok'] else 'FAILED'}\n  after:  {a['wall']:6.1f} s wall {a['cpu']:6.1f} s CPU "
                      f"(load {a['load']}) {'ok' if a['ok'] else 'FAILED'}", flush=True)
                for side in (b, a):
                    if side['tail']:
                        print(side['tail'])
    finally:
        for copy in copies:
            copy.unlink(missing_ok=True)
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1))
    return 0 if all(r['before']['ok'] and r['after']['ok'] for r in rows) else 1


if __name__ == '__main__':
    sys.exit(main())
