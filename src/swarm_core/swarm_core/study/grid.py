"""The grid of a study (no ROS): ``--set`` expressions and ranges, setting a dotted field of
a scenario mapping, and the size limits, checked from the lengths of the lists alone."""
from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass, field

import numpy as np
import yaml

from swarm_core.scenario import loader as scenario

#: most cells (grid points) and runs (cells × seeds) a study may have: checked from the
#: lengths of the grid's lists before any cell is made
MAX_CELLS = 10_000
MAX_RUNS = 100_000


class StudyError(ValueError):
    """A study that cannot run; the message names the bad input."""


def parse_values(text: str) -> list:
    """``5,10,20`` → [5, 10, 20]; ``0:0.05:6`` → 6 values from 0 to 0.05 (both ends);
    each item is read as YAML (numbers, true/false, strings)."""
    text = text.strip()
    if not text:
        raise StudyError('empty list of values')
    if ':' in text and not text.startswith(('[', '{')):
        parts = text.split(':')
        if len(parts) != 3:
            raise StudyError(f'{text!r}: a range is START:STOP:COUNT')
        try:
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
        except ValueError:
            raise StudyError(f'{text!r}: a range is START:STOP:COUNT (numbers, COUNT an integer)') from None
        if n < 1:
            raise StudyError(f'{text!r}: empty range (COUNT must be ≥ 1)')
        if n > MAX_CELLS:
            raise StudyError(f'{text!r}: {n} values; a study has at most {MAX_CELLS} cells')
        return [float(v) for v in np.linspace(a, b, n)] if n > 1 else [a]
    vals = []
    for item in text.split(','):
        if not item.strip():
            raise StudyError(f'{text!r}: empty value in the list')
        try:
            vals.append(scenario.safe_yaml(item))
        except yaml.YAMLError:
            raise StudyError(f'{text!r}: cannot read value {item!r}') from None
    return vals


def parse_set(expr: str) -> tuple[str, list]:
    """``law.leader_gain=5,10`` → ('law.leader_gain', [5, 10])."""
    fld, eq, vals = expr.partition('=')
    fld = fld.strip()
    if not eq or not fld:
        raise StudyError(f'--set {expr!r}: give FIELD=VALUES, e.g. law.leader_gain=5,10,20')
    try:
        return fld, parse_values(vals)
    except StudyError as err:
        raise StudyError(f'--set {fld}: {err}') from None


def set_field(data: dict, dotted: str, value):
    """Set ``data[a][b]...`` for ``a.b...`` (integer parts index lists); creates missing mappings."""
    parts = dotted.split('.')
    node = data
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise StudyError(f'{dotted}: {".".join(parts[:i]) or "(top)"} has {len(node)} items, no {part!r}')
            key = int(part)
        elif isinstance(node, dict):
            key = part
            if not last and node.get(key) is None:
                node[key] = {}
        else:
            raise StudyError(f'{dotted}: {".".join(parts[:i])} is a value, not a section')
        if last:
            node[key] = json.loads(json.dumps(value))    # a copy: cells never share a mapping
        else:
            node = node[key]


def check_size(grid: dict, seeds) -> None:
    """StudyError if ``grid`` ({field: values}) has more than `MAX_CELLS` cells or, with
    ``seeds`` (a count or a list), more than `MAX_RUNS` runs; from the lengths alone."""
    cells = math.prod(len(v) for v in grid.values())
    if cells > MAX_CELLS:
        raise StudyError(f'{cells} cells ({" × ".join(str(len(v)) for v in grid.values())}): '
                         f'a study has at most {MAX_CELLS}')
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        n_seeds = seeds
    elif isinstance(seeds, (list, tuple, range)):
        n_seeds = len(seeds)
    else:
        raise StudyError(f'seeds: {seeds!r} is not a count or a list of seeds')
    if cells * n_seeds > MAX_RUNS:
        raise StudyError(f'{cells} cells × {n_seeds} seeds = {cells * n_seeds} runs: '
                         f'a study has at most {MAX_RUNS}')


#: a study field that is no scenario field: which agents run on MuJoCo robots
#: (`robot_units.ROBOT_SETS`); a study with it runs on the robot engine (`swarm_robots.engine`)
ROBOT_SET = 'robot_set'

@dataclass
class Study:
    """A scenario (its mapping and source), a grid, fixed overrides and seeds."""
    data: dict
    source: str
    grid: dict = field(default_factory=dict)        # field -> list of values (in order)
    fixed: dict = field(default_factory=dict)       # field -> value, applied to every cell
    seeds: list = field(default_factory=lambda: list(range(10)))
    name: str = ''
    figure: dict = field(default_factory=dict)      # optional: {check: NAME}

    @property
    def params(self) -> list:
        return list(self.grid)

    def cells(self) -> list[dict]:
        """Every grid cell as {field: value}, the first field varying slowest."""
        keys = self.params
        return [dict(zip(keys, combo)) for combo in itertools.product(*(self.grid[k] for k in keys))]

    def cell_data(self, cell: dict) -> dict:
        """The scenario mapping of one cell (a deep copy with the fixed and cell values set)."""
        d = json.loads(json.dumps(self.data))
        for k, v in {**self.fixed, **cell}.items():
            if k != ROBOT_SET:
                set_field(d, k, v)
        return d

    def robot_set(self, cell: dict) -> str | None:
        """The cell's robot set (`ROBOT_SET`), None when it runs no robot engine."""
        return {**self.fixed, **cell}.get(ROBOT_SET)
