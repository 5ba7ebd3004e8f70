#!/usr/bin/env python3
"""What `ros2 bag record` loses of /swarm/states in a lockstep run, with its stock QoS (adapted
to the offers, depth 10) and with the shipped override file
(src/swarm_tools/config/record_qos_overrides.yaml: depth 1000).

The recorder is the rosbag2 emulation tests/fakes/rosbag2_record.py (a Python callback: slower per
message than rosbag2's C++, so its depth-10 losses are an upper bound).  Each repetition runs
both variants one after the other on the same machine (`swarm run SCENARIO --mode lockstep`,
one process per node, started after the recorder said it was ready).  "lost" counts, per
agent, the steps 0..last that the recorder never received.

    .venv/bin/python scripts/bench_bag_qos.py [--repeat 3] [--duration 30]
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'scripts'))
from bench_ros import claim_domain, loadavg

OVERRIDES = ROOT / 'src' / 'swarm_tools' / 'config' / 'record_qos_overrides.yaml'
EMULATION = ROOT / 'tests' / 'fakes' / 'rosbag2_record.py'
BIN = Path(sys.executable).parent


def lost_states(report: dict, steps: int, dt: float) -> tuple[dict, dict]:
    """({agent: steps of 0..steps the recorder never received}, {agent: of those, the ones
    after its first received step}): the first are all losses, the second the losses of a
    subscription already matched (a full queue) rather than of a late match."""
    lost, gaps = {}, {}
    for name, st in report['states'].items():
        got = {int(round(int(s) / (dt * 1e9))) for s in st}
        lost[name] = len(set(range(steps + 1)) - got)
        gaps[name] = len(set(range(min(got), steps + 1)) - got) if got else steps + 1
    return lost, gaps


def run_once(scenario: str, duration: float, overrides: bool, env: dict, tmp: Path) -> dict:
    cmd = [sys.executable, str(EMULATION)]
    if overrides:
        cmd += ['--qos-profile-overrides-path', str(OVERRIDES)]
    rec = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                           start_new_session=True)
    try:
        assert 'ready' in rec.stderr.readline()
        t0 = time.monotonic()
        run = subprocess.run([str(BIN / 'swarm'), 'run', scenario, '--mode', 'lockstep',
                              '--duration', str(duration), '--no-figure', '--out', str(tmp / 'run')],
                             capture_output=True, text=True, env=env, timeout=900)
        wall = time.monotonic() - t0
        if run.returncode != 0:
            raise SystemExit(f'swarm run failed:\n{run.stdout[-2000:]}{run.stderr[-2000:]}')
        time.sleep(1.0)
        os.killpg(rec.pid, signal.SIGINT)
        out, _err = rec.communicate(timeout=60)
    finally:
        if rec.poll() is None:
            os.killpg(rec.pid, signal.SIGKILL)
            rec.wait()
    report = json.loads(out.strip().splitlines()[-1])
    report['wall'] = wall
    return report


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--scenario', default='global_alignment')
    p.add_argument('--duration', type=float, default=30.0, help='sim seconds (default 30)')
    p.add_argument('--repeat', type=int, default=3)
    a = p.parse_args(argv)
    from swarm_core.scenario.loader import load
    scn = load(a.scenario)
    steps = int(round(a.duration / scn.dt))
    dom, lock = claim_domain(61)
    env = dict(os.environ, ROS_DOMAIN_ID=str(dom), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    print(f'bench_bag_qos: {a.scenario}, {len(scn.names)} agents, {steps} steps, domain {dom}, '
          f'load {loadavg()}', flush=True)
    rows = []
    for k in range(a.repeat):
        for overrides in (False, True):
            with tempfile.TemporaryDirectory() as tmp:
                r = run_once(a.scenario, a.duration, overrides, env, Path(tmp))
            lost, gaps = lost_states(r, steps, scn.dt)
            rate = steps * len(scn.names) / r['wall']
            q = r['requested'].get('/swarm/states', {})
            rows.append((overrides, sum(lost.values()), sum(gaps.values()), rate, q))
            print(f'  run {k + 1}: {"override" if overrides else "stock   "} /swarm/states {q}: '
                  f'lost {sum(lost.values())} of {(steps + 1) * len(scn.names)} '
                  f'(per agent {sorted(lost.values())}; after the first received: {sum(gaps.values())}), '
                  f'~{rate:.0f} states/s incl. start-up',
                  flush=True)
    lock.close()
    print('\n| recorder QoS on /swarm/states | runs | states lost per run (all agents) '
          '| of those, after the first received |')
    print('|---|---|---|---|')
    for overrides in (False, True):
        rs = [r for r in rows if r[0] == overrides]
        label = ('override file: reliable, transient-local, depth 1000' if overrides
                 else 'stock: adapted to offers (reliable, transient-local), depth 10')
        print(f'| {label} | {len(rs)} | {", ".join(str(r[1]) for r in rs)} | {", ".join(str(r[2]) for r in rs)} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
