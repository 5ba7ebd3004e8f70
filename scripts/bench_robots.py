#!/usr/bin/env python3
"""Benchmark of the pure MuJoCo robot world (swarm_robots.physics, no ROS): real-time factor
and CPU per control step for N robots.

    .venv/bin/python scripts/bench_robots.py [--robots 6,24,96] [--seconds 20] [--out FILE.json]
    .venv/bin/python scripts/bench_robots.py --robots 6,24 --compare REV [--rounds 3]

``--compare REV``: the same measurement of this checkout and of git revision REV's
``swarm_robots`` (extracted with ``git archive``), each round in a fresh process, the two
interleaved; medians of CPU ms per step and their ratio.  The "in MuJoCo" column is the CPU
spent inside ``mj_step`` (the rest is the controllers, odometry and contacts in Python).

One control step is one lockstep step of the swarm: dt model units = dt·L/v0 robot seconds
(0.2 s at dt = 0.1, L = 0.3 m, v0 = 0.15 m/s).  Every step each robot gets a cmd_vel
(v0, clip(v0·u/L, ±ω_max)) with a random curvature u in [-1, 1] (seeded), as an agent would
send; the robots start on a grid at the scaled radio spacing (1.5·L), so some of them meet.
The real-time factor is robot seconds per wall second; CPU is this process's CPU time (robot s
per CPU s is the real-time factor one free core would give).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from swarm_robots.description import TURTLEBOT3_BURGER
from swarm_robots.physics import RobotWorld


def grid(n, spacing):
    """n start poses on a square grid, headings all along +x."""
    side = math.ceil(math.sqrt(n))
    return [[spacing * (k % side), spacing * (k // side), 0.0] for k in range(n)]


def measure(n, seconds, length_scale, cruise_speed, dt, seed=0):
    """One size: {robots, step_s, steps, rtf, wall/cpu ms per step, contacts}."""
    step = dt * length_scale / cruise_speed
    world = RobotWorld(TURTLEBOT3_BURGER, grid(n, 1.5 * length_scale))
    rng = np.random.default_rng(seed)
    max_angular = TURTLEBOT3_BURGER.max_angular
    robots = np.arange(n)

    def one_step():
        omega = np.clip(cruise_speed * rng.uniform(-1, 1, n) / length_scale, -max_angular, max_angular)
        world.command(robots, cruise_speed, omega)
        world.advance(step)

    one_step()                                            # warm-up
    steps = max(1, round(seconds / step))
    physics = sys.modules[RobotWorld.__module__]
    mj_step, in_mujoco = physics.mujoco.mj_step, [0.0]

    def timed(*a, **k):                                   # the CPU inside MuJoCo's step
        c = time.process_time()
        mj_step(*a, **k)
        in_mujoco[0] += time.process_time() - c
    physics.mujoco.mj_step = timed
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        for _ in range(steps):
            one_step()
    finally:
        physics.mujoco.mj_step = mj_step
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return dict(robots=n, step_s=step, steps=steps, rtf=steps * step / wall, rtf_cpu=steps * step / cpu,
                wall_ms_per_step=1e3 * wall / steps, cpu_ms_per_step=1e3 * cpu / steps,
                mujoco_ms_per_step=1e3 * in_mujoco[0] / steps, contacts=world.contacts)


def compare(args) -> None:
    """``--compare REV``: this checkout and REV's swarm_robots, interleaved (module docstring)."""
    root = Path(__file__).resolve().parents[1]
    cmd = [sys.executable, __file__, '--robots', args.robots, '--seconds', str(args.seconds), '--json',
           '--length-scale', str(args.length_scale), '--cruise-speed', str(args.cruise_speed), '--dt', str(args.dt)]
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(['git', '-C', str(root), 'archive', args.compare, 'src/swarm_robots'],
                                 check=True, capture_output=True).stdout
        subprocess.run(['tar', '-x', '-C', tmp], input=archive, check=True)
        env_rev = dict(os.environ, PYTHONPATH=os.path.join(tmp, 'src', 'swarm_robots'))
        runs = {'this': [], args.compare: []}
        for _ in range(args.rounds):
            for label, env in (('this', None), (args.compare, env_rev)):
                out = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
                runs[label].append(json.loads(out))
    print(f'| robots | CPU ms/step {args.compare} | CPU ms/step this | in MuJoCo (this) | speed-up |')
    print('|---:|---:|---:|---:|---:|')
    for i, n in enumerate(r['robots'] for r in runs['this'][0]):
        old = float(np.median([rr[i]['cpu_ms_per_step'] for rr in runs[args.compare]]))
        new = float(np.median([rr[i]['cpu_ms_per_step'] for rr in runs['this']]))
        mj = float(np.median([rr[i]['mujoco_ms_per_step'] for rr in runs['this']]))
        print(f'| {n} | {old:.2f} | {new:.2f} | {mj:.2f} | {old / new:.2f}× |')


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--robots', default='6,24,96', help='comma list of robot counts')
    ap.add_argument('--seconds', type=float, default=20.0, help='robot seconds per size')
    ap.add_argument('--length-scale', type=float, default=0.3, help='L, m per model unit')
    ap.add_argument('--cruise-speed', type=float, default=0.15, help='v0, m/s')
    ap.add_argument('--dt', type=float, default=0.1, help='the swarm step, model units')
    ap.add_argument('--out', help='also write the results as JSON here')
    ap.add_argument('--compare', metavar='REV', help='also measure git revision REV, interleaved')
    ap.add_argument('--rounds', type=int, default=3, help='--compare: rounds of each')
    ap.add_argument('--json', action='store_true', help='print the results as JSON only')
    args = ap.parse_args(argv)
    if args.compare:
        return compare(args)
    rows = [measure(int(n), args.seconds, args.length_scale, args.cruise_speed, args.dt)
            for n in args.robots.split(',') if n.strip()]
    if args.json:
        print(json.dumps(rows))
        return
    print('| robots | step (robot s) | steps | real-time factor | robot s per CPU s | wall ms/step '
          '| CPU ms/step | in MuJoCo | contacts |')
    print('|---:|---:|---:|---:|---:|---:|---:|---:|---:|')
    for r in rows:
        print(f'| {r["robots"]} | {r["step_s"]:.3g} | {r["steps"]} | {r["rtf"]:.1f}× | {r["rtf_cpu"]:.1f}× | '
              f'{r["wall_ms_per_step"]:.1f} | {r["cpu_ms_per_step"]:.1f} | {r["mujoco_ms_per_step"]:.1f} | '
              f'{r["contacts"]} |')
    if args.out:
        with open(args.out, 'w') as f:
            json.dump(dict(args=vars(args), results=rows), f, indent=1)


if __name__ == '__main__':
    main()
