#!/usr/bin/env python3
"""Benchmark of realtime runs: are the agents' states on time?

Three parts, each through the product's own launcher (``swarm run --mode realtime
--agents-per-process auto``) on a scenario generated from `homotopy_global` with n agents on
a grid (`bench_ros.scenario_file`):

- ``--record-case N,RTF`` (default 96,5): N agents at --rtf RTF with ``--record``: the share of
  states on time (the world's ``timing`` in metrics.json), the states the bag lost
  (owed n·(steps+1) less those recorded) and what the bag says of the timing (`bag_timing`:
  the clock's phase, the periods skipped, the worst wall second);
- ``--big-case N,RTF`` (default 1000,1): N agents: on-time share, speed (each agent's path
  length over the run's time, min / median / max; the law flies at unit speed) and start time
  (launching ``swarm run`` to the world's discovery line);
- ``--sweep N,N,...`` at --rtf 1: on-time share and CPU per control period (all processes of
  the run, from /proc) against n; the largest n with ≥ 99 % on time; ``--plot`` draws both
  against n on log-log axes.

The machine's load changes every number here but the CPU per period; the script prints the
load average next to each run.  ``--compare REV --rounds R`` runs git revision REV (its src/
first on PYTHONPATH, with this venv and this script, so the same measures) and this checkout in
turn, R pairs, for numbers side by side on a loaded machine.  ``--keep DIR`` keeps every run's
output.  Processes, the domain id and Ctrl-C are handled as in `bench_ros` (it reuses its
`Run`).
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

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_ros as B

#: the on-time share a run must reach (swarm_world.lateness.ON_TIME_TARGET)
TARGET = 0.99


def case(exe, env, tmp, n, rtf, duration, *, record=False, timeout=900.0) -> dict:
    """One realtime run of n agents for ``duration`` sim s at ``rtf``; its numbers."""
    dt = scenario_dt()
    steps = int(round(duration / dt))
    scn = B.scenario_file(n, steps, tmp)
    out = tmp / f'run-{n}-{rtf:g}-{int(record)}'
    args = [exe, 'run', str(scn), '--mode', 'realtime', '--rtf', f'{rtf:g}', '--agents-per-process', 'auto',
            '--no-figure', '--out', str(out), '--progress-every', str(duration / 2)]
    bag = tmp / f'run-{n}-{rtf:g}.mcap'
    if record:
        args += ['--record', str(bag)]
    load0 = B.loadavg()
    print(f'  n={n} rtf={rtf:g}{" --record" if record else ""}, {duration:g} sim s; load {load0}', flush=True)
    r = B.Run(args, env, timeout).go()
    r.update(agents=n, rtf=rtf, duration=duration, record=record, load_before=load0, load_after=B.loadavg())
    try:
        r['timing'] = json.loads((out / 'metrics.json').read_text()).get('timing')
    except (OSError, ValueError):
        r['timing'] = None
    r['speed'] = speeds(out / 'trajectory.npz')
    if r.get('cores_busy') and r.get('run_wall_s'):
        periods_per_s = rtf / dt
        r['cpu_ms_per_period'] = round(1000 * r['cores_busy'] / periods_per_s, 3)
    if record and bag.exists():
        # lost by the bag: states the world received (and the n first ones, sent before the clock
        # started) that the bag does not hold; the states a late agent never sent are in `timing`
        got = B.bag_states(bag)
        sent = n + ((r['timing'] or {}).get('arrived') or 0)
        r.update(bag_states=got, bag_states_owed=n * (steps + 1), bag_lost=max(0, sent - got),
                 bag_timing=bag_timing(bag, dt, rtf))
    print(f'    -> {line(r)}', flush=True)
    return r


def bag_timing(bag, dt, rtf) -> dict:
    """The run's timing per control period as the bag tells it (the recorder's receive times
    standing in for the world's): ``clock_after_boundary``, the share of /clock messages in the
    first quarter of a period (the agents' timers fire on the first one past a boundary);
    ``skipped``, the periods the agents' states caught up over; ``worst_second``, the wall
    second (from the clock's start) with the smallest share of states on time at the recorder,
    and that share: bursts show there, spread lateness does not."""
    from swarm_ros.protocol import cdr_to_odometry_full
    from swarm_tools.bags.mcap_io import iter_messages
    from swarm_tools.bags.msgdefs import leading_stamp_ns
    clock, states = [], {}
    for m in iter_messages(bag, topics=['/clock', '/swarm/states']):
        if m.topic == '/clock':
            clock.append((m.log_time * 1e-9, leading_stamp_ns(m.data) * 1e-9))
        else:
            _, name, sec, nsec, *_ = cdr_to_odometry_full(m.data)
            states.setdefault(name, []).append((m.log_time * 1e-9, sec + nsec * 1e-9))
    if not clock or not states:
        return {}
    clock = np.array(clock)
    wall0 = np.min(clock[:, 0] - clock[:, 1] / rtf)            # the clock's start (its fastest message)
    got = np.concatenate([np.array(v) for v in states.values()])
    second = np.floor(got[:, 1] / rtf).astype(int)
    on_time = got[:, 0] - wall0 - got[:, 1] / rtf <= dt / rtf
    share = np.bincount(second, on_time) / np.maximum(np.bincount(second), 1)
    worst = int(np.argmin(np.where(np.bincount(second) > 0, share, np.inf)))
    steps = [np.unique(np.rint(np.array(v)[:, 1] / dt).astype(int)) for v in states.values()]
    return dict(clock_after_boundary=round(float(np.mean((clock[:, 1] / dt) % 1 < 0.25)), 3),
                skipped=int(sum(np.sum(np.diff(k) - 1) for k in steps)),
                worst_second=worst, worst_second_on_time=round(float(share[worst]), 4))


def scenario_dt() -> float:
    """dt of the scenario the runs are made from (`bench_ros.scenario_file`: homotopy_global)."""
    import yaml

    from swarm_core.scenario.loader import resolve
    return float(yaml.safe_load(resolve('homotopy_global')[0])['dt'])


def speeds(path) -> dict | None:
    """Each agent's path length over the time to its last move (the world holds an agent's
    last state to the end of the run): min / median / max.  The path between two recorded
    states is the arc the agent flew (`flown_periods`), not the chord: a state that caught up
    several periods turned on the way."""
    try:
        with np.load(path) as z:
            t, r, theta, u = z['t'], z['r'], z['theta'], z['u']
    except (OSError, ValueError, KeyError):
        return None
    dt = float(t[1] - t[0])
    v = []
    for i in range(r.shape[1]):
        new = np.flatnonzero((np.diff(r[:, i], axis=0) != 0).any(axis=1)) + 1     # rows of a new state
        if new.size < 2 or not np.isfinite(r[:, i]).all():
            continue
        rows = np.r_[0, new]
        p = flown_periods(r[rows, i], theta[rows, i], u[rows[1:] - 1, i], np.diff(rows), dt)
        v.append(p.sum() * dt / (t[new[-1]] - t[0]))
    if not v:
        return None
    return dict(min=round(float(np.min(v)), 4), median=round(float(np.median(v)), 4), max=round(float(np.max(v)), 4))


def flown_periods(r, theta, u, gaps, dt):
    """(m,) the control periods an agent flew between its m+1 recorded states (r (m+1, 2),
    θ (m+1,)), each reached with u (m,) held after ``gaps`` (m,) periods of clock: the p in
    1..gap whose ZOH arc (chord p·dt·sinc(u·p·dt/2), turn u·p·dt) best fits the recorded
    chord and turn.  At unit speed the path is p·dt; p < gap is sim time not flown."""
    top = int(min(gaps.max(), 200))
    p = np.arange(1, top + 1)[None, :]                                 # (1, P) candidates
    half = u[:, None] * p * dt / 2
    chord = np.abs(p * dt * np.sinc(half / np.pi))
    d = np.diff(r, axis=0)
    miss = np.abs(chord - np.hypot(d[:, 0], d[:, 1])[:, None])
    turn = np.angle(np.exp(1j * (theta[:-1, None] + 2 * half - theta[1:, None])))
    score = np.where(p <= gaps[:, None], miss + np.abs(turn), np.inf)
    return np.argmin(score, axis=1) + 1


def line(r) -> str:
    tm = r.get('timing') or {}
    share = tm.get('on_time_share')
    return (f"exit {r['exit_code']}, on time {'—' if share is None else f'{share:.2%}'}, "
            f"p99 {tm.get('lateness_p99_ms', '—')} ms, achieved rtf {tm.get('achieved_rtf', '—')}, "
            f"start {r.get('start_s', '—')} s, speed {r.get('speed')}, "
            f"CPU ms/period {r.get('cpu_ms_per_period', '—')}"
            + (f", bag {r['bag_states']}/{r['bag_states_owed']} states (lost {r['bag_lost']}), "
               f"bag timing {r.get('bag_timing')}" if 'bag_lost' in r else ''))


def on_time(r) -> float:
    return ((r.get('timing') or {}).get('on_time_share') or 0.0) if r['exit_code'] == 0 else 0.0


def plot(sweep, path):
    """On-time share and CPU per control period against n, log-log."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    pts = sorted((r['agents'], on_time(r), r.get('cpu_ms_per_period')) for r in sweep)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    ax1.loglog([p[0] for p in pts], [max(p[1], 1e-3) for p in pts], 'o-')
    ax1.axhline(TARGET, color='grey', ls='--', lw=0.8)
    ax1.set(xlabel='agents n', ylabel='share of states on time', title='realtime, rtf 1')
    c = [p for p in pts if p[2]]
    ax2.loglog([p[0] for p in c], [p[2] for p in c], 'o-')
    ax2.set(xlabel='agents n', ylabel='CPU ms per control period (all processes)', title='cost per period')
    for ax in (ax1, ax2):
        ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def pair(text):
    n, _, rtf = text.partition(',')
    return int(n), float(rtf or 1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--record-case', type=pair, default=(96, 5.0), metavar='N,RTF', help='default 96,5')
    ap.add_argument('--big-case', type=pair, default=(1000, 1.0), metavar='N,RTF', help='default 1000,1')
    ap.add_argument('--sweep', default='96,192,384,768,1000,1500', help="agent counts at rtf 1 ('' = none)")
    ap.add_argument('--duration', type=float, default=30.0, help='sim seconds per run (default 30)')
    ap.add_argument('--skip', default='', help='parts to leave out: record,big (comma-separated)')
    ap.add_argument('--swarm', default=B.DEFAULT_SWARM, help='the swarm executable (default: this venv\'s)')
    ap.add_argument('--timeout', type=float, default=900.0, help='give up on one run after this many s')
    ap.add_argument('--plot', metavar='PNG', help='log-log plot of the sweep')
    ap.add_argument('--out', default='bench/realtime.json', help='results JSON (default bench/realtime.json)')
    ap.add_argument('--keep', metavar='DIR', help="keep each run's output (trajectory, metrics, bag) in DIR")
    ap.add_argument('--compare', metavar='REV', help='also run git revision REV (its src/ on PYTHONPATH, this '
                    'venv and script), interleaved with this checkout: REV, current, REV, current, ...')
    ap.add_argument('--rounds', type=int, default=1, help='with --compare: pairs of runs (default 1)')
    a = ap.parse_args(argv)
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, B.on_signal)
    dom, lock = B.claim_domain()
    env = dict(os.environ, ROS_DOMAIN_ID=str(dom), PYTHONUNBUFFERED='1')
    res = dict(command=' '.join([Path(sys.argv[0]).name] + (sys.argv[1:] if argv is None else argv)),
               date=time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()), cpus=os.cpu_count(), load_start=B.loadavg())
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryDirectory(prefix='bench_rt_') as tmp:
            tmp = Path(a.keep or tmp)
            tmp.mkdir(parents=True, exist_ok=True)
            if a.compare:
                before = dict(env, PYTHONPATH=extract(a.compare, tmp / 'rev'))
                res['compare'] = a.compare
                for k in range(a.rounds):
                    for side, e in ((a.compare, before), ('current', env)):
                        print(f'bench_realtime: {side}, round {k + 1}', flush=True)
                        res.setdefault(side, []).append(
                            parts(a, e, tmp / f'{k}-{side}', lambda: out.write_text(json.dumps(res, indent=1))))
            else:
                res.update(parts(a, env, tmp, lambda: out.write_text(json.dumps(res, indent=1))))
    finally:
        res['load_end'] = B.loadavg()
        out.write_text(json.dumps(res, indent=1))
        lock.close()
    if not a.compare:
        print(f"bench_realtime: largest n at rtf 1 with ≥ {TARGET:.0%} on time: {res.get('largest_n_on_time')}")
    if a.plot and res.get('sweep'):
        plot(res['sweep'], a.plot)
        print(f'bench_realtime: wrote {a.plot}')
    print(f'bench_realtime: wrote {out}')
    return 0


def parts(a, env, tmp, save) -> dict:
    """The record case, the big case and the sweep (those not skipped) in directory ``tmp``."""
    tmp.mkdir(parents=True, exist_ok=True)
    skip, res = set(a.skip.split(',')), {}
    if 'record' not in skip:
        res['record'] = case(a.swarm, env, tmp, *a.record_case, a.duration, record=True, timeout=a.timeout)
    if 'big' not in skip:
        res['big'] = case(a.swarm, env, tmp, *a.big_case, a.duration, timeout=a.timeout)
    res['sweep'] = []
    for n in B.parse_ints(a.sweep):
        res['sweep'].append(case(a.swarm, env, tmp, n, 1.0, a.duration, timeout=a.timeout))
        save()
    ok = [r['agents'] for r in res['sweep'] if on_time(r) >= TARGET]
    res['largest_n_on_time'] = max(ok) if ok else None
    return res


def extract(rev, into) -> str:
    """src/ of git revision ``rev`` into ``into``: the PYTHONPATH that puts its packages before
    this venv's editable installs of this checkout."""
    import subprocess
    root = Path(__file__).resolve().parent.parent
    tar = subprocess.run(['git', '-C', str(root), 'archive', rev, 'src'], capture_output=True, check=True).stdout
    into.mkdir(parents=True, exist_ok=True)
    subprocess.run(['tar', '-x', '-C', str(into)], input=tar, check=True)
    return os.pathsep.join(str(d) for d in sorted((into / 'src').iterdir()) if d.is_dir())


if __name__ == '__main__':
    sys.exit(main())
