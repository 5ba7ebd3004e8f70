"""Hostile and damaged bags: type names from data import nothing unknown, a truncated bag is
recovered into a valid indexed one, and `swarm report` leaves out what cannot be a state of
the run instead of crashing or inventing an agent."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from swarm_core.engine import reference as engine
from swarm_core.scenario import loader as scenario
from tests.helpers import SIX_GLOBAL, odom_cdr, write_states_bag


@pytest.fixture(scope='module')
def traj(tmp_path_factory):
    f = tmp_path_factory.mktemp('scn') / 'six.yaml'
    f.write_text(SIX_GLOBAL)
    return engine.simulate(scenario.load(str(f)))


def test_message_class_imports_only_installed_interface_types(tmp_path, monkeypatch):
    """A type name from the graph or a bag's schema imported any module it named."""
    from swarm_tools.bags.record import message_class
    pkg = tmp_path / 'evil_pkg' / 'msg'
    pkg.mkdir(parents=True)
    (tmp_path / 'evil_pkg' / '__init__.py').write_text('')
    (pkg / '__init__.py').write_text('import os\nos.environ["EVIL_IMPORTED"] = "1"\nclass X: pass\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv('EVIL_IMPORTED', raising=False)
    for name in ['evil_pkg/msg/X', 'os/path/join', 'evil_pkg.msg/msg/X', '../x/msg/Y', 'std_msgs/msg/Nope']:
        with pytest.raises(ValueError):
            message_class(name)
    assert 'EVIL_IMPORTED' not in __import__('os').environ and 'evil_pkg.msg' not in sys.modules
    assert message_class('nav_msgs/msg/Odometry').__name__ == 'Odometry'


def test_bag_recover_rewrites_a_truncated_bag(traj, tmp_path, swarm_cmd):
    """A killed recorder's bag cannot be opened by mcap's default (seeking) reader;
    `swarm bag recover` writes one that can, with every message of the complete chunks."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    full = tmp_path / 'full.mcap'
    w = write_states_bag(traj, full, flush_every=7)       # the last steps stay in the open chunk
    w._fh.flush()
    size_open = full.stat().st_size          # everything flushed so far, no summary: as killed
    w.close()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(full.read_bytes()[:size_open - 7])     # cut inside the last chunk
    with pytest.raises(McapError):
        with open(cut, 'rb') as fh:
            list(make_reader(fh).iter_messages())
    out = tmp_path / 'fixed.mcap'
    r = subprocess.run([swarm_cmd, 'bag', 'recover', cut, out], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert 'input ends early' in r.stdout
    with open(out, 'rb') as fh:
        reader = make_reader(fh)
        assert reader.get_summary() is not None          # indexed: summary and chunk indexes
        msgs = list(reader.iter_messages())
    n = len(traj.names)
    assert n * 10 <= len(msgs) < n * len(traj.t)
    with open(full, 'rb') as fh:
        first = [m for _, _, m in make_reader(fh).iter_messages()][:len(msgs)]
    assert [m.data for _, _, m in msgs] == [m.data for m in first]
    assert {c.topic for _, c, _ in msgs} == {'/swarm/states'}
    again = subprocess.run([swarm_cmd, 'bag', 'recover', cut, out], capture_output=True, text=True, timeout=60)
    assert again.returncode == 2 and 'exists' in again.stderr     # no silent overwrite


def test_report_leaves_out_bad_states(traj, tmp_path, swarm_cmd):
    """NaN, inf, absurd stamps and unknown senders crashed the report or made a 7th agent."""
    bag = tmp_path / 'hostile.mcap'
    write_states_bag(traj, bag, hostile=True).close()
    r = subprocess.run([swarm_cmd, 'report', bag, '--out', tmp_path / 'rep', '--no-figure'],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / 'rep' / 'metrics.json').read_text())
    assert doc['summary']['names'] == list(traj.names)
    assert doc['summary']['t_end'] == pytest.approx(traj.t[-1])
    z = np.load(tmp_path / 'rep' / 'trajectory.npz')
    assert np.isfinite(z['r']).all() and len(z['t']) == len(traj.t)
    np.testing.assert_allclose(z['r'], traj.r, atol=1e-9)
    err = r.stderr
    assert 'non-finite or absurd values' in err and 'stamps outside' in err and "'ghost'" in err, err
    assert len(err.strip().splitlines()) <= 4, err       # one line per kind


def _chunks(path):
    from mcap.reader import make_reader
    with open(path, 'rb') as fh:
        return sorted((c.chunk_start_offset, c.chunk_length) for c in make_reader(fh).get_summary().chunk_indexes)


@pytest.mark.parametrize('where', ['data', 'length'])
def test_a_damaged_chunk_costs_only_that_chunk(traj, tmp_path, swarm_cmd, where):
    """One flipped byte mid-bag made `report` and `bag recover` drop every later chunk.
    ``data``: a byte inside a chunk's compressed records (its CRC fails); ``length``: the
    chunk's record length (the framing: the read goes on at the next indexed chunk)."""
    from swarm_tools.bags.mcap_io import iter_messages
    from swarm_tools.bags.recover import recover
    from swarm_tools.bags.report import read_run
    bag = tmp_path / 'bag.mcap'
    write_states_bag(traj, bag, flush_every=7).close()
    total = len(list(iter_messages(bag)))
    chunks = _chunks(bag)
    assert len(chunks) >= 8
    start, length = chunks[len(chunks) // 2]
    raw = bytearray(bag.read_bytes())
    raw[start + (length - 40 if where == 'data' else 8)] ^= 0xFF
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(bytes(raw))
    stats = {}
    kept = len(list(iter_messages(bad, stats=stats)))
    per_chunk = 7 * len(traj.names)
    assert total - per_chunk <= kept < total, (kept, total)
    assert stats['damaged'] == 1 and not stats['truncated'], stats
    res = recover(bad, tmp_path / 'fixed.mcap')
    assert res['messages'] == kept and res['damaged'] == 1, res
    warned = []
    run = read_run(bad, warn=warned.append)
    assert sorted(run['per_agent']) == sorted(traj.names)
    assert sum(len(v) for v in run['per_agent'].values()) == kept
    assert any('damaged' in w for w in warned), warned
    r = subprocess.run([swarm_cmd, 'bag', 'recover', bad, tmp_path / 'cli.mcap'],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and f'{kept} messages' in r.stdout and '1 damaged chunk' in r.stdout, r


def _string(text):
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String
    return serialize_message(String(data=text))


def test_report_takes_the_roster_from_the_run_announcement(traj, tmp_path, capsys):
    """A bag with many fake `agent_N` senders (a few states each, more of them than the run's
    agents) reported each as an agent; the run's /swarm/run announcement names the roster."""
    from swarm_ros.runinfo import run_json
    from swarm_tools.bags import report
    from swarm_tools.bags.mcap_io import qos_dict
    bag = tmp_path / 'spoofed.mcap'
    w = write_states_bag(traj, bag)
    latched = [qos_dict(history=1, depth=1, reliability=1, durability=1)]
    w.add_topic('/swarm/run', 'std_msgs/msg/String', latched)
    w.write('/swarm/run', _string(run_json('1a2b3c4d', 'six', 'lockstep', traj.names, 1.0)), 1)
    w.write('/swarm/run', _string(run_json('dead0000', 'fake', 'lockstep', ['agent_9'], 2.0)), 2)
    base = 2_000_000_000 * 10**9
    for i in range(300):
        for s in range(3):
            state = odom_cdr(f'agent_{100 + i}', int(traj.t[s] * 1e9), i, i, 0, 1, 0)
            w.write('/swarm/states', state, base + 3 * i + s)
    w.close()
    assert report.main([str(bag), '--out', str(tmp_path / 'rep'), '--no-figure']) == 0
    doc = json.loads((tmp_path / 'rep' / 'metrics.json').read_text())
    assert doc['summary']['names'] == list(traj.names)
    err = capsys.readouterr().err
    assert "left out 900 states of 300 unknown senders (not in the run's roster)" in err, err
    assert 'more than one run' in err and 'run 1a2b3c4d' in err, err


def test_play_republishes_only_the_projects_types(traj, tmp_path):
    """A second /swarm/states channel with schema os/msg/system was played as Odometry; a
    project topic of another type (here /swarm/lambda as String) is not the project's."""
    from swarm_tools.bags.mcap_io import bag_topics, qos_dict
    from swarm_tools.bags.play import foreign_lines
    from swarm_tools.bags.record import swarm_type
    bag = tmp_path / 'mixed.mcap'
    w = write_states_bag(traj, bag)
    sid = w._w.register_schema('os/msg/system', 'ros2msg', b'string cmd')
    cid = w._w.register_channel('/swarm/states', 'cdr', sid, {})
    for k in range(5):
        w._w.add_message(cid, 10**18 + k, _string('rm -rf /'), 10**18 + k)
    w.add_topic('/swarm/lambda', 'std_msgs/msg/String', [qos_dict()])
    w.write('/swarm/lambda', _string('1.0'), 10**18)
    w.add_topic('/my/tf', 'std_msgs/msg/String', [qos_dict()])       # not the project's: as recorded
    w.write('/my/tf', _string('x'), 10**18)
    w.close()
    topics = bag_topics(bag, swarm_type)
    states = topics['/swarm/states']
    assert states['type'] == 'nav_msgs/msg/Odometry' and states['channels'] == {w.topics['/swarm/states'].channel_id}
    assert states['count'] == len(traj.t) * len(traj.names) and states['other'] == {'os/msg/system': 5}
    assert topics['/swarm/lambda']['type'] is None
    assert topics['/my/tf']['type'] == 'std_msgs/msg/String' and topics['/my/tf']['count'] == 1
    lines = foreign_lines(topics)
    assert len(lines) == 2 and '5 messages of type os/msg/system' in lines[1], lines
    assert 'std_msgs/msg/Float64' in lines[0], lines
