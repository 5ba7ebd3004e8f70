"""A law that leaves a thread running (tests/helpers.FAULTY_LAWS's LeavesThread): the command
that ran it ends at once with one line, in the batch engine and in a sweep's worker processes
(Python would otherwise wait for that thread at the exit for ever).  In subprocesses: the
thread never ends."""
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
