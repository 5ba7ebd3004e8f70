"""The shipped `ros2 bag record` QoS override file (src/swarm_tools/config/record_qos_overrides.yaml)
used by a rosbag2 recorder emulation (tests/fakes/rosbag2_record.py: discovery, QoS adaptation, overrides as
rosbag2 Jazzy does them; see its docstring) on a lockstep run: every /swarm/states message of
every agent is received.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

from swarm_ros import protocol as P
from tests.helpers import FAKES, ROOT, short_homotopy

OVERRIDES = ROOT / 'src' / 'swarm_tools' / 'config' / 'record_qos_overrides.yaml'
EMULATION = FAKES / 'rosbag2_record.py'


def test_rosbag2_style_recorder_with_overrides_loses_no_state(ros_domain, processes, swarm_cmd, tmp_path):
    """`ros2 bag record -a --qos-profile-overrides-path FILE` started before a lockstep
    `swarm run --state-readers 1`: each agent's states of steps 0..last all arrive.  (The run has fewer states
    than the agents' writer history (`STATES_DEPTH`), so a datagram lost under load is resent
    on a heartbeat, at the latest while a stopped agent waits for its acknowledgements; in a
    longer run a recorder slower than the run loses what drops out of that history, measured by
    scripts/bench_bag_qos.py.)"""
    steps, dt = 90, 0.05
    assert steps < P.STATES_DEPTH
    scn = short_homotopy(tmp_path / 'scn.yaml', duration=steps * dt, lam='{kind: constant, value: 0.0}', at=1000.0)
    rec = processes.start([sys.executable, EMULATION, '--qos-profile-overrides-path', OVERRIDES],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert 'ready' in rec.stderr.readline()
    # --state-readers 1: the agents' first states wait for the recorder's reader (a short run
    # is over before a recorder that has not yet discovered an agent's writer could match it)
    run = processes.start([swarm_cmd, 'run', scn, '--mode', 'lockstep', '--no-figure', '--state-readers', '1',
                           '--out', tmp_path / 'run'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True)
    out = processes.communicate(run, timeout=600)
    assert run.returncode == 0, out[-3000:]
    os.killpg(rec.pid, signal.SIGINT)
    report = json.loads(processes.communicate(rec, timeout=60).strip().splitlines()[-1])
    assert report['requested']['/swarm/states'] == {'depth': 1000, 'reliability': 'reliable',
                                                    'durability': 'transient_local'}
    assert len(report['states']) == 6, sorted(report['states'])
    for name, stamps in report['states'].items():
        got = sorted({round(s / (dt * 1e9)) for s in stamps})
        assert got[-1] >= steps and got == list(range(got[-1] + 1)), \
            (name, got[-1], sorted(set(range(got[-1] + 1)) - set(got)))
