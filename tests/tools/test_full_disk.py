"""A full or read-only disk under the outputs: one line and a non-zero exit, no traceback
(`swarm sweep`, `swarm report --out`).  The disk is a tiny tmpfs (needs root to mount)."""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys

import pytest

from test_bag_hostile import SCN, write_bag


@contextlib.contextmanager
def tiny_disk(where, *, full=True, read_only=False):
    """A 256 KiB tmpfs at ``where``: filled up (``full``) or remounted read-only."""
    where.mkdir()
    if os.geteuid() != 0 or subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=256k', 'tmpfs', str(where)],
                                           capture_output=True).returncode != 0:
        pytest.skip('cannot mount a tmpfs here')
    try:
        if full:
            with open(where / 'filler', 'wb', buffering=0) as f, contextlib.suppress(OSError):
                while True:
                    f.write(b'\0' * 4096)
        if read_only:
            subprocess.run(['mount', '-o', 'remount,ro', str(where)], check=True)
        yield where
    finally:
        subprocess.run(['umount', '-l', str(where)], check=False)


def _swarm(*args):
    return subprocess.run([sys.executable, '-m', 'swarm_tools.cli', *map(str, args)], capture_output=True,
                          text=True, timeout=300)


def _one_line(r, *words):
    assert r.returncode != 0, (r.returncode, r.stdout, r.stderr)
    assert 'Traceback' not in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) <= 2, r.stderr
    assert all(w in r.stderr for w in words), r.stderr


def test_sweep_and_report_on_a_full_or_read_only_disk(tmp_path):
    from swarm_core import engine, scenario
    scn = tmp_path / 'six.yaml'
    scn.write_text(SCN)
    bag = tmp_path / 'run.mcap'
    write_bag(engine.simulate(scenario.load(str(scn))), bag).close()
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


@pytest.mark.ros
@pytest.mark.parametrize('room', ['none', 'little'])
def test_run_record_on_a_full_disk_is_one_line_and_a_nonzero_exit(ros_domain, processes, swarm_cmd, tmp_path, room):
    """The bag on a full disk: the recorder died with a traceback, the nodes waited for it
    (60 s), the launcher said exit 0 with a 0-byte bag.  Now the run goes on without waiting,
    its other outputs (on another disk) are written, and the exit is 1.  ``little``: the disk
    fills up during the run (the recording stops with one line)."""
    import time
    scn = tmp_path / 'six.yaml'
    scn.write_text(SCN.replace('duration: 8', 'duration: 20'))
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
