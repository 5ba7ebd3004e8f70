"""A full disk under a run's bag (`swarm run --record`): one line and a non-zero exit, no
traceback, and the run's other outputs written.  The disk is a tiny tmpfs (needs root to
mount); the pure verbs on a full disk: tests/tools/test_full_disk.py."""
from __future__ import annotations

import subprocess
import time

import pytest

from tests.helpers import SIX_GLOBAL, tiny_disk


@pytest.mark.parametrize('room', ['none', 'little'])
def test_run_record_on_a_full_disk_is_one_line_and_a_nonzero_exit(ros_domain, processes, swarm_cmd, tmp_path, room):
    """The bag on a full disk: the recorder died with a traceback, the nodes waited for it
    (60 s), the launcher said exit 0 with a 0-byte bag.  Now the run goes on without waiting,
    its other outputs (on another disk) are written, and the exit is 1.  ``little``: the disk
    fills up during the run (the recording stops with one line)."""
    scn = tmp_path / 'six.yaml'
    scn.write_text(SIX_GLOBAL.replace('duration: 8', 'duration: 20'))
    with tiny_disk(tmp_path / 'disk') as disk:
        if room == 'little':
            (disk / 'filler').unlink()
            with open(disk / 'filler', 'wb') as f:
                f.write(b'\0' * (256 - 24) * 1024)
        t0 = time.monotonic()
        proc = processes.start([swarm_cmd, 'run', scn, '--record', disk / 'run.mcap', '--out', tmp_path / 'out',
                                '--no-figure'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        text = processes.communicate(proc, 240)
        wall = time.monotonic() - t0
    assert proc.returncode == 1, text
    assert 'Traceback' not in text and 'No space left on device' in text, text
    assert 'is not complete' in text, text
    assert wall < 45, (wall, text)
    assert (tmp_path / 'out' / 'trajectory.npz').is_file() and (tmp_path / 'out' / 'metrics.json').is_file()
