"""A law parameter named like an agent node's own parameter (``x``, ``dt``, ``use_sim_time``,
``law``, ``run_id``, ``stale_after``, ...) or like a method of `Law` (``parameters``) is refused
when the scenario is loaded, in every engine alike, with one line naming the reserved names.
It used to run in `swarm simulate` and `swarm sweep` and give tracebacks in `swarm run` (the agent
declared the name twice), and ``parameters`` a traceback everywhere.  `swarm run`:
tests/e2e/test_law_reserved_names_run.py; an agent node started by hand:
tests/agent/ros/test_law_reserved_names.py."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from swarm_core.scenario.loader import ScenarioError, load

NAMES = ['x', 'dt', 'use_sim_time', 'law', 'run_id', 'stale_after', 'parameters', 'cmd_type']
SWARM = str(Path(sys.executable).parent / 'swarm')


def law_file(tmp_path, name: str) -> str:
    (tmp_path / 'laws').mkdir(exist_ok=True)
    (tmp_path / 'laws' / f'with_{name}.py').write_text(
        'import numpy as np\n'
        'from swarm_core.laws import Law, param\n\n\n'
        'class L(Law):\n'
        '    """A law with a parameter of a reserved name."""\n'
        f'    {name} = param(0.1, lo=0.0, hi=10.0, doc="clash")\n\n'
        '    def control(self, view):\n'
        '        return np.zeros(len(view.receivers))\n')
    return f'laws/with_{name}.py:L'


def scenario(tmp_path, name: str, blend: bool = False) -> Path:
    kind = law_file(tmp_path, name)
    law = (f'{{kind: blend, from: {{kind: global}}, to: {{kind: {kind}}}}}' if blend else f'{{kind: {kind}}}')
    path = tmp_path / f's_{name}.yaml'
    path.write_text(f'name: s_{name}\nseed: 0\nduration: 2\ndt: 0.1\nagents:\n  count: 3\nlaw: {law}\n')
    return path


@pytest.mark.parametrize('blend', [False, True], ids=['alone', 'in-a-blend'])
@pytest.mark.parametrize('name', NAMES)
def test_a_law_parameter_of_a_reserved_name_is_refused_at_load(tmp_path, name, blend):
    path = scenario(tmp_path, name, blend)
    with pytest.raises(ScenarioError) as err:
        load(str(path))
    text = str(err.value)
    assert '\n' not in text
    assert f"parameter {name!r} takes a reserved name" in text and f'with_{name}.py:L' in text, text
    for reserved in ('x', 'dt', 'use_sim_time', 'law', 'run_id', 'stale_after', 'parameters'):
        assert f' {reserved},' in text or f' {reserved})' in text or f'({reserved},' in text, (reserved, text)


@pytest.mark.parametrize('verb', [['simulate', '--no-figure'], ['sweep', '--seeds', '2']], ids=['simulate', 'sweep'])
@pytest.mark.parametrize('name', ['dt', 'parameters'])
def test_simulate_and_sweep_refuse_it_in_one_line(tmp_path, name, verb):
    path = scenario(tmp_path, name)
    r = subprocess.run([SWARM, verb[0], str(path), '--out', str(tmp_path / 'out'), *verb[1:]],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, (r.returncode, r.stdout[-2000:], r.stderr[-2000:])
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"parameter {name!r} takes a reserved name" in lines[0], r.stderr[-3000:]


def test_no_shipped_law_takes_a_reserved_name():
    from swarm_core.laws import make_law, names
    from swarm_core.reserved import check_law_names
    for kind in names():
        section = {'kind': kind}
        if kind == 'blend':
            section = {'kind': 'blend', 'from': {'kind': 'homotopy'}, 'to': {'kind': 'spl_circular'}}
        check_law_names(make_law(section))
