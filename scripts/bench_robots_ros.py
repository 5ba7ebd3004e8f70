#!/usr/bin/env python3
"""Benchmark: lockstep steps/s of `swarm run` with 6 agents on MuJoCo robots against the same 6
agents kinematic, side by side (and 3 + 3 mixed, and the six in one agent container),
interleaved case by case so that the cases share the machine's load.

Every case is a real ``swarm run`` (agents, world, commander and, with robots, the robot world
as OS processes) of `homotopy_global`'s law and λ window on six agents in a grid, with a
``robots:`` section (L = 0.3 m, v0 = 0.15 m/s: one lockstep step of dt = 0.05 is 0.1 robot s).
Numbers come from the world's own ``finished ... (R steps/s)`` line and the CPU time per step
of every process (`bench_ros.Run`); the issue's target is robots at ≥ 50 % of the kinematic
run's steps/s.  ``--swarm LABEL=PATH`` (repeatable) measures several swarm executables (e.g.
before and after a change) interleaved case by case, as bench_ros does.  Uses its own
ROS_DOMAIN_ID and ends every process it started (bench_ros).
"""
from __future__ import annotations

import argparse
import json
import signal
import sys
import tempfile
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_ros

#: the scale of the robots (scenario section robots:)
ROBOTS = {'length_scale': 0.3, 'cruise_speed': 0.15}
CASES = {'kinematic': [], 'robots': ['--robots', 'mujoco'], 'mixed': ['--robots', 'mujoco:agent_0-agent_2'],
         'kinematic_container': ['--agents-per-process', '6'],
         'robots_container': ['--robots', 'mujoco', '--agents-per-process', '6']}


def role(pid: int) -> str:
    """bench_ros's roles, and the robot world."""
    try:
        if b'swarm_robots' in Path(f'/proc/{pid}/cmdline').read_bytes():
            return 'robots'
    except OSError:
        return '?'
    return _role(pid)


_role, bench_ros.role = bench_ros.role, role


def scenario_file(steps: int, tmp: Path) -> Path:
    """homotopy_global's law and λ window, six agents on a grid, a robots: section."""
    path = bench_ros.scenario_file(6, steps, tmp)
    doc = yaml.safe_load(path.read_text())
    doc.update(name='bench_robots', robots=ROBOTS)
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--steps', type=int, default=2000, help='lockstep steps per run (default 2000)')
    ap.add_argument('--repeat', type=int, default=2, help='runs per case, interleaved (default 2)')
    ap.add_argument('--cases', default='kinematic,robots,mixed', help=f'of {", ".join(CASES)}')
    ap.add_argument('--swarm', action='append', metavar='LABEL=PATH', help=(
        'a swarm executable to measure, with a label; repeat to measure several interleaved, case by '
        'case (e.g. after=.venv/bin/swarm before=/tmp/old/swarm); default: this=' + bench_ros.DEFAULT_SWARM))
    ap.add_argument('--timeout', type=float, default=900, help='give up on one run after this many s')
    ap.add_argument('--out', default='bench/robots_ros.json', help='results JSON (default bench/robots_ros.json)')
    a = ap.parse_args(argv)
    cases = [c.strip() for c in a.cases.split(',') if c.strip()]
    if not cases or any(c not in CASES for c in cases):
        ap.error(f'--cases: comma-separated, of {", ".join(CASES)}')
    exes = [item.partition('=')[::2] for item in a.swarm or [f'this={bench_ros.DEFAULT_SWARM}']]
    if any(not label or not exe for label, exe in exes):
        ap.error('--swarm: want LABEL=PATH')
    if len(exes) > 1:
        cases = [f'{c}@{label}' for c in cases for label, _ in exes]
    exe_of = {c: exes[0][1] if '@' not in c else dict(exes)[c.split('@')[1]] for c in cases}
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, bench_ros.on_signal)
    dom, lock = bench_ros.claim_domain(61)
    env = dict(bench_ros.os.environ, ROS_DOMAIN_ID=str(dom), PYTHONUNBUFFERED='1')
    results = {c: [] for c in cases}
    with tempfile.TemporaryDirectory(prefix='bench_robots_') as tmp:
        path = scenario_file(a.steps, Path(tmp))
        for k in range(a.repeat):
            for case in cases:
                print(f'[{case} #{k + 1}] load {bench_ros.loadavg()}', flush=True)
                args = [exe_of[case], 'run', str(path), '--out', str(Path(tmp) / case), '--no-figure',
                        '--progress-every', '1e9', *CASES[case.split('@')[0]]]
                r = bench_ros.Run(args, env, a.timeout).go()
                r['load'] = bench_ros.loadavg()
                results[case].append(r)
                print(f'    {case}: {r.get("steps_per_s")} steps/s, cpu/step {r.get("cpu_ms_per_step")}', flush=True)
    lock.close()
    best = {c: max((r.get('steps_per_s') or 0 for r in rs), default=0) for c, rs in results.items()}
    summary = dict(steps=a.steps, best_steps_per_s=best)
    for c, v in best.items():             # each executable's cases against its own kinematic run
        kin = best.get('kinematic' + c[len(c.split('@')[0]):])
        if kin:
            summary.setdefault('ratio_to_kinematic', {})[c] = round(v / kin, 3)
    print(json.dumps(summary, indent=1))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(dict(summary=summary, runs=results), indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
