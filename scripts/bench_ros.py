#!/usr/bin/env python3
"""Benchmark of the ROS 2 swarm (issue 3): lockstep steps/s with every agent its own OS process
for n = 6, 12, 24, 48, 96 (and in one process for comparison), start-up / discovery time,
per-process memory (RSS), and the wall time of the whole `homotopy_global` run to t = 1000
with 6 agent processes and a bag (``--record``).

``--per-process 1,auto`` measures every agent count with those ``--agents-per-process`` values
(agent containers); ``--no-agent-clock`` adds, for 6 agent processes, a run whose world sends
/clock only every 10^6 steps (what the agents' /clock readers cost in lockstep); ``--plot``
draws CPU per step and steps/s against n on log-log axes.

Every run goes through the product's own launcher (``swarm run``): for n agents a scenario
file is generated in a temporary directory from `homotopy_global` (same law, gains, λ window
and leader rule) with ``agents: {count: n}`` on a grid.  Numbers are read from the world's
own lines (``discovered in X s``, ``finished ... in W s (R steps/s)``); "start" is the wall
time from launching ``swarm run`` to the world's discovery line (process start + discovery).

``--swarm LABEL=PATH`` (repeatable) runs the same cases with several ``swarm`` executables
(e.g. a wrapper running an older checkout) interleaved case by case, so that before/after
numbers share the machine's load.  Because the machine is shared, the load-independent number
is the CPU time per step (all processes of a run, from /proc), next to steps/s.

The script uses its own ROS_DOMAIN_ID (claimed with the test suite's flock convention in
/tmp/homotopy-swarm-domains, so it never shares one with a running test), starts every
launcher in a session of its own and, at the end of each run or on Ctrl-C / SIGTERM, stops
it with SIGINT and then SIGKILLs any process still left in that session (by pid).
"""
from __future__ import annotations

import argparse
import fcntl
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SWARM = str(Path(sys.executable).parent / 'swarm')
LOCK_DIR = Path(os.environ.get('SWARM_DOMAIN_LOCK_DIR', '/tmp/homotopy-swarm-domains'))
#: lockstep steps per measured run, by agent count (about 5-20 s each on the 2-core machine)
TICKS = os.sysconf('SC_CLK_TCK')
DEFAULT_STEPS = {6: 4000, 12: 2400, 24: 1200, 48: 600, 96: 400, 240: 300, 500: 200, 1000: 150}


# ------------------------------------------------------------------ helpers

def claim_domain(first: int = 77):
    """(ROS_DOMAIN_ID, lock file): an id in 1..100 no test or other bench holds."""
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    for k in range(100):
        dom = 1 + (first - 1 + k) % 100
        f = open(LOCK_DIR / f'{dom}.lock', 'a')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return dom, f
        except OSError:
            f.close()
    raise SystemExit('bench_ros: no free ROS_DOMAIN_ID in 1..100')


def loadavg() -> str:
    return ' '.join(Path('/proc/loadavg').read_text().split()[:3])


def scenario_file(n: int, steps: int, tmp: Path, dim: int = 2) -> Path:
    """homotopy_global (dim 3: homotopy_3d) with n agents on a grid, run for `steps` steps."""
    from swarm_core.scenario.loader import resolve
    text, _ = resolve('homotopy_global' if dim == 2 else 'homotopy_3d')
    doc = yaml.safe_load(text)
    doc['name'] = f'bench_n{n}' + ('' if dim == 2 else '_3d')
    doc['agents'] = {'count': n, 'positions': {'rule': 'grid', 'spacing': 1.0},
                     'headings': doc['agents']['headings']}
    doc['duration'] = steps * doc['dt']
    doc.pop('expect', None)
    path = tmp / f'{doc["name"]}.yaml'
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def session_pids(sid: int) -> list[int]:
    out = []
    for d in os.listdir('/proc'):
        if not d.isdigit():
            continue
        try:
            with open(f'/proc/{d}/stat') as f:
                fields = f.read().rsplit(')', 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != 'Z':       # field 6 of stat = session id
            out.append(int(d))
    return out


def rss_kib(pid: int):
    try:
        with open(f'/proc/{pid}/status') as f:
            for line in f:
                if line.startswith('VmRSS:'):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def cpu_seconds(pid: int):
    """utime + stime of a process (s), or None."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / TICKS


def role(pid: int) -> str:
    try:
        cmd = Path(f'/proc/{pid}/cmdline').read_bytes().split(b'\0')
    except OSError:
        return '?'
    text = b' '.join(cmd).decode(errors='replace')
    for key, name in (('swarm_agent_container', 'container'), ('swarm_agent', 'agent'), ('swarm_world', 'world'),
                      ('homotopy_commander', 'commander'), (' record', 'recorder'), (' run', 'launcher')):
        if key in text:
            return name
    return 'other'


class Run:
    """One ``swarm run`` in a session of its own; reads its lines, samples RSS, always ends it."""

    current: 'Run | None' = None

    def __init__(self, args, env, timeout):
        self.args, self.env, self.timeout = args, env, timeout
        self.lines = []
        self.t_discovered = None
        self.t_finished = None
        self.rss = {}            # pid -> (role, max RSS KiB)
        self.cpu = {}            # pid -> (role, (t, cpu s) first sample, (t, cpu s) last sample)
        self.proc = None

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line)
            if 'discovered in' in line and self.t_discovered is None:      # lockstep and realtime
                self.t_discovered = time.monotonic()
            if '[world] finished' in line and self.t_finished is None:
                self.t_finished = time.monotonic()
            if '[world]' in line or 'swarm run:' in line:
                print('      ' + line.rstrip(), flush=True)

    def _sample(self):
        while self.proc.poll() is None:
            if self.t_discovered is not None and self.t_finished is None:
                for pid in session_pids(self.proc.pid):
                    kib, cpu, now = rss_kib(pid), cpu_seconds(pid), time.monotonic()
                    if kib is None or cpu is None:
                        continue
                    r, old = self.rss.get(pid, (role(pid), 0))
                    self.rss[pid] = (r, max(old, kib))
                    first = self.cpu[pid][1] if pid in self.cpu else (now, cpu)
                    self.cpu[pid] = (r, first, (now, cpu))
            time.sleep(0.1)

    def go(self) -> dict:
        Run.current = self
        t0 = time.monotonic()
        self.proc = subprocess.Popen(self.args, env=self.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, start_new_session=True)
        reader = threading.Thread(target=self._read, daemon=True)
        sampler = threading.Thread(target=self._sample, daemon=True)
        reader.start()
        sampler.start()
        try:
            code = self.proc.wait(timeout=self.timeout)
        except subprocess.TimeoutExpired:
            print(f'      timed out after {self.timeout:.0f} s; stopping', flush=True)
            code = None
        wall = time.monotonic() - t0
        self.end()
        reader.join(timeout=5)
        Run.current = None
        return self.result(code, wall, t0)

    def end(self):
        """SIGINT to the launcher (it stops its children), then SIGKILL whatever is left of the session."""
        p = self.proc
        if p is None:
            return
        if p.poll() is None:
            try:
                p.send_signal(signal.SIGINT)
                p.wait(timeout=12)
            except (subprocess.TimeoutExpired, ProcessLookupError):
                pass
        for pid in session_pids(p.pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if p.poll() is None:
            p.wait(timeout=5)

    def result(self, code, wall, t0) -> dict:
        import re
        out = dict(exit_code=code, launcher_wall_s=round(wall, 2))
        for ln in self.lines:
            m = re.search(r'discovered in ([0-9.]+) s', ln)
            if m:
                out['discovery_s'] = float(m.group(1))
            m = re.search(r'finished t=\S+ \((\d+) steps\) in ([0-9.]+) s \((\d+) steps/s\)', ln)
            if m:
                steps, w = int(m.group(1)), float(m.group(2))
                out.update(steps=steps, run_wall_s=w, steps_per_s=round(steps / w, 1) if w > 0 else None)
        out['stalls'] = sum('stalled at step' in ln for ln in self.lines)
        if self.t_discovered is not None:
            out['start_s'] = round(self.t_discovered - t0, 2)
        by_role = {}
        for r, kib in self.rss.values():
            by_role.setdefault(r, []).append(kib / 1024)
        out['rss_mib'] = {r: dict(count=len(v), median=round(statistics.median(v), 1), max=round(max(v), 1))
                          for r, v in sorted(by_role.items())}
        out['rss_total_mib'] = round(sum(kib for _, kib in self.rss.values()) / 1024, 1)
        # CPU time per lockstep step, by role (all processes of a role summed): Δcpu over the
        # sampled part of the run divided by the steps made in it (at the run's mean rate)
        if out.get('steps_per_s'):
            cpu_by_role, spans = {}, []
            for r, (t0_, c0), (t1, c1) in self.cpu.values():
                if t1 - t0_ > 1.0:
                    cpu_by_role[r] = cpu_by_role.get(r, 0.0) + (c1 - c0) / (t1 - t0_)
                    spans.append(t1 - t0_)
            if cpu_by_role:
                per_step = {r: round(1000 * v / out['steps_per_s'], 3) for r, v in cpu_by_role.items()}
                out['cpu_ms_per_step'] = dict(per_step, total=round(sum(per_step.values()), 3))
                out['cores_busy'] = round(sum(cpu_by_role.values()), 2)
        if code != 0:
            out['tail'] = ''.join(self.lines[-15:])
        return out


def on_signal(signum, frame):
    run = Run.current
    print(f'\nbench_ros: {signal.Signals(signum).name}: stopping the current run', file=sys.stderr, flush=True)
    if run is not None:
        run.end()
    raise SystemExit(130)


# ------------------------------------------------------------------ main

def parse_ints(text):
    return [int(v) for v in text.split(',') if v.strip()] if text else []


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--agents', default='6,12,24,48,96',
                    help='agent counts, agents as processes (default 6,12,24,48,96)')
    ap.add_argument('--in-process', default='6,12,24', help="agent counts run with --in-process ('' = none)")
    ap.add_argument('--steps', type=float, default=1.0,
                    help='scale the steps per run (default 1: 4000 steps at n=6 … 400 at n=96)')
    ap.add_argument('--full', action=argparse.BooleanOptionalAction, default=True,
                    help='also the whole homotopy_global run to t = 1000 with a bag (default on)')
    ap.add_argument('--per-process', default='1', help="--agents-per-process values for the process runs, "
                    "comma-separated (e.g. 1,auto; default 1)")
    ap.add_argument('--no-agent-clock', action='store_true', help='also 6 agent processes with /clock every 10^6 steps')
    ap.add_argument('--max-processes', type=int, default=100, help='skip one-process-per-agent runs of more '
                    'agents than this (Fast DDS simple discovery stops near 100 participants; default 100)')
    ap.add_argument('--plot', metavar='PNG', help='log-log plot of CPU per step and steps/s against n')
    ap.add_argument('--repeat', type=int, default=1, help='runs per case (default 1)')
    ap.add_argument('--swarm', action='append', metavar='LABEL=PATH', help=(
        'a swarm executable to measure, with a label; repeat to measure several interleaved, case by '
        'case (e.g. after=.venv/bin/swarm before=/tmp/old/swarm); default: this=' + DEFAULT_SWARM))
    ap.add_argument('--timeout', type=float, default=900, help='give up on one run after this many s')
    ap.add_argument('--run-args', default='', metavar='ARGS',
                    help="more options of every swarm run but the full one, e.g. '--start-timeout 900'")
    ap.add_argument('--dim', default='2', help="dimensions of the process runs' swarms, comma-separated "
                    '(2: homotopy_global, 3: homotopy_3d on a grid; e.g. 2,3 side by side; default 2)')
    ap.add_argument('--out', default='bench/ros.json', help='results JSON (default bench/ros.json)')
    a = ap.parse_args(argv)
    try:
        counts, inproc = parse_ints(a.agents), parse_ints(a.in_process)
    except ValueError:
        ap.error('--agents / --in-process: comma-separated integers')
    if not all(d.strip() in ('2', '3') for d in a.dim.split(',')):
        ap.error(f'--dim {a.dim}: 2, 3 or 2,3')
    exes = []
    for item in a.swarm or [f'this={DEFAULT_SWARM}']:
        label, sep, exe = item.partition('=')
        if not sep or not label or not exe:
            ap.error(f'--swarm {item!r}: want LABEL=PATH')
        exes.append((label, exe))
    for _, exe in exes:
        if not os.access(exe, os.X_OK):
            ap.error(f'{exe}: not an executable')
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, on_signal)
    dom, lock = claim_domain()
    env = dict(os.environ, ROS_DOMAIN_ID=str(dom), PYTHONUNBUFFERED='1')
    for k in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS', 'FASTRTPS_DEFAULT_PROFILES_FILE',
              'FASTDDS_DEFAULT_PROFILES_FILE'):
        env.pop(k, None)                    # the launcher chooses (LOCALHOST, or a profile past 32)
    per = [v.strip() for v in a.per_process.split(',') if v.strip()]
    dims = [{'2': '', '3': '-3d'}[d.strip()] for d in a.dim.split(',') if d.strip() in ('2', '3')]
    cases = [('processes' + d, n, k) for n in counts for k in per for d in dims] + \
        [('in-process', n, '1') for n in inproc]
    if a.no_agent_clock:
        cases.append(('no-agent-clock', 6, '1'))
    if a.full:
        cases.append(('full', 6, '1'))
    results = dict(command=' '.join([Path(sys.argv[0]).name] + (sys.argv[1:] if argv is None else argv)),
                   date=time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()), domain=dom, cpus=os.cpu_count(),
                   load_start=loadavg(), runs=[])
    out_path = Path(a.out)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    print(f'bench_ros: domain {dom}, {len(cases)} cases x {len(exes)} executables x {a.repeat}; load {loadavg()}',
          flush=True)
    try:
        with tempfile.TemporaryDirectory(prefix='bench_ros_') as tmp:
            tmp = Path(tmp)
            for rep in range(a.repeat):
                for kind, n, k in cases:
                    for label, exe in exes:
                        if k == '1' and kind.startswith('processes') and n > a.max_processes:
                            print(f'  [{label}] processes n={n} K=1: skipped (more than --max-processes)', flush=True)
                            continue
                        run_dir = tmp / f'{label}-{kind}-{n}-{k}-{rep}'
                        if kind == 'full':
                            bag = tmp / f'{label}-{rep}.mcap'
                            args = [exe, 'run', 'homotopy_global', '--record', str(bag), '--no-figure',
                                    '--progress-every', '250', '--out', str(run_dir)]
                        else:
                            steps = int(DEFAULT_STEPS.get(n, max(200, 24000 // n)) * a.steps)
                            scn = scenario_file(n, steps, tmp, dim=3 if kind.endswith('-3d') else 2)
                            args = [exe, 'run', str(scn), '--no-figure', '--out', str(run_dir),
                                    '--progress-every', str(steps * 0.05 / 2)]
                            if kind == 'in-process':
                                args.append('--in-process')
                            if k != '1':
                                args += ['--agents-per-process', k]
                            args += a.run_args.split()
                            if kind == 'no-agent-clock':
                                args += ['--clock-every', '1000000']
                        load0 = loadavg()
                        print(f'  [{label}] {kind} n={n} K={k} (run {rep + 1}/{a.repeat}); load {load0}', flush=True)
                        r = Run(args, env, a.timeout).go()
                        if kind == 'full' and bag.exists():
                            r['bag_mib'] = round(bag.stat().st_size / 2**20, 2)
                            r['bag_states'] = bag_states(bag)
                            if r.get('steps'):
                                r['bag_states_expected'] = (r['steps'] + 2) * n   # t_0 … t_{steps+1}
                        r.update(label=label, kind=kind, agents=n, per_process=k, repeat=rep, load_before=load0,
                                 load_after=loadavg())
                        results['runs'].append(r)
                        print(f'    -> {summary_line(r)}', flush=True)
                        out_path.write_text(json.dumps(results, indent=1))
    finally:
        results['load_end'] = loadavg()
        out_path.write_text(json.dumps(results, indent=1))
        lock.close()
    print(markdown(results))
    print(f'bench_ros: wrote {out_path}')
    if a.plot:
        plot(results, a.plot)
        print(f'bench_ros: wrote {a.plot}')
    return 0


def plot(results, path):
    """CPU ms per step and steps/s against n (log-log), one line per label and agents per process."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    lines = {}
    for r in results['runs']:
        if r['kind'] != 'processes' or r['exit_code'] != 0 or not r.get('steps_per_s'):
            continue
        key = f"{r['label']}, K={r.get('per_process', '1')}"
        lines.setdefault(key, []).append((r['agents'], r.get('cpu_ms_per_step', {}).get('total'), r['steps_per_s']))
    for key, pts in sorted(lines.items()):
        pts.sort()
        n = [p[0] for p in pts]
        ax1.loglog(n, [p[1] for p in pts], 'o-', label=key)
        ax2.loglog(n, [p[2] for p in pts], 'o-', label=key)
    ax1.set(xlabel='agents n', ylabel='CPU ms per lockstep step (all processes)', title='cost per step')
    ax2.set(xlabel='agents n', ylabel='lockstep steps/s', title='rate')
    for ax in (ax1, ax2):
        ax.grid(True, which='both', alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def bag_states(bag) -> int:
    """Number of /swarm/states messages in a bag."""
    from swarm_tools.bags.mcap_io import bag_topics
    return bag_topics(bag).get('/swarm/states', {}).get('count', 0)


def summary_line(r):
    rss = r.get('rss_mib', {})
    ag = rss.get('agent', {})
    return (f"exit {r['exit_code']}, {r.get('steps_per_s', '—')} steps/s, {r.get('stalls')} stalls, "
            f"start {r.get('start_s', '—')} s (discovery {r.get('discovery_s', '—')} s), "
            f"launcher wall {r['launcher_wall_s']} s, "
            f"agent RSS {ag.get('median', '—')} MiB, total {r.get('rss_total_mib', '—')} MiB, "
            f"CPU ms/step {r.get('cpu_ms_per_step', {})}"
            + (f", bag {r.get('bag_mib')} MiB with {r.get('bag_states')}/{r.get('bag_states_expected')} states"
               if 'bag_mib' in r else ''))


def markdown(results) -> str:
    rows = ['| executable | how | agents | agents per process | steps/s | start (s) | discovery (s) '
            '| RSS agent / world / commander (MiB) | RSS total (MiB) '
            '| CPU ms/step (agents / world / commander / total) | wall (s) | load before→after |',
            '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in results['runs']:
        rss = r.get('rss_mib', {})
        f = lambda k, rss=rss: str(rss.get(k, {}).get('median', '—'))
        how = {'processes': 'processes', 'processes-3d': 'processes, 3D', 'in-process': 'one process',
               'full': 'homotopy_global t=1000 + bag',
               'no-agent-clock': 'processes, /clock every 10^6 steps'}[r['kind']]
        sps = r.get('steps_per_s', '—') if r['exit_code'] == 0 else f"failed ({r['exit_code']})"
        cpu = r.get('cpu_ms_per_step', {})
        c = lambda k, cpu=cpu: str(cpu.get(k, '—'))
        cpus = (f"{c('agent') if 'agent' in cpu else c('container')} / {c('world')} / {c('commander')} / {c('total')}"
                if r['kind'] != 'in-process' else f"one process: {c('total')}")
        ag = 'agent' if 'agent' in rss or 'container' not in rss else 'container'
        rows.append(f"| {r['label']} | {how} | {r['agents']} | {r.get('per_process', '1')} | {sps} | "
                    f"{r.get('start_s', '—')} | {r.get('discovery_s', '—')} | "
                    f"{f(ag)} / {f('world')} / {f('commander')} | {r.get('rss_total_mib', '—')} | {cpus} | "
                    f"{r['launcher_wall_s']} | {r['load_before']} → {r['load_after']} |")
    return '\n'.join(rows)


if __name__ == '__main__':
    sys.exit(main())
