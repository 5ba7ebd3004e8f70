#!/usr/bin/env python3
"""How often does ``ros2 topic pub --once`` reach the commander? (a measurement, not a test)

Starts ``swarm run SCENARIO --mode MODE [--record BAG]``, then runs the Jazzy emulation
``tests/fakes/emulate_topic_pub.py`` (a fresh process, so a fresh DDS participant, each try) TRIES
times on ``/swarm/lambda`` and on ``/agent_0/steering``, each with a new value, and counts the
tries that the commander took (its log line naming the value, within --wait s).

    .venv/bin/python scripts/bench_topic_pub.py --tries 20 --mode realtime --record
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
EMULATION = ROOT / 'tests' / 'fakes' / 'emulate_topic_pub.py'


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--scenario', default='homotopy_global')
    p.add_argument('--mode', choices=('realtime', 'lockstep'), default='realtime')
    p.add_argument('--record', action='store_true', help='run with --record')
    p.add_argument('--tries', type=int, default=20)
    p.add_argument('--wait', type=float, default=10.0, help='wall s to wait for the commander per try')
    a = p.parse_args()
    # a ROS_DOMAIN_ID no other run or test uses meanwhile (the project's pytest plugin's lock files)
    from swarm_tools.pytest_plugin import claim_domain
    domain, lock = claim_domain()
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               RMW_IMPLEMENTATION='rmw_fastrtps_cpp', PYTHONUNBUFFERED='1')
    tmp = Path(tempfile.mkdtemp(prefix='bench_topic_pub_'))
    log = tmp / 'run.log'
    cmd = [str(BIN / 'swarm'), 'run', a.scenario, '--mode', a.mode, '--duration', '100000',
           '--out', str(tmp / 'out'), '--no-figure']
    if a.record:
        cmd += ['--record', str(tmp / 'bag.mcap')]
    with open(log, 'w') as f:
        run = subprocess.Popen(cmd, env=env, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
    results = {}
    try:
        end = time.monotonic() + 120
        while 'discovered' not in log.read_text() and 'step 0' not in log.read_text() and time.monotonic() < end:
            time.sleep(0.5)
        time.sleep(5.0)
        for label, topic, fmt in (('lambda', '/swarm/lambda', 'set-point {:g}'),
                                  ('steering', '/agent_0/steering', 'steering of agent_0 set to {:g}')):
            ok = 0
            for k in range(a.tries):
                v = 0.31 + 0.02 * k if label == 'lambda' else 0.0011 * (k + 1)
                t0 = time.monotonic()
                subprocess.run([sys.executable, str(EMULATION), '--once', topic, 'std_msgs/msg/Float64',
                                f'{{data: {v}}}'], env=env, stdout=subprocess.DEVNULL, timeout=120)
                took = time.monotonic() - t0
                want = fmt.format(v)
                end = time.monotonic() + a.wait
                hit = False
                while time.monotonic() < end:
                    if want in log.read_text():
                        hit = True
                        break
                    time.sleep(0.1)
                ok += hit
                print(f'{label} try {k + 1}: {"taken" if hit else "LOST"} (tool ran {took:.2f} s)', flush=True)
            results[label] = ok
    finally:
        os.killpg(run.pid, signal.SIGINT)
        try:
            run.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    print(f'{a.mode}{" --record" if a.record else ""}: ' +
          ', '.join(f'{k} {v}/{a.tries}' for k, v in results.items()))
    return 0


if __name__ == '__main__':
    sys.exit(main())
