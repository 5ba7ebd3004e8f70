#!/usr/bin/env python3
"""Benchmark: simple discovery against a Fast DDS discovery server, one agent per process.

For each case ``N:KIND`` (KIND simple or server) it runs ``swarm run`` on homotopy_global with
N agents on a grid (scenario as in bench_ros.py) and ``--discovery KIND``, and reads the
world's own lines: start (launch to "discovered"), discovery, lockstep steps/s, CPU per step and
total RSS (sampled from /proc, as bench_ros.py does).  Cases run interleaved, ``--repeat``
times, so that both kinds share the machine's load.  Default: 48 agents both ways (a size where
both work) and 150 agents through the server.

Uses bench_ros.py's domain claim and run handling: its own ROS_DOMAIN_ID, every launcher in a
session of its own, everything left in that session SIGKILLed (by pid) at the end of a run.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_ros import DEFAULT_SWARM, Run, claim_domain, loadavg, on_signal, scenario_file


def parse_cases(text):
    out = []
    for item in text.split(','):
        n, _, kind = item.strip().partition(':')
        if not n.isdigit() or kind not in ('simple', 'server'):
            raise ValueError(f'case {item!r}: want N:simple or N:server')
        out.append((int(n), kind))
    return out


def line(r) -> str:
    cpu = r.get('cpu_ms_per_step', {}).get('total')
    return (f"{r['agents']:>4} {r['discovery']:<6} exit {r['exit_code']}  start {r.get('start_s', '-')} s  "
            f"discovery {r.get('discovery_s', '-')} s  {r.get('steps_per_s', '-')} steps/s  "
            f"cpu {cpu if cpu is not None else '-'} ms/step  rss {r.get('rss_total_mib', '-')} MiB  "
            f"stalls {r.get('stalls', 0)}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--cases', default='48:simple,48:server,150:server',
                    help='comma-separated N:simple / N:server (default 48:simple,48:server,150:server)')
    ap.add_argument('--steps', type=int, default=300, help='lockstep steps per run (default 300)')
    ap.add_argument('--repeat', type=int, default=1, help='rounds over the cases (default 1)')
    ap.add_argument('--timeout', type=float, default=900, help='give up on one run after this many s')
    ap.add_argument('--swarm', default=DEFAULT_SWARM, help='the swarm executable')
    ap.add_argument('--out', default='bench/discovery.json', help='results JSON (default bench/discovery.json)')
    a = ap.parse_args(argv)
    try:
        cases = parse_cases(a.cases)
    except ValueError as err:
        ap.error(str(err))
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, on_signal)
    dom, lock = claim_domain(61)
    env = dict(os.environ, ROS_DOMAIN_ID=str(dom), PYTHONUNBUFFERED='1')
    for k in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS', 'FASTRTPS_DEFAULT_PROFILES_FILE',
              'FASTDDS_DEFAULT_PROFILES_FILE', 'ROS_DISCOVERY_SERVER', 'ROS_SUPER_CLIENT'):
        env.pop(k, None)
    results = dict(command=' '.join(['scripts/bench_discovery.py'] + (sys.argv[1:] if argv is None else argv)),
                   date=time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()), domain=dom, cpus=os.cpu_count(),
                   load_start=loadavg(), runs=[])
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryDirectory(prefix='bench_discovery_') as tmp:
            tmp = Path(tmp)
            for rep in range(a.repeat):
                for n, kind in cases:
                    scn = scenario_file(n, a.steps, tmp)
                    load0 = loadavg()
                    print(f'  n={n} {kind} (round {rep + 1}/{a.repeat}); load {load0}', flush=True)
                    r = Run([a.swarm, 'run', str(scn), '--discovery', kind, '--no-figure',
                             '--out', str(tmp / f'{kind}-{n}-{rep}'), '--progress-every', str(a.steps * 0.05 / 2),
                             '--start-timeout', str(a.timeout)],
                            env, a.timeout).go()
                    r.update(agents=n, discovery=kind, repeat=rep, load_before=load0, load_after=loadavg())
                    results['runs'].append(r)
                    print('    -> ' + line(r), flush=True)
                    out.write_text(json.dumps(results, indent=1))
    finally:
        results['load_end'] = loadavg()
        out.write_text(json.dumps(results, indent=1))
        lock.close()
    print('\n'.join(line(r) for r in results['runs']))
    print(f'bench_discovery: wrote {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
