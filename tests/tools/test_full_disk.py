"""A full or read-only disk under the outputs: one line and a non-zero exit, no traceback
(`swarm sweep`, `swarm report --out`).  The disk is a tiny tmpfs (needs root to mount); a
run's bag on a full disk: tests/tools/bags/ros/test_full_disk_run.py."""
from __future__ import annotations

import subprocess
import sys

from tests.helpers import SIX_GLOBAL, tiny_disk, write_states_bag


def _swarm(*args):
    return subprocess.run([sys.executable, '-m', 'swarm_tools.cli', *map(str, args)], capture_output=True,
                          text=True, timeout=300)


def _one_line(r, *words):
    assert r.returncode != 0, (r.returncode, r.stdout, r.stderr)
    assert 'Traceback' not in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) <= 2, r.stderr
    assert all(w in r.stderr for w in words), r.stderr


def test_sweep_and_report_on_a_full_or_read_only_disk(tmp_path):
    from swarm_core.engine import reference as engine
    from swarm_core.scenario import loader as scenario
    scn = tmp_path / 'six.yaml'
    scn.write_text(SIX_GLOBAL)
    bag = tmp_path / 'run.mcap'
    write_states_bag(engine.simulate(scenario.load(str(scn))), bag).close()
    with tiny_disk(tmp_path / 'full') as disk:
        r = _swarm('sweep', scn, '--set', 'law.leader_gain=10', '--seeds', '1', '--jobs', '1', '--quiet',
                   '--no-figure', '--out', disk / 'study')
        _one_line(r, 'No space left on device')
        r = _swarm('report', bag, '--out', disk / 'rep', '--no-figure')
        _one_line(r, 'No space left on device')
        assert [p.name for p in (disk / 'rep').iterdir()] == []          # no partial file left
    with tiny_disk(tmp_path / 'ro', full=False, read_only=True) as disk:
        r = _swarm('report', bag, '--out', disk, '--no-figure')
        _one_line(r, 'not writable')
