"""Output paths: no write follows a symbolic link or replaces anything but a regular file
where an output goes; `--force` never replaces a device, FIFO or directory."""
from __future__ import annotations

import os
import stat
import subprocess
import sys

import pytest

SCN = """
name: tiny
dt: 0.1
duration: 1
agents:
  positions: [[0, 0], [1, 0], [0, 1]]
law: {kind: global}
"""


def _planted(tmp_path):
    """A link to a file outside, a FIFO, a directory and a device (/dev/full's numbers)."""
    victim = tmp_path / 'victim.txt'
    victim.write_text('precious')
    d = tmp_path / 'out'
    d.mkdir()
    (d / 'link').symlink_to(victim)
    os.mkfifo(d / 'fifo')
    (d / 'dir').mkdir()
    os.mknod(d / 'dev', stat.S_IFCHR | 0o666, os.makedev(1, 7))
    return victim, d


def test_writers_refuse_links_devices_fifos_and_directories(tmp_path):
    from swarm_core.files import atomic_open, open_regular
    victim, d = _planted(tmp_path)
    for name in ('link', 'fifo', 'dir', 'dev'):
        with pytest.raises(OSError, match='not a regular file'):
            with atomic_open(d / name) as fh:
                fh.write('x')
        with pytest.raises(OSError, match='not a regular file'):
            open_regular(d / name)
    assert victim.read_text() == 'precious'
    assert (d / 'link').is_symlink() and stat.S_ISFIFO(os.lstat(d / 'fifo').st_mode)
    assert stat.S_ISCHR(os.lstat(d / 'dev').st_mode) and (d / 'dir').is_dir()
    assert sorted(p.name for p in d.iterdir()) == ['dev', 'dir', 'fifo', 'link']    # no temporary left
    with atomic_open(d / 'new.txt') as fh:          # a regular file is written and replaced
        fh.write('one')
    with open_regular(d / 'new.txt', 'a') as fh:
        fh.write(' two')
    assert (d / 'new.txt').read_text() == 'one two'


def _swarm(*args):
    return subprocess.run([sys.executable, '-m', 'swarm_tools.cli', *map(str, args)], capture_output=True,
                          text=True, timeout=300)


def test_sweep_and_bag_recover_do_not_write_through_planted_files(tmp_path):
    """Symlinks planted as runs.csv and the figure were written through, and `swarm bag recover
    X /dev/full --force` replaced the device node with a file."""
    victim = tmp_path / 'victim.txt'
    victim.write_text('precious')
    scn = tmp_path / 'tiny.yaml'
    scn.write_text(SCN)
    out = tmp_path / 'study'
    out.mkdir()
    (out / 'runs.csv').symlink_to(victim)
    r = _swarm('sweep', scn, '--set', 'law.leader_gain=10', '--seeds', '1', '--jobs', '1', '--quiet', '--out', out)
    assert r.returncode == 1 and 'Traceback' not in r.stderr, r.stderr
    assert 'symbolic link' in r.stderr and 'runs.csv' in r.stderr, r.stderr
    assert victim.read_text() == 'precious' and (out / 'runs.csv').is_symlink()
    (out / 'runs.csv').unlink()
    (out / 'tiny.png').symlink_to(victim)
    r = _swarm('sweep', scn, '--set', 'law.leader_gain=10', '--seeds', '1', '--jobs', '1', '--quiet', '--out', out)
    assert r.returncode == 1 and 'tiny.png' in r.stderr and 'Traceback' not in r.stderr, r.stderr
    assert victim.read_text() == 'precious' and (out / 'rates.md').is_file()

    from swarm_tools.bags.mcap_io import BagWriter
    bag = tmp_path / 'b.mcap'
    BagWriter(bag).close()
    dev = tmp_path / 'full'
    os.mknod(dev, stat.S_IFCHR | 0o666, os.makedev(1, 7))
    r = _swarm('bag', 'recover', bag, dev, '--force')
    assert r.returncode != 0 and 'a device' in r.stderr and 'Traceback' not in r.stderr, r.stderr
    assert stat.S_ISCHR(os.lstat(dev).st_mode)
