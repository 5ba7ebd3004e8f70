"""Realtime deaths are seen: an agent process SIGKILLed from outside in a realtime run is lost
after the world's missing_timeout, as in lockstep: a ``lost`` event on /swarm/events and in
events.jsonl, and it leaves the cluster count (live and in the final metrics) instead of staying
frozen where it died.  The decisions: tests/world/test_realtime_liveness.py."""
from __future__ import annotations

import json
import os
import signal

import numpy as np

from tests.helpers import ROOT

SCENARIO = ROOT / 'examples' / 'six_agents_live.yaml'      # λ = 0: one swarm of six


def test_a_sigkilled_realtime_agent_is_lost_and_leaves_the_clusters(swarm):
    run = swarm(SCENARIO, mode='realtime', rtf=2, duration=16, missing_timeout=1.5, no_figure=True)
    run.wait_until(lambda m: m['t'] >= 3, timeout=10)
    pid = json.loads((run.out / 'pids.json').read_text())['agent_5']
    os.kill(pid, signal.SIGKILL)                      # from outside: no fault, no event of its own
    # the world notices within missing_timeout wall s (3 sim s at rtf 2), and says so on /swarm/events
    lost = run.wait_until(lambda m: any(e.get('kind') == 'lost' for e in run.events()), timeout=8)
    assert lost is not None
    ev = next(e for e in run.events() if e.get('kind') == 'lost')
    assert ev['agent'] == 'agent_5' and ev['node'] == 'world' and ev['silent_for'] >= 1.5, ev
    # the five others fly on as one swarm, and the dead one is not a cluster of its own
    assert run.wait_until(lambda m: m['t'] >= ev['t'] + 6, timeout=12)['clusters'] == 1
    assert run.wait(timeout=60) == 0, ''.join(run.log[-30:])
    events = [json.loads(ln) for ln in (run.out / 'events.jsonl').read_text().splitlines()]
    assert [(e['kind'], e['agent']) for e in events if e['kind'] == 'lost'] == [('lost', 'agent_5')]
    summary = run.metrics_json()['summary']
    assert summary['final_clusters'] == 1, summary
    traj = run.trajectory()
    k = ev['step']
    assert np.isnan(traj.r[k:, 5]).all() and np.isfinite(traj.r[:k, 5]).all()   # not held where it died
    assert np.isfinite(traj.r[:, :5]).all()
