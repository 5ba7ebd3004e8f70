"""Faults end to end: `swarm run --processes --record` with scheduled faults (a frozen follower,
a killed leader with and without failover) and live ones (`swarm kill`, `swarm pause`, an agent
process killed from outside), asserted on what the bag holds and on the world's trajectory.

The scenario is homotopy_global's swarm with the split brought forward (λ rises at t = 8,
leaders steer ±0.05): by t = 14 (seed 0) there are two subswarms; the left leader is killed
then.  Measured with the batch engine (seeds 0, 1): with failover its subswarm turns at
0.049-0.051 over t = 16-24 (program 0.05); without, at −0.006 to −0.008.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess

import numpy as np
import pytest

from swarm_core.analysis import outcomes
from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from tests.helpers import Lines, short_homotopy

#: the scheduled faults: a follower frozen for 2 s at t = 6, the left leader killed at t = 14
SCHEDULED = [{'at': 6, 'freeze': 'agent_1', 'for': 2.0}, {'at': 14, 'kill': 'leader:0'}]
PROGRAM = 0.05


def bag_view(bag, names, dt, steps):
    """(t, r (T, n, 2), θ (T, n), events) from the bag: each agent's published states on the
    step grid (NaN where it published none) and the /swarm/events objects."""
    from swarm_core.model.frenet import yaw_from_quaternion
    from swarm_tools.bags.mcap_io import iter_messages, parse_float64, parse_odometry, parse_string
    T = steps + 1
    r = np.full((T, len(names), 2), np.nan)
    th = np.full((T, len(names)), np.nan)
    events, steering = [], {}
    for m in iter_messages(bag):
        if m.topic == '/swarm/states':
            s = parse_odometry(m.data)
            k = int(round(s['stamp_ns'] * 1e-9 / dt))
            if k < T:
                i = names.index(s['child_frame_id'])
                r[k, i] = s['x'], s['y']
                th[k, i] = yaw_from_quaternion(s['qz'], s['qw'])
        elif m.topic == '/swarm/events':
            events.append(json.loads(parse_string(m.data)))
        elif m.topic.endswith('/steering'):
            steering.setdefault(m.topic.split('/')[1], []).append(parse_float64(m.data))
    for i in range(len(names)):
        ok = np.isfinite(th[:, i])
        th[ok, i] = np.unwrap(th[ok, i])
    return np.arange(T) * dt, r, th, events, steering


def run(processes, swarm_cmd, tmp_path, *extra, name='faults', duration, **scenario):
    """`swarm run --record` of homotopy_global's swarm with the split brought forward (λ rises at
    t = 8, leaders chosen at t = 2 steer ±`PROGRAM`), ``scenario``: further keys."""
    path = short_homotopy(tmp_path / f'{name}.yaml', name='early_faults', duration=duration, at=2,
                          curvature=PROGRAM, lam={'kind': 'tanh_window', 'rise_at': 8, 'fall_at': 1000, 'tau': 2},
                          **scenario)
    out, bag = tmp_path / name, tmp_path / f'{name}.mcap'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--record', bag, '--no-figure',
                         '--progress-every', '5', *extra], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                        text=True)
    return path, out, bag, p


@pytest.mark.parametrize('failover', [True, False], ids=['failover', 'no_failover'])
def test_scheduled_faults_follower_frozen_leader_killed(failover, tmp_path, ros_domain, processes, swarm_cmd):
    extra = {'failover': {'timeout': 0.5}} if failover else {}
    path, out, bag, p = run(processes, swarm_cmd, tmp_path, duration=24, faults=SCHEDULED, **extra)
    text = processes.communicate(p, 300)
    assert p.returncode == 0, text
    assert 'killed (fault injection)' in text, text
    scn = load(str(path))
    ref = simulate(scn)
    live = Trajectory.load(out / 'trajectory.npz')
    # the world's trajectory equals the batch engine's, dead rows and all
    assert np.array_equal(np.isfinite(live.r), np.isfinite(ref.r))
    fin = np.isfinite(ref.r)
    np.testing.assert_array_equal(live.r[fin], ref.r[fin])     # exact
    assert np.nanmax(np.abs(live.theta - ref.theta)) < 1e-9    # θ comes back through the quaternion
    both = np.isfinite(live.u) & np.isfinite(ref.u)
    assert np.isnan(live.u[np.isnan(ref.u)]).all()
    np.testing.assert_array_equal(live.u[both], ref.u[both])
    assert np.array_equal(live.leader, ref.leader)
    # the events: the same as the batch engine's, in the events file and in the bag
    want = [(e['kind'], e.get('agent'), e['t']) for e in ref.meta['events']]
    got_file = [(e['kind'], e.get('agent'), e['t']) for e in
                map(json.loads, (out / 'events.jsonl').read_text().splitlines())]
    t, r, th, events, steering = bag_view(bag, scn.names, scn.dt, scn.steps)
    got_bag = [(e['kind'], e.get('agent'), e['t']) for e in events]
    assert sorted(got_file, key=str) == sorted(want, key=str)
    assert sorted(got_bag, key=str) == sorted(want, key=str)
    killed = next(e['agent'] for e in ref.meta['events'] if e['kind'] == 'kill')
    k = scn.names.index(killed)
    k0_kill = 280
    # from the bag: the frozen follower published nothing in (6, 8], the dead leader nothing after
    # 14, and every other state is there (depth-100 writers; agents wait for the recorder's match
    # before their first state)
    assert np.isnan(r[121:161, 1]).all() and np.isfinite(r[161:, 1]).all() and np.isfinite(r[:121, 1]).all()
    assert np.isnan(r[281:, k]).all() and np.isfinite(r[:280, k]).all()
    # the lost leader's subswarm, measured on the bag's states
    bag_traj = Trajectory(scn.names, t, r, th, np.zeros_like(th), np.zeros(len(t)), np.zeros_like(th, bool),
                          meta=dict(events=events))
    lost, group, t_kill = outcomes.lost_leader_group(bag_traj, scn.law.cutoff_radius, slot=0)
    assert lost == k and t_kill == 14.0 and group
    rate = outcomes.group_turn_rate(bag_traj, group, 16.0, 24.0)
    if failover:
        # swarm report rebuilds the world's view from the bag alone (dead rows NaN, freeze held)
        rep = tmp_path / 'report'
        res = subprocess.run([swarm_cmd, 'report', str(bag), '--out', str(rep), '--no-figure'],
                             capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        from_bag = Trajectory.load(rep / 'trajectory.npz')
        steps = np.round(from_bag.t / scn.dt).astype(int)          # compare at the same sim times
        keep = steps < len(live.t)
        fb, lv = from_bag.r[keep], live.r[steps[keep]]
        dead = steps[keep] >= k0_kill
        assert np.isnan(fb[dead, k]).all() and np.isfinite(fb[~dead, k]).all()
        both = np.isfinite(fb) & np.isfinite(lv)
        assert keep.sum() > 0.5 * len(live.t)
        np.testing.assert_array_equal(fb[both], lv[both])      # the bag holds the exact floats
        succ = next(e['agent'] for e in events if e['kind'] == 'failover')
        assert succ in [scn.names[j] for j in group]
        assert steering[succ][-1] == PROGRAM            # the commander steers the successor
        assert abs(rate - PROGRAM) < 0.2 * PROGRAM, rate
    else:
        assert not any(e['kind'] == 'failover' for e in events)
        assert abs(rate - PROGRAM) > 0.5 * PROGRAM, rate


def agent_pid(out, name):
    """The pid of an agent process, from the pids.json the launcher writes into --out."""
    return json.loads((out / 'pids.json').read_text())[name]


def test_live_kill_pause_and_lost_agent(tmp_path, ros_domain, processes, swarm_cmd):
    # 3000 steps (dt = 0.1): time for the live verbs to land while the run goes on
    path, out, bag, p = run(processes, swarm_cmd, tmp_path, '--missing-timeout', '3', name='live', duration=300,
                            dt=0.1)
    lines = Lines(p)
    assert lines.wait_for('discovered in', 120), ''.join(lines.lines)
    cli = [processes.start([swarm_cmd, 'kill', 'agent_4'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True),
           processes.start([swarm_cmd, 'pause', 'agent_1', '5'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)]
    os.kill(agent_pid(out, 'agent_0'), signal.SIGKILL)    # from outside: the world must notice
    for c in cli:
        msg, _ = c.communicate(timeout=60)
        assert c.returncode == 0, msg
    lines.wait(p, 240)
    text = ''.join(lines.lines)
    assert p.returncode == 0, text
    assert 'agent_0 exited with code' in text and 'agent_4 killed (fault injection)' in text, text
    scn = load(str(path))
    events = [json.loads(ln) for ln in (out / 'events.jsonl').read_text().splitlines()]
    by = {(e['kind'], e.get('agent')): e for e in events}
    kill, lost = by[('kill', 'agent_4')], by[('lost', 'agent_0')]
    freeze, resume = by[('freeze', 'agent_1')], by[('resume', 'agent_1')]
    assert kill['source'] == 'live' and freeze['source'] == 'live'
    assert resume['t'] == pytest.approx(freeze['t'] + 5.0)
    live = Trajectory.load(out / 'trajectory.npz')
    k_kill, k_lost = kill['step'], lost['step']
    assert np.isnan(live.r[k_kill:, 4]).all() and np.isfinite(live.r[:k_kill, 4]).all()
    assert np.isnan(live.r[k_lost:, 0]).all() and np.isfinite(live.r[:k_lost, 0]).all()
    assert np.isfinite(live.r[:, [1, 2, 3, 5]]).all()          # the run went on to the end
    # the bag: what each agent published, and the events
    t, r, th, bag_events, _ = bag_view(bag, scn.names, scn.dt, scn.steps)
    assert {(e['kind'], e.get('agent')) for e in bag_events} >= set(by)
    assert np.isnan(r[k_kill + 1:, 4]).all()
    assert np.isnan(r[k_lost + 1:, 0]).all()
    k0, k1 = freeze['step'], resume['step']
    assert np.isnan(r[k0 + 1:k1 + 1, 1]).all() and np.isfinite(r[k1 + 1:, 1]).all()
    assert np.isfinite(r[-1, [1, 2, 3, 5]]).all()
    # the frozen agent held still: it went on from where it stopped
    assert np.array_equal(live.r[k1, 1], live.r[k0, 1])
