"""A real recorded run: `swarm run SCENARIO --record BAG.mcap` (agents, world and commander as
processes, lockstep), the bag read back with two readers and reported on.

The scenario is homotopy_global with the split brought forward (λ rises at t = 8, leaders
steer harder), so that a 30 s run shows one swarm becoming two subswarms. Its cutoff radius
(5) is not the law's default (4), so a report that did not read it from the bag would count
other clusters.
"""
from __future__ import annotations

import json
import subprocess
from collections import defaultdict

import numpy as np
import pytest

from tests.helpers import short_homotopy


@pytest.fixture
def recorded_run(ros_domain, processes, swarm_cmd, tmp_path):
    scn_file = short_homotopy(tmp_path / 'early_split.yaml', name='early_split',
                              description='homotopy_global with the split brought forward (bag tests)',
                              duration=30, at=2, curvature=0.05, law={'cutoff_radius': 5.0},
                              lam={'kind': 'tanh_window', 'rise_at': 8, 'fall_at': 1000, 'tau': 2})
    bag = tmp_path / 'run.mcap'
    out = tmp_path / 'live'
    proc = processes.start([swarm_cmd, 'run', scn_file, '--record', bag, '--out', out,
                            '--no-figure'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
    text = processes.communicate(proc, 240)
    assert proc.returncode == 0, text
    return bag, out, text


def test_recorded_lockstep_run(recorded_run, swarm_cmd, tmp_path):
    from mcap_ros2.reader import read_ros2_messages
    from rosbags.highlevel import AnyReader

    from swarm_core.engine.trajectory import Trajectory
    from swarm_core.model.frenet import yaw_from_quaternion

    bag, live_dir, text = recorded_run
    assert 'lost: 0' in text, text
    assert 'missing between first and last: 0' in text, text
    live = Trajectory.load(live_dir / 'trajectory.npz')
    steps = len(live.t) - 1
    assert steps == 600

    # reader 1: rosbags decodes every message of every topic
    per_topic = defaultdict(int)
    with AnyReader([bag]) as reader:
        for conn, _t, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            per_topic[conn.topic] += 1
    # reader 2: mcap_ros2 decodes them too; the states, per agent, are the run's
    states = defaultdict(dict)
    per_topic2 = defaultdict(int)
    for m in read_ros2_messages(str(bag)):
        per_topic2[m.channel.topic] += 1
        if m.channel.topic == '/swarm/states':
            s = m.ros_msg
            t_ns = s.header.stamp.sec * 10**9 + s.header.stamp.nanosec
            assert t_ns not in states[s.child_frame_id], 'a state recorded twice'
            states[s.child_frame_id][t_ns] = s
    assert per_topic2 == per_topic
    assert sorted(states) == sorted(live.names)
    for k, name in enumerate(live.names):
        got = states[name]
        grid = [int(round(t * 1e9)) for t in live.t]
        missing = [i for i, t in enumerate(grid) if t not in got]
        assert not missing, f'{name}: missing steps {missing[:10]} of {len(grid)}'
        # every step run is there (the agents may publish one more state after the last step)
        assert len(got) in (steps + 1, steps + 2)
        pos = np.array([[got[t].pose.pose.position.x, got[t].pose.pose.position.y] for t in grid])
        np.testing.assert_array_equal(pos, live.r[:, k])
        yaw = np.array([yaw_from_quaternion(got[t].pose.pose.orientation.z,
                                            got[t].pose.pose.orientation.w) for t in grid])
        assert np.abs(np.angle(np.exp(1j * (yaw - live.theta[:, k])))).max() < 1e-9
    assert per_topic['/swarm/leaders'] >= 1 and per_topic['/clock'] >= steps

    # the report from the bag alone (no --cutoff-radius: the bag's /world/metrics carries it):
    # the live run's cluster history (one swarm, then two)
    rep = tmp_path / 'report'
    res = subprocess.run([swarm_cmd, 'report', str(bag), '--out', str(rep)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    mine = json.loads((rep / 'metrics.json').read_text())
    theirs = json.loads((live_dir / 'metrics.json').read_text())
    assert mine['summary']['cutoff_radius'] == 5.0, res.stderr
    assert theirs['summary']['cluster_changes'][-1][1] == 2, 'the run should split'
    assert mine['summary']['cluster_changes'] == theirs['summary']['cluster_changes']
    n = len(theirs['series']['clusters'])
    assert mine['series']['clusters'][:n] == theirs['series']['clusters']
    assert mine['summary']['leaders_seen'] == [live.names[k] for k in
                                               np.flatnonzero(live.leader.any(axis=0))]
    assert (rep / 'report.png').is_file()
    # the u the report reads from the states is the u the agents applied (the last state's u
    # is carried by a state after the run, if the bag has one)
    rebuilt = Trajectory.load(rep / 'trajectory.npz')
    np.testing.assert_array_equal(rebuilt.r[:steps + 1], live.r)
    np.testing.assert_array_equal(rebuilt.u[:steps], live.u[:steps])
