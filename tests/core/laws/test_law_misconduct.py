"""A law that leaves a thread running (tests/helpers.FAULTY_LAWS's LeavesThread): the command
that ran it ends at once with one line, in the batch engine and in a sweep's worker processes
(Python would otherwise wait for that thread at the exit for ever).  In subprocesses: the
thread never ends."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import faulty_law_scenario

SWARM = str(Path(sys.executable).parent / 'swarm')


@pytest.mark.parametrize('args', [['simulate', '--no-figure'], ['sweep', '--seeds', '2', '--jobs', '2']],
                         ids=['simulate', 'sweep-workers'])
def test_a_law_that_leaves_a_thread_ends_the_command_with_one_line(tmp_path, args):
    path = faulty_law_scenario(tmp_path, 'faulty.py:LeavesThread')
    verb, *rest = args
    r = subprocess.run([SWARM, verb, str(path), *rest, '--out', str(tmp_path / 'out'), '--quiet'],
                       capture_output=True, text=True, timeout=120)
    said = [ln for ln in r.stderr.splitlines() if 'faulty.py' in ln]
    assert r.returncode == 1, r.stderr
    assert len(said) == 1 and 'LeavesThread left a thread running (never-ends): a law may not start threads' in said[0]
    assert '(at t = 5.1, step 51)' in said[0] and 'Traceback' not in r.stderr, r.stderr


@pytest.mark.parametrize('module', [False, True], ids=['file', 'module'])
def test_a_law_file_that_exits_at_import_is_one_line(tmp_path, module):
    (tmp_path / 'exits.py').write_text('import sys\nsys.exit(4)\n')
    kind = 'exits:Law' if module else 'exits.py:Law'
    path = tmp_path / 's.yaml'
    path.write_text(f'name: x\nseed: 0\ndt: 0.1\nduration: 2\nagents: {{count: 3}}\nlaw: {{kind: "{kind}"}}\n')
    env = {**os.environ, 'PYTHONPATH': f'{tmp_path}:{os.environ.get("PYTHONPATH", "")}'}
    r = subprocess.run([SWARM, 'simulate', str(path), '--no-figure', '--out', str(tmp_path / 'o')],
                       capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [
        f"swarm: {path}: law.kind '{kind}': {'module exits' if module else 'exits.py'} does not import: "
        'SystemExit: 4'], r.stderr


def test_a_nul_in_a_path_is_one_line(tmp_path):
    from swarm_core.checks import InputError
    from swarm_core.scenario.loader import ScenarioError, load, parse
    for name in ('a\0b.yaml', 'a\0b'):
        with pytest.raises(ScenarioError, match='a path with a NUL byte names no scenario file'):
            load(name)
    data = {'name': 'x', 'agents': {'count': 3}, 'law': {'kind': 'ex\0its.py:Law'}}
    with pytest.raises((ScenarioError, InputError), match="a NUL byte is in no file's or module's name"):
        parse(data, 'inline')


VANISH = ('import os\nimport numpy as np\nfrom swarm_core.laws import Law, param\n\n\nclass Vanish(Law):\n'
          '    gain = param(0.1, lo=0.0, hi=1.0)\n\n    def control(self, view):\n        if view.t > 5:\n'
          '            os._exit(0)\n        return np.zeros(view.receivers.size)\n')


@pytest.mark.parametrize('study', [False, True], ids=['sweep', 'study'])
def test_a_worker_whose_law_calls_os_exit_stops_the_sweep_with_one_line(tmp_path, study):
    """os._exit in a law ends a sweep's worker without a word: one line, exit 1, no
    BrokenProcessPool traceback (a study keeps its cache)."""
    (tmp_path / 'vanish.py').write_text(VANISH)
    path = faulty_law_scenario(tmp_path, 'vanish.py:Vanish')
    more = ['--set', 'law.gain=0.1,0.2', '--out', str(tmp_path / 'study'), '--no-figure'] if study else []
    r = subprocess.run([SWARM, 'sweep', str(path), '--seeds', '2', '--jobs', '2', '--quiet', *more],
                       capture_output=True, text=True, timeout=120)
    said = [ln for ln in r.stderr.splitlines() if 'ended without a word' in ln]
    assert r.returncode == 1 and len(said) == 1 and 'Traceback' not in r.stderr, r.stderr
    assert 'the study stops' in said[0] if study else said[0].endswith('the sweep stops')
