"""`swarm report` on a bag built from a batch-engine run gives what the run itself gives.

The homotopy_global run (paper Fig. 3: one swarm, a split into two subswarms led by one leader
each, a reunion) is serialised as the ROS nodes publish it (Odometry per agent per step, λ as
Float64, leaders as a latched std_msgs/String), written with the project's writer, and the
report's trajectory, metrics and cluster history are compared with the run's own.
"""
from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from swarm_core import engine, metrics, scenario
from swarm_core.frenet import quaternion_from_heading

RECORD_EVERY = 5          # every 5th step: 0.5 time units between recorded states at dt = 0.1, 2001 x 6 agents


@pytest.fixture(scope='module')
def run():
    scn = scenario.load('homotopy_global')
    return scn, engine.simulate(scn, record_every=RECORD_EVERY)


def write_bag(traj, path, *, leaders=True, lam=True, cut_after=None, metrics_cutoff=None,
              target=None, barrier=None):
    """The run as the ROS nodes would have published it, written with BagWriter (with
    ``metrics_cutoff``: one /world/metrics message carrying it, as the world publishes; with
    ``target`` / ``barrier``: the world's latched /world/target and /world/barrier)."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64, String

    from swarm_tools.bag import BagWriter, qos_dict

    vol = [qos_dict(history=1, depth=10, reliability=1, durability=2)]
    latched = [qos_dict(history=1, depth=1, reliability=1, durability=1)]
    w = BagWriter(path, flush_interval=3600)
    w.add_topic('/swarm/states', 'nav_msgs/msg/Odometry', vol)
    if metrics_cutoff is not None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        w.add_topic('/world/metrics', 'diagnostic_msgs/msg/DiagnosticArray', vol)
        st = DiagnosticStatus(name='swarm', hardware_id='world', values=[
            KeyValue(key='clusters', value='1'), KeyValue(key='cutoff_radius', value=str(metrics_cutoff))])
        w.write('/world/metrics', serialize_message(DiagnosticArray(status=[st])), 1_700_000_000 * 10**9)
    if target is not None:
        from geometry_msgs.msg import PointStamped
        w.add_topic('/world/target', 'geometry_msgs/msg/PointStamped', latched)
        m = PointStamped()
        m.point.x, m.point.y = map(float, target)
        w.write('/world/target', serialize_message(m), 1_700_000_000 * 10**9)
    if barrier is not None:
        from geometry_msgs.msg import Point32, PolygonStamped
        w.add_topic('/world/barrier', 'geometry_msgs/msg/PolygonStamped', latched)
        m = PolygonStamped()
        m.polygon.points = [Point32(x=float(x), y=float(y)) for x, y in barrier]
        w.write('/world/barrier', serialize_message(m), 1_700_000_000 * 10**9)
    if lam:
        w.add_topic('/swarm/lambda', 'std_msgs/msg/Float64', vol)
    if leaders:
        w.add_topic('/swarm/leaders', 'std_msgs/msg/String', latched)
    base = 1_700_000_000 * 10**9
    last_leaders = None
    qz, qw = quaternion_from_heading(traj.theta)
    for s in range(len(traj.t)):
        log = base + s * 1_000_000
        t_ns = int(round(traj.t[s] * 1e9))
        for k, name in enumerate(traj.names):
            m = Odometry()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
            m.header.frame_id = 'world'
            m.child_frame_id = name
            m.pose.pose.position.x = float(traj.r[s, k, 0])
            m.pose.pose.position.y = float(traj.r[s, k, 1])
            m.pose.pose.orientation.z = float(qz[s, k])
            m.pose.pose.orientation.w = float(qw[s, k])
            m.twist.twist.linear.x = 1.0
            # as agents publish it: the u held over the step that ended at this state
            m.twist.twist.angular.z = float(traj.u[s - 1, k]) if s > 0 else 0.0
            w.write('/swarm/states', serialize_message(m), log + k)
        # as the lockstep commander does: step s's inputs are decided from step s's states
        if lam:
            w.write('/swarm/lambda', serialize_message(Float64(data=float(traj.lam[s]))), log + 1000)
        who = tuple(np.array(traj.names)[traj.leader[s]])
        if leaders and who != last_leaders:
            w.write('/swarm/leaders', serialize_message(String(data=','.join(who))), log + 2000)
            last_leaders = who
        if cut_after is not None and s == cut_after:
            w.maybe_flush(force=True)
            w._fh.flush()
            return path          # like a killed recorder: no summary, no footer
    w.close()
    return path


def _history(series):
    c, t = series['clusters'], series['t']
    return [(round(float(t[i]), 6), int(c[i])) for i in range(len(c)) if i == 0 or c[i] != c[i - 1]]


def test_report_matches_the_run(run, tmp_path, swarm_cmd):
    scn, traj = run
    bag = write_bag(traj, tmp_path / 'global.mcap')
    out = tmp_path / 'report'
    res = subprocess.run([swarm_cmd, 'report', str(bag), '--out', str(out), '--cutoff-radius',
                          str(scn.law.cutoff_radius)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    doc = json.loads((out / 'metrics.json').read_text())

    every = int(round(1.0 / (scn.dt * RECORD_EVERY)))
    live = metrics.time_series(traj.t, traj.r, traj.theta, traj.leader, scn.law.cutoff_radius,
                               every=every)
    expected = _history(live)
    assert max(c for _, c in expected) == 2, 'the run should split into two subswarms'
    got = [(round(t, 6), c) for t, c in doc['summary']['cluster_changes']]
    assert got == expected
    assert doc['series']['clusters'] == live['clusters'].tolist()
    assert doc['series']['one_leader_per_cluster'] == live['one_leader_per_cluster'].tolist()
    assert doc['summary']['leaders_seen'] == [traj.names[k] for k in
                                              np.flatnonzero(traj.leader.any(axis=0))]

    rebuilt = engine.Trajectory.load(out / 'trajectory.npz')
    assert rebuilt.names == traj.names
    np.testing.assert_array_equal(rebuilt.r, traj.r)
    np.testing.assert_allclose(rebuilt.t, traj.t, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(rebuilt.u[:-1], traj.u[:-1])
    assert np.isnan(rebuilt.u[-1]).all(), 'the u after the newest state is not in the bag'
    np.testing.assert_array_equal(rebuilt.lam, traj.lam)
    np.testing.assert_array_equal(rebuilt.leader, traj.leader)
    d = np.angle(np.exp(1j * (rebuilt.theta - traj.theta)))
    assert np.abs(d).max() < 1e-9
    assert (out / 'report.png').stat().st_size > 10_000


def test_report_of_a_cut_bag_reads_to_the_last_chunk(run, tmp_path):
    """A bag whose writer died (no summary): the report still runs on what was written."""
    from swarm_tools import report

    _scn, traj = run
    bag = write_bag(traj, tmp_path / 'cut.mcap', cut_after=1200)
    out = tmp_path / 'rep'
    assert report.main([str(bag), '--out', str(out), '--no-figure']) == 0
    doc = json.loads((out / 'metrics.json').read_text())
    assert doc['summary']['truncated_bag'] is True
    rebuilt = engine.Trajectory.load(out / 'trajectory.npz')
    assert len(rebuilt.t) == 1201
    np.testing.assert_array_equal(rebuilt.r, traj.r[:1201])


def test_report_without_lambda_or_leaders_and_bad_input(run, tmp_path, capsys):
    from swarm_tools import report

    _scn, traj = run
    short = engine.Trajectory(traj.names, traj.t[:50], traj.r[:50], traj.theta[:50],
                              traj.u[:50], traj.lam[:50], traj.leader[:50])
    bag = write_bag(short, tmp_path / 'bare.mcap', leaders=False, lam=False)
    assert report.main([str(bag), '--out', str(tmp_path / 'r'), '--no-figure', '--animate']) == 0
    assert (tmp_path / 'r' / 'swarm.gif').read_bytes()[:6] in (b'GIF89a', b'GIF87a')
    doc = json.loads((tmp_path / 'r' / 'metrics.json').read_text())
    assert doc['summary']['has_lambda'] is False and doc['summary']['leaders_seen'] == []
    assert report.main([str(tmp_path / 'missing.mcap')]) == 2
    with pytest.raises(SystemExit):
        report.main([str(bag), '--cutoff-radius', '-1'])


def test_report_takes_the_cutoff_radius_from_the_bag(run, tmp_path, capsys):
    """No --cutoff-radius: the report counts clusters with the cutoff_radius on /world/metrics;
    a bag without it gets the law's default and a warning."""
    from swarm_core.laws import LawConfig
    from swarm_tools import report

    _scn, traj = run
    short = engine.Trajectory(traj.names, traj.t[:50], traj.r[:50], traj.theta[:50],
                              traj.u[:50], traj.lam[:50], traj.leader[:50])
    bag = write_bag(short, tmp_path / 'w.mcap', metrics_cutoff=0.5)
    assert report.main([str(bag), '--out', str(tmp_path / 'r'), '--no-figure']) == 0
    doc = json.loads((tmp_path / 'r' / 'metrics.json').read_text())
    assert doc['summary']['cutoff_radius'] == 0.5
    # agents 1 apart at the start: one swarm at w = 4, six singletons at w = 0.5
    assert doc['series']['clusters'][0] == 6
    assert 'no cutoff_radius' not in capsys.readouterr().err
    bare = write_bag(short, tmp_path / 'bare.mcap')
    assert report.main([str(bare), '--out', str(tmp_path / 'b'), '--no-figure']) == 0
    doc = json.loads((tmp_path / 'b' / 'metrics.json').read_text())
    assert doc['summary']['cutoff_radius'] == LawConfig.cutoff_radius
    assert doc['series']['clusters'][0] == 1
    assert 'no cutoff_radius on /world/metrics' in capsys.readouterr().err
