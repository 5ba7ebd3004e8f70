"""A study cache entry that is not a regular file of this run (a symbolic link, a directory, a
FIFO, another key's file) is ignored with one warning and run again, and the study's outputs are
still written; nothing is written through a link planted at an entry.  A cut or non-JSON file:
tests/core/test_hostile_inputs.py."""
from __future__ import annotations

import json
import os
import shutil
import threading
import warnings

import pytest

from swarm_tools import simulate as simulate_cli

ARGV = ['homotopy_global', '--set', 'law.leader_gain=10', '--seeds', '1', '--duration', '2',
        '--jobs', '1', '--quiet', '--no-figure']


def _first_run(out):
    """A one-run study into ``out``: its runs.csv and the path of its one cache entry."""
    assert simulate_cli.sweep_main([*ARGV, '--out', str(out)]) == 0
    (entry,) = (out / 'cache').glob('*.json')
    return (out / 'runs.csv').read_text(), entry


def _plant(kind, entry, tmp_path):
    """Put a ``kind`` of entry at the path of the cache entry ``entry``; the file a link points
    to (its content must not change), else None."""
    good = entry.read_text()
    entry.unlink()
    if kind == 'symlink':
        target = tmp_path / 'elsewhere.json'
        target.write_text(good)                 # even a good row: a link is not this run's file
        entry.symlink_to(target)
        return target
    if kind == 'dangling symlink':
        entry.symlink_to(tmp_path / 'no-such-file.json')
        return None
    if kind == 'directory':
        entry.mkdir()
    elif kind == 'fifo':
        os.mkfifo(entry)
    elif kind == 'other key':
        doc = json.loads(good)
        doc['key'] = 'f' * 24                   # another run's file copied over this one
        entry.write_text(json.dumps(doc))
    return None


@pytest.mark.parametrize('kind', ['symlink', 'dangling symlink', 'directory', 'fifo', 'other key'])
def test_an_entry_that_is_not_this_runs_file_is_run_again_and_the_outputs_written(tmp_path, kind):
    csv, entry = _first_run(tmp_path / 'first')
    out = tmp_path / 'second'
    shutil.copytree(tmp_path / 'first' / 'cache', out / 'cache', symlinks=True)
    entry = out / 'cache' / entry.name
    target = _plant(kind, entry, tmp_path)
    before = target.read_text() if target else None
    result = {}

    def sweep():                                # a FIFO opened for reading would block: a thread
        with warnings.catch_warnings(record=True) as warned:
            warnings.simplefilter('always')
            result['rc'] = simulate_cli.sweep_main([*ARGV, '--out', str(out)])
        result['warned'] = [str(w.message) for w in warned if issubclass(w.category, UserWarning)]
    worker = threading.Thread(target=sweep, daemon=True)
    worker.start()
    worker.join(120)
    if worker.is_alive():                       # unblock the reader so the thread ends
        with open(entry, 'w'):
            pass
        worker.join(30)
        pytest.fail(f'the study hung on a {kind} in its cache')
    assert result['rc'] == 0
    warned = [w for w in result['warned'] if 'study cache' in w]
    assert len(warned) == 1 and 'running it again' in warned[0] and entry.name in warned[0], result['warned']
    assert (out / 'runs.csv').read_text() == csv                  # the same row, computed again
    assert (out / 'rates.csv').is_file() and (out / 'rates.md').is_file()
    if target is not None:
        assert entry.is_symlink() and target.read_text() == before   # not written through the link



def test_a_change_to_the_robot_description_file_is_a_change_of_the_runs(tmp_path):
    """The cache key of a cell that names a robot description follows the file's content, as a
    user's law file does: an edited description is run again, not taken from the cache."""
    from swarm_core import study as st
    from swarm_core.study.runner import tasks
    desc = tmp_path / 'robot.yaml'
    desc.write_text('wheel_radius: 0.05\n')
    study = st.make_study('homotopy_global', [('robot_set', ['all'])], seeds=1,
                          fixed={'robots.description': str(desc)})
    before = [t.key for t in tasks(study, version='v')]
    assert before == [t.key for t in tasks(study, version='v')]          # the same file: the same runs
    desc.write_text('wheel_radius: 0.06\n')
    assert not set(before) & {t.key for t in tasks(study, version='v')}
