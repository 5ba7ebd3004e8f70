#!/usr/bin/env python3
"""Write tests/durations.json (wall seconds per ROS test file) from pytest outputs with
``--durations=0``, for the shards of scripts/test.sh (`--shard`, tests/conftest.py).

    bash scripts/test.sh --durations=0 > suite.log; .venv/bin/python scripts/test_durations.py suite.log

A file's time is the sum of its tests' setup, call and teardown; only ROS tests (the ones the
shards deal out) are kept.  A file not in the table is counted at the table's mean per test."""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / 'tests' / 'durations.json'
LINE = re.compile(r'^([0-9.]+)s (?:call|setup|teardown)\s+(tests/\S+?)::', re.M)


def parse(texts) -> dict:
    """{file: seconds} of the ROS test files in pytest ``--durations`` lines."""
    sys.path.insert(0, str(ROOT))
    from tests.conftest import ros_by_folder
    out = {}
    for text in texts:
        for m in LINE.finditer(text):
            path = m.group(2)
            if ros_by_folder(ROOT / path):
                out[path] = out.get(path, 0.0) + float(m.group(1))
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('logs', nargs='+', type=Path,
                   help='pytest outputs with --durations=0 (scripts/test.sh prints all shards)')
    p.add_argument('--out', type=Path, default=OUT, help=f'where to write (default: {OUT.relative_to(ROOT)})')
    args = p.parse_args(argv)
    found = parse(f.read_text(errors='replace') for f in args.logs)
    if not found:
        print('test_durations: no --durations line of a ROS test in ' + ', '.join(map(str, args.logs)),
              file=sys.stderr)
        return 2
    args.out.write_text(json.dumps({k: round(v, 1) for k, v in sorted(found.items())}, indent=1) + '\n')
    print(f'test_durations: {len(found)} files, {sum(found.values()):.0f} s, written to {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
