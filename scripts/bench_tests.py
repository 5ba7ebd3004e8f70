#!/usr/bin/env python3
"""Wall and CPU time of single tests, this checkout against an older commit, interleaved.

Each named test runs alone in a fresh ``pytest`` process, first in its form at ``--compare``
(its file taken from that commit with ``git show`` and put beside the test's current file as
``_bench_before_<old file>``, so that it sees the same conftest, the same `ros` marker by
folder and the same installed packages), then in this checkout's form, ``--repeats`` times
over.  CPU is user + system of pytest and every process it waited for (the swarm's processes
included).  The load average is printed with each run: on a shared machine compare the
columns of one run, not runs apart.

The old file is the test's current path at that commit, or else the one file of the
commit's tests/ that defines the test's function (the tests moved from a flat tests/ into
folders that mirror src/).  The copy is adapted to the layout of now: its `ros` marks are
dropped (the marker comes from the folder), ``from conftest import`` and the bare imports of
stand-ins (``from rosbag2_record import``) read tests/helpers.py and tests/fakes/, and
``__file__`` is the old file's path (``Path(__file__).parents[1]`` is the checkout again).
Not adapted (the old form then fails and its output is printed): names that tests/helpers.py
no longer has, imports from other test modules, files the old test read beside itself, and
modules of the project that have moved since (tests of commits before 0c4c8b3 may import
``swarm_core.trajectory`` and the like, gone with the sub-packages of b834787).

    .venv/bin/python scripts/bench_tests.py --compare 0c4c8b3 \\
        tests/e2e/test_process_runs.py::test_realtime_lambda_from_the_cli_splits_the_swarm
"""
from __future__ import annotations

import argparse
import ast
import io
import json
import os
import re
import resource
import subprocess
import sys
import time
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def git(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(['git', *args], cwd=ROOT, check=check, capture_output=True, text=True)


def old_file(path: str, name: str, commit: str) -> str:
    """The file of ``commit`` that holds test ``name`` (``test_x``, ``TestX::test_x[p]``) of
    ``path``: ``path`` itself if the commit has it, else the one file of its tests/ defining the
    test's function (one named as ``path`` if several do)."""
    if git('cat-file', '-e', f'{commit}:{path}', check=False).returncode == 0:
        return path
    func = name.split('::')[-1].split('[')[0]
    hits = git('grep', '-l', '-E', rf'^\s*(async\s+)?def {re.escape(func)}\(', commit, '--', 'tests',
               check=False).stdout.split()
    hits = [h.partition(':')[2] for h in hits]
    same = [h for h in hits if Path(h).name == Path(path).name]
    if len(hits) == 1 or len(same) == 1:
        return hits[0] if len(hits) == 1 else same[0]
    raise SystemExit(f'bench_tests: {commit} has no {path}, and {len(hits)} files of its tests/ define '
                     f'{func}: {", ".join(hits) or "none"}')


def adapted(text: str, old: str) -> str:
    """The old test file's text for the layout of now (see the module's docstring)."""
    # `__file__` (a name, not inside a string) -> the old file's path
    spots = [t.start for t in tokenize.generate_tokens(io.StringIO(text).readline)
             if t.type == tokenize.NAME and t.string == '__file__']
    lines = text.splitlines(keepends=True)
    for row, col in reversed(spots):
        line = lines[row - 1]
        lines[row - 1] = line[:col] + repr(str(ROOT / old)) + line[col + len('__file__'):]
    text = ''.join(lines)
    # the `ros` marker comes from the folder now; a mark by hand outside a ros/ folder is an error
    text = re.sub(r'^[ \t]*@pytest\.mark\.ros\b[ \t]*(#.*)?\n', '', text, flags=re.M)
    text = re.sub(r'^(\s*pytestmark\s*=\s*)pytest\.mark\.ros\b', r'\1[]', text, flags=re.M)
    text = re.sub(r'\bpytest\.mark\.ros\b\s*,\s*|,\s*pytest\.mark\.ros\b', '', text)
    # the helpers moved from conftest to tests/helpers.py, the stand-ins into tests/fakes/
    text = re.sub(r'^(\s*)from conftest import', r'\1from tests.helpers import', text, flags=re.M)
    fakes = '|'.join(re.escape(f.stem) for f in (ROOT / 'tests' / 'fakes').glob('*.py') if f.stem != '__init__')
    if fakes:
        text = re.sub(rf'^(\s*)from ({fakes}) import', r'\1from tests.fakes.\2 import', text, flags=re.M)
    have = {n.id if isinstance(n, ast.Name) else n.name
            for node in ast.parse((ROOT / 'tests' / 'helpers.py').read_text()).body
            for n in (node.targets if isinstance(node, ast.Assign) else [node])
            if isinstance(n, (ast.Name, ast.FunctionDef, ast.ClassDef))}
    gone = sorted({a.name for node in ast.walk(ast.parse(text)) if isinstance(node, ast.ImportFrom)
                   and node.module == 'tests.helpers' for a in node.names} - have)
    if gone:
        print(f'bench_tests: tests/helpers.py has no {", ".join(gone)} (imported by {old} from conftest): '
              'its old form will fail', file=sys.stderr)
    return text


def before_copy(node: str, commit: str) -> tuple[str, Path]:
    """The node id of ``node`` in its file as of ``commit``, written beside the test's current
    file (so that the conftest's `ros` marker by folder applies to it as to the current form)."""
    path, _, name = node.partition('::')
    path = (ROOT / path).resolve().relative_to(ROOT).as_posix()
    old = old_file(path, name, commit)
    copy = (ROOT / path).parent / f'_bench_before_{Path(old).name}'
    copy.write_text(adapted(git('show', f'{commit}:{old}').stdout, old))
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
    ap.add_argument('tests', nargs='+', help='pytest node ids (tests/FOLDER/FILE.py::NAME[PARAM])')
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
