"""``swarm laws``: every law a scenario can name, with its parameters (no ROS).

    swarm laws           every registered law: the built-in ones and those of installed packages
                         (entry-point group swarm_core.laws)
    swarm laws NAME      one law: a registered kind, FILE.py:Class or module:Class
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from swarm_core.laws import LawError, law_class
from swarm_core.laws.registry import GROUP, catalogue, describe


def laws_main(argv) -> int:
    p = argparse.ArgumentParser(
        prog='swarm laws', description='List the laws a scenario can name (law: {kind: NAME}): their '
        'dimensions, one-line docs and parameters with defaults and ranges.',
        epilog=f'An installed package adds a law under the entry-point group {GROUP}; see docs/laws.md.')
    p.add_argument('name', nargs='?', help='one law: a registered kind, FILE.py:Class or module:Class')
    a = p.parse_args(argv)
    if a.name is not None:
        try:
            print('\n'.join(describe(law_class(a.name, base_dir=Path.cwd(), field='swarm laws'))))
        except LawError as err:
            print(err, file=sys.stderr)
            return 2
        return 0
    lines, errors = catalogue()
    print('\n'.join(lines))
    for err in errors:
        print(err, file=sys.stderr)
    return 2 if errors else 0
