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

from swarm_core.analysis import metrics
from swarm_core.engine import reference as engine
from swarm_core.scenario import loader as scenario
from tests.helpers import write_run_bag

RECORD_EVERY = 5          # every 5th step: 0.5 time units between recorded states at dt = 0.1, 2001 x 6 agents


@pytest.fixture(scope='module')
def run():
    scn = scenario.load('homotopy_global')
    return scn, engine.simulate(scn, record_every=RECORD_EVERY)


def _history(series):
    c, t = series['clusters'], series['t']
    return [(round(float(t[i]), 6), int(c[i])) for i in range(len(c)) if i == 0 or c[i] != c[i - 1]]


def test_report_matches_the_run(run, tmp_path, swarm_cmd):
    scn, traj = run
    bag = write_run_bag(traj, tmp_path / 'global.mcap')
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
    from swarm_tools.bags import report

    _scn, traj = run
    bag = write_run_bag(traj, tmp_path / 'cut.mcap', cut_after=1200)
    out = tmp_path / 'rep'
    assert report.main([str(bag), '--out', str(out), '--no-figure']) == 0
    doc = json.loads((out / 'metrics.json').read_text())
    assert doc['summary']['truncated_bag'] is True
    rebuilt = engine.Trajectory.load(out / 'trajectory.npz')
    assert len(rebuilt.t) == 1201
    np.testing.assert_array_equal(rebuilt.r, traj.r[:1201])


def test_report_without_lambda_or_leaders_and_bad_input(run, tmp_path, capsys):
    from swarm_tools.bags import report

    _scn, traj = run
    short = engine.Trajectory(traj.names, traj.t[:50], traj.r[:50], traj.theta[:50],
                              traj.u[:50], traj.lam[:50], traj.leader[:50])
    bag = write_run_bag(short, tmp_path / 'bare.mcap', leaders=False, lam=False)
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
    from swarm_core.laws import Law
    from swarm_tools.bags import report

    _scn, traj = run
    short = engine.Trajectory(traj.names, traj.t[:50], traj.r[:50], traj.theta[:50],
                              traj.u[:50], traj.lam[:50], traj.leader[:50])
    bag = write_run_bag(short, tmp_path / 'w.mcap', metrics_cutoff=0.5)
    assert report.main([str(bag), '--out', str(tmp_path / 'r'), '--no-figure']) == 0
    doc = json.loads((tmp_path / 'r' / 'metrics.json').read_text())
    assert doc['summary']['cutoff_radius'] == 0.5
    # agents 1 apart at the start: one swarm at w = 4, six singletons at w = 0.5
    assert doc['series']['clusters'][0] == 6
    assert 'no cutoff_radius' not in capsys.readouterr().err
    bare = write_run_bag(short, tmp_path / 'bare.mcap')
    assert report.main([str(bare), '--out', str(tmp_path / 'b'), '--no-figure']) == 0
    doc = json.loads((tmp_path / 'b' / 'metrics.json').read_text())
    assert doc['summary']['cutoff_radius'] == Law.cutoff_radius.default
    assert doc['series']['clusters'][0] == 1
    assert 'no cutoff_radius on /world/metrics' in capsys.readouterr().err
