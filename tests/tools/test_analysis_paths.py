"""`swarm simulate`, `swarm run` and `swarm report` analyse a run the same way.

One short target_barrier run (target and barrier metrics included) is written by
``swarm simulate``; its trajectory goes into a bag as the nodes publish it.  The launcher's
rebuild from that bag (`outputs.salvage`, what ``swarm run`` does when the world saved
nothing) and ``swarm report`` (cutoff radius, target and barrier read from the bag) must give
the summary values ``swarm simulate`` gives, wherever their summaries share a key.  No ROS
graph: rclpy only serialises the messages.
"""
from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from swarm_core.analysis import outputs as analysis
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario import loader as scenario
from swarm_tools import simulate as simulate_cli
from tests.helpers import write_run_bag

DURATION = 20
#: keys every summary carries (swarm_core.analysis.outputs.run_summary)
SHARED = ('steps', 't_end', 'agents', 'final_clusters', 'max_clusters', 'min_distance',
          'final_polarisation', 'cluster_changes', 'intrusions_total', 'barrier_clearance',
          'closest_centroid_target_distance')


def _same(a, b, key):
    if isinstance(a, list):
        assert len(a) == len(b), key
        for x, y in zip(a, b):
            _same(x, y, key)
    elif isinstance(a, float) or isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-9), key
    else:
        assert a == b, key


def test_three_entry_points_share_one_analysis(tmp_path, capsys):
    from swarm_tools.bags import report
    from swarm_tools.run import outputs

    sim_dir = tmp_path / 'simulate'
    assert simulate_cli.simulate_main(['target_barrier', '--duration', str(DURATION), '--out',
                                       str(sim_dir), '--quiet', '--no-figure']) == 0
    sim = json.loads((sim_dir / 'metrics.json').read_text())
    traj = Trajectory.load(sim_dir / 'trajectory.npz')
    scn = scenario.load('target_barrier', duration=DURATION)
    assert len(traj.t) == scn.steps + 1

    bag = write_run_bag(traj, tmp_path / 'run.mcap', metrics_cutoff=scn.law.cutoff_radius,
                    target=scn.target, barrier=scn.barrier)
    run_dir = tmp_path / 'run'
    assert outputs.salvage(scn, run_dir, bag, 'lockstep', 0.0, figure=False)
    run = json.loads((run_dir / 'metrics.json').read_text())
    rep_dir = tmp_path / 'report'
    assert report.main([str(bag), '--out', str(rep_dir), '--no-figure']) == 0
    rep = json.loads((rep_dir / 'metrics.json').read_text())

    s = sim['summary']
    assert s['intrusions_total'] == 0 and s['closest_centroid_target_distance'] > 0
    for other in (run['summary'], rep['summary']):
        for key in SHARED:
            _same(other[key], s[key], key)
    assert rep['summary']['cutoff_radius'] == scn.law.cutoff_radius       # from the bag
    # the launcher judges the scenario's checks as swarm simulate does
    assert {k: v['passed'] for k, v in run['summary']['checks'].items()} == \
        {k: v['passed'] for k, v in s['checks'].items()}
    assert run['summary']['behaviour_ok'] == s['behaviour_ok']
    # the same series, sample by sample
    for doc in (run, rep):
        assert doc['series'].keys() == sim['series'].keys()
        for key, values in sim['series'].items():
            _same(doc['series'][key], values, key)


def test_jsonable_writes_nan_as_null():
    doc = dict(a=np.array([1.0, np.nan, np.inf]), b=np.float64(np.nan), c=np.int64(3),
               d=np.array([True, False]))
    assert json.loads(analysis.dumps(doc)) == dict(a=[1.0, None, None], b=None, c=3, d=[True, False])


def test_cluster_changes():
    series = dict(t=np.arange(5.0), clusters=np.array([1, 1, 2, 2, 1]))
    assert analysis.cluster_changes(series) == [(0.0, 1), (2.0, 2), (4.0, 1)]


def _odometry_cdr(end, frame, child, sec, nsec, doubles):
    """A serialized nav_msgs/Odometry in byte order ``end``, packed by hand (XCDR1)."""
    body = struct.pack(end + 'iI', sec, nsec)
    for s in (frame, child):
        b = s.encode() + b'\0'
        body += b'\0' * (-len(body) % 4) + struct.pack(end + 'I', len(b)) + b
    body += b'\0' * (-len(body) % 8)
    return (b'\0\1\0\0' if end == '<' else b'\0\0\0\0') + body + struct.pack(end + '85d', *doubles)


@pytest.mark.parametrize('end', ['<', '>'])
def test_one_odometry_decoder_for_the_world_and_the_report(end):
    """Both byte orders; the report's fields (frame_id, stamp, vx) and the world's (pose, u,
    sender tag) come from the one decoder."""
    from swarm_ros import protocol as P
    from swarm_tools.bags.mcap_io import parse_odometry
    d = np.arange(85, dtype=float) / 8
    raw = _odometry_cdr(end, 'map', 'agent_3', 12, 345, d)
    name, sec, nsec, pose, wz, tag = P.cdr_to_odometry_tagged(raw)
    assert (name, sec, nsec, wz, tag) == ('agent_3', 12, 345, d[48], d[7 + P.SENDER_TAG_INDEX])
    assert pose == (d[0], d[1], d[3], d[4], d[5], d[6])
    assert parse_odometry(raw) == dict(stamp_ns=12_000_000_345, frame_id='map', child_frame_id='agent_3',
                                       x=d[0], y=d[1], qz=d[5], qw=d[6], vx=d[43], wz=d[48])
