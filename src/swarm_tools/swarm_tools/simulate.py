"""``swarm simulate``, ``swarm sweep`` and ``swarm scenarios`` (batch engine, no ROS)."""
from __future__ import annotations

import argparse
import multiprocessing
import os
import signal
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import numpy as np

from swarm_core import study as st
from swarm_core.analysis.outputs import analyse, check_output_dir, dumps, summary_of, write_failed, write_outputs
from swarm_core.command.plan import law_timeline, read_commands, recorded_law_hashes
from swarm_core.engine import fast
from swarm_core.engine import reference as engine
from swarm_core.files import write_atomic
from swarm_core.laws import LawError, LawFailed
from swarm_core.laws.guards import exit_workers_leaving_no_thread
from swarm_core.laws.paper import compiled_sums
from swarm_core.scenario import loader as scenario
from swarm_core.study.runner import VANISHED_WORKER


class _Progress:
    """A progress bar on stderr when it is a terminal; plain lines every 10% otherwise."""

    def __init__(self, label, enabled=True):
        self.label, self.enabled = label, enabled
        self.tty = sys.stderr.isatty()
        self.last = -1
        self.start = time.perf_counter()

    def __call__(self, step, steps):
        if not self.enabled:
            return
        pct = int(100 * step / max(1, steps))
        if self.tty:
            bar = '#' * (pct // 4)
            sys.stderr.write(f'\r{self.label} [{bar:<25}] {pct:3d}%  step {step}/{steps}')
            if step >= steps:
                sys.stderr.write(f'  {time.perf_counter() - self.start:.1f}s\n')
            sys.stderr.flush()
        elif pct // 10 != self.last // 10 or step >= steps:
            sys.stderr.write(f'{self.label}: {pct}% (step {step}/{steps})\n')
        self.last = pct


def _make_dir_or_exit(prog, path) -> Path:
    """Create the output directory ``path`` before anything is computed: one line and exit 2
    if it cannot be made (not a traceback after the work is done)."""
    err = check_output_dir(path)
    if err:
        print(f'{prog}: {err}', file=sys.stderr)
        raise SystemExit(2)
    return Path(path)


def _load_or_exit(name, **over):
    try:
        return scenario.load(name, **over)
    except scenario.ScenarioError as err:
        print(f'swarm: {err}', file=sys.stderr)
        raise SystemExit(2) from None


#: largest events file ``--replay`` reads (a long run's events.jsonl is a few MB)
MAX_REPLAY_BYTES = 64 * 1024 * 1024


def _replay_or_exit(path, scn) -> dict:
    """The commands of an events file by step (`swarm_core.command.plan.read_commands`), or exit 2
    naming the problem.  A law file whose hash differs from the one the run recorded is said in
    one line (the replay runs the file as it is now)."""
    try:
        with open(path, 'rb') as fh:           # at most the limit, whatever the file is (/dev/zero)
            raw = fh.read(MAX_REPLAY_BYTES + 1)
        if len(raw) > MAX_REPLAY_BYTES:
            raise ValueError(f'more than {MAX_REPLAY_BYTES} bytes')
        lines = raw.decode('utf-8').splitlines()
        commands = read_commands(lines, scn.names)
        law_timeline(commands, scn.law, len(scn.names))          # an agent's law changes: each must fit its law
        ran = [h for h in recorded_law_hashes(lines) if h != scn.law_hash]
        if ran:                     # the run's law file is not the one this replay imports
            print(f'swarm simulate: --replay {path}: the law file changed since the run (the run\'s hash '
                  f'{ran[0]}, now {scn.law_hash or "none"}): the replay runs today\'s file', file=sys.stderr)
        late = [s for s in commands if s > scn.steps]
        if late:
            raise ValueError(f'a command at step {late[0]} is after the last step {scn.steps}')
    except (OSError, ValueError) as err:
        print(f'swarm simulate: --replay {path}: {getattr(err, "strerror", None) or err}', file=sys.stderr)
        raise SystemExit(2) from None
    return commands


def _engine_option(p):
    p.add_argument('--engine', choices=['fast', 'reference'], default='fast', help=(
        'fast (default): the law\'s compiled run (swarm_core.engine.fast) where it covers the run, else the '
        'reference; reference: the numpy engine the ROS nodes are checked against (a study with '
        'robot_set runs on the robot engine, swarm_robots.engine)'))


def _simulator(name):
    """``simulate`` of engine ``name`` (a law's compiled run is imported only when it runs)."""
    if name == 'reference':
        return engine.simulate
    return fast.simulate


def simulate_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm simulate', description=(
        'Run a scenario in the batch engine (pure numpy, no ROS) and write trajectory.npz, '
        'metrics.json and a figure into --out.'))
    p.add_argument('scenario', help='a shipped scenario name (see `swarm scenarios`) or a YAML file')
    p.add_argument('--seed', type=int, help='random seed (initial headings, noise); default: the file\'s')
    p.add_argument('--duration', type=float, help='simulated time to run (default: the file\'s)')
    p.add_argument('--dt', type=float, help='control/integration step (default: the file\'s)')
    p.add_argument('--integrator', choices=['zoh', 'rk4'], help=(
        'zero-order-hold exact arc (default) or RK4 reference (default --out: runs/SCENARIO-seedN-rk4)'))
    p.add_argument('--out', default=None, help='output directory (default: runs/SCENARIO-seedN)')
    p.add_argument('--record-every', type=int, default=1, metavar='K', help='keep every K-th step (default 1)')
    p.add_argument('--no-figure', action='store_true', help='skip the PNG figure')
    p.add_argument('--quiet', action='store_true', help='no progress output')
    p.add_argument('--replay', metavar='EVENTS.jsonl', help=(
        "re-apply a run's live commands (the 'command' events of its events.jsonl: λ, steering, an "
        "agent's law parameters) at their steps"))
    _engine_option(p)
    p.add_argument('--compiled', choices=compiled_sums.CHOICES, default='auto', help=compiled_sums.HELP)
    a = p.parse_args(argv)
    if a.record_every < 1:
        p.error('--record-every must be ≥ 1')
    over = dict(seed=a.seed, duration=a.duration, dt=a.dt)
    if a.integrator:
        over['integrator'] = a.integrator
    scn = _load_or_exit(a.scenario, **over)
    # the RK4 reference run gets its own default directory (it overwrote the ZOH run's)
    rk4 = '-rk4' if scn.spec.integrator == 'rk4' else ''
    out = a.out or os.path.join('runs', f'{scn.label}-seed{scn.seed}{rk4}')
    _make_dir_or_exit('swarm simulate', out)
    if not a.quiet:
        src = scn.source if scn.source.startswith(scn.name) else f'{scn.name} ({scn.source})'
        print(f'swarm simulate: {src}, {len(scn.names)} agents, law {scn.law.kind}, '
              f'dt {scn.dt}, t = 0..{scn.duration:g} ({scn.steps} steps), seed {scn.seed}', file=sys.stderr)
    commands = _replay_or_exit(a.replay, scn) if a.replay else None
    try:
        traj = _simulator(a.engine)(scn, record_every=a.record_every, commands=commands, compiled=a.compiled,
                                    progress=_Progress(f'{scn.name} seed {scn.seed}', not a.quiet))
    except LawFailed as err:        # the steps done are saved, with one line
        return _law_failed(err, out, scn, a.no_figure)
    if not a.quiet and traj.meta.get('fallback'):
        print(f'swarm simulate: the fast engine does not cover this run ({traj.meta["fallback"]}): '
              'the reference engine ran it', file=sys.stderr)
    series, checks = analyse(traj, scenario=scn)
    try:
        summary = write_outputs(out, scn, traj, series, checks, figure=not a.no_figure)
    except OSError as err:
        print(write_failed('swarm simulate', out, err), file=sys.stderr)
        return 1
    interrupted = summary['interrupted']
    changes = ', '.join(f't={t:g}: {c}' for t, c in summary['cluster_changes'][:12])
    print(f'{scn.name} seed {scn.seed}: t_end {summary["t_end"]:g}, final clusters {summary["final_clusters"]}, '
          f'polarisation {summary["final_polarisation"]:.3f}, min distance {summary["min_distance"]:.3g}, '
          f'compute {summary["wall_seconds"]:.2f}s' + (' (INTERRUPTED: partial run saved)' if interrupted else ''))
    print(f'  clusters over time: {changes}')
    for ev in summary.get('events', [])[:20]:
        det = ', '.join(f'{k}={v}' for k, v in ev.items() if k not in ('t', 'kind', 'step'))
        print(f'  event t={ev["t"]:g}: {ev["kind"]} ({det})')
    for name, res in checks.items():
        det = res.get('not_judged') or ', '.join(f'{k}={v}' for k, v in res.items() if k != 'passed')
        verdict = {True: 'PASS', False: 'FAIL', None: 'NOT JUDGED'}[res['passed']]
        print(f'  {verdict} {name}: {det}')
    print(f'  wrote {out}/trajectory.npz, metrics.json' + ('' if a.no_figure else f', {scn.label}.png'))
    return 130 if interrupted else 0


def _law_failed(err, out, scn, no_figure) -> int:
    """A law that failed during ``swarm simulate``: one line, the steps done saved; exit 1."""
    traj = err.trajectory
    sys.stderr.write('\n' if sys.stderr.isatty() else '')      # (after a progress bar)
    if traj is None or not len(traj.t):
        print(f'swarm simulate: {err}; nothing saved', file=sys.stderr)
        return 1
    try:
        series, checks = analyse(traj, scenario=scn)
        write_outputs(out, scn, traj, series, checks, figure=not no_figure)
    except OSError as e:
        print(write_failed('swarm simulate', out, e), file=sys.stderr)
        return 1
    print(f'swarm simulate: {err}; the steps done (t = 0..{traj.t[-1]:g}) are in {out}/trajectory.npz, '
          'metrics.json', file=sys.stderr)
    return 1


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep; ``results`` holds the seeds that finished (in seed order)."""

    def __init__(self, results):
        super().__init__()
        self.results = results


class SweepFailed(SweepInterrupted):
    """A seed's law failed (`LawError`): the sweep stops as on Ctrl-C, with that line."""

    def __init__(self, message, results):
        super().__init__(results)
        self.message = message


_STOP = None      # in a sweep's worker processes: set when the sweep is interrupted


def _init_worker(stop):
    """Pool worker initializer: a Ctrl-C while idle is ignored (``_sweep_one`` takes it
    while it computes), so a worker never dies with a traceback between seeds; ``stop`` is
    set by the parent when the sweep is interrupted (seeds already queued then do not start)."""
    global _STOP
    _STOP = stop
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    exit_workers_leaving_no_thread()       # a law that left a thread running must not hold the pool


def _sweep_one(args):
    name, seed, over = args
    if _STOP is not None and _STOP.is_set():
        return dict(seed=seed, interrupted=True)
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        scn = scenario.load(name, seed=seed, **over)
        traj = engine.simulate(scn)
        if traj.meta.get('interrupted'):
            return dict(seed=seed, interrupted=True)
        series, checks = analyse(traj, scenario=scn)
    except KeyboardInterrupt:
        return dict(seed=seed, interrupted=True)
    except LawError as err:        # a law that failed: the sweep stops (`SweepFailed`)
        return dict(seed=seed, failed=str(err))
    finally:
        signal.signal(signal.SIGINT, old)
    s = summary_of(scn, traj, series, checks)
    return dict(seed=seed, ok=s['behaviour_ok'], checks=checks, final_clusters=s['final_clusters'],
                wall=s['wall_seconds'])


def sweep(name, seeds, jobs=1, progress=True, **over):
    """Run seeds 0..seeds−1 (or the given list) and return the per-seed results.

    Ctrl-C (SIGINT to this process or to its whole group) stops the seeds still running
    (each at its next step) and raises `SweepInterrupted` with the results of the seeds
    that had finished; an interrupted seed is not counted.  A seed whose law fails stops the
    others the same way and raises `SweepFailed` naming it."""
    seed_list = list(range(seeds)) if isinstance(seeds, int) else list(seeds)
    work = [(name, s, over) for s in seed_list]
    results = []

    def take(r):
        if r.get('interrupted'):
            raise KeyboardInterrupt
        if r.get('failed'):
            raise SweepFailed(f'{name} seed {r["seed"]}: {r["failed"]}', results)
        results.append(r)
        if progress:
            print(f'  {name} seed {r["seed"]}: {"ok" if r["ok"] else "FAILED"} '
                  f'({len(results)}/{len(work)})', file=sys.stderr, flush=True)

    if jobs > 1:
        stop = multiprocessing.Event()
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker, initargs=(stop,)) as pool:
            futures = [pool.submit(_sweep_one, w) for w in work]
            try:
                for f in futures:
                    try:
                        r = f.result()
                    except BrokenProcessPool:
                        raise SweepFailed(f'{name}: {VANISHED_WORKER}', results) from None
                    take(r)
            except KeyboardInterrupt as why:
                stop.set()
                for f in futures:
                    f.cancel()
                for child in multiprocessing.active_children():   # the pool's workers
                    try:
                        os.kill(child.pid, signal.SIGINT)         # end the running seeds now
                    except ProcessLookupError:
                        pass
                raise (why if isinstance(why, SweepFailed) else SweepInterrupted(results)) from None
    else:
        try:
            for w in work:
                take(_sweep_one(w))
        except SweepFailed:
            raise
        except KeyboardInterrupt:
            raise SweepInterrupted(results) from None
    return results


def _median(vals):
    vals = [v for v in vals if v is not None]
    return None if not vals else float(np.median(vals))


def sweep_table(name, results) -> str:
    n = len(results)
    names = list(results[0]['checks']) if results else []
    lines = [f'### {name} ({n} seeds: {results[0]["seed"]}..{results[-1]["seed"]})' if results else f'### {name}',
             '', '| check | passed | median detail |', '|---|---|---|']
    for c in names:
        passed = sum(r['checks'][c]['passed'] is True for r in results)
        unjudged = sum(r['checks'][c]['passed'] is None for r in results)
        keys = list(dict.fromkeys(k for r in results for k in r['checks'][c] if k not in ('passed', 'not_judged')))
        det = []
        for k in keys:
            vals = [r['checks'][c].get(k) for r in results]
            if all(isinstance(v, (int, float)) or v is None for v in vals):
                med = _median(vals)
                det.append(f'{k} {med:.4g}' if med is not None else f'{k} n/a')
        note = f' ({unjudged} not judged: run shorter than the scenario)' if unjudged else ''
        lines.append(f'| {c} | {passed}/{n}{note} | {", ".join(det)} |')
    ok = sum(bool(r['ok']) for r in results)
    lines.append(f'| **all checks** | **{ok}/{n}** | '
                 f'failing seeds: {[r["seed"] for r in results if r["ok"] is False]} |')
    return '\n'.join(lines)


def _sweep_parser() -> argparse.ArgumentParser:
    """The options of ``swarm sweep``: a plain sweep over seeds, or a parameter study."""
    p = argparse.ArgumentParser(prog='swarm sweep', description=(
        "Run scenarios over many seeds and count how often the paper's behaviour happens "
        "(the scenario's `expect` checks). With --set or --study: a parameter study over a "
        "grid of scenario fields (one scenario), written as tables and a figure into --out DIR, "
        "cached per run so a re-run skips finished runs. Ctrl-C stops and keeps what finished "
        "(exit 130)."))
    p.add_argument('scenarios', nargs='*', help='shipped scenario names or YAML files')
    p.add_argument('--seeds', type=int, default=None,
                   help='seeds FIRST..FIRST+N-1 (default 20; a study file may set it)')
    p.add_argument('--first-seed', type=int, default=0, metavar='FIRST', help='first seed (default 0)')
    jobs = os.cpu_count() or 1
    p.add_argument('--jobs', type=int, default=jobs, help=f'parallel processes (default: the CPU count, {jobs})')
    p.add_argument('--dt', type=float, help="override dt (default: the scenario's)")
    p.add_argument('--integrator', choices=['zoh', 'rk4'], help="override the integrator (default: the scenario's)")
    p.add_argument('--out', metavar='PATH', help='plain sweep: FILE.md for the tables (per-seed JSON next to it); '
                   'study: the output directory (default runs/study-NAME)')
    g = p.add_argument_group('parameter studies (swarm_core.study.runner)')
    g.add_argument('--set', action='append', default=[], metavar='FIELD=VALUES',
                   help='a grid axis over a scenario field: law.leader_gain=10,30,50 or a range '
                        'noise.heading=0:0.05:6 (START:STOP:COUNT); repeat for more axes')
    g.add_argument('--study', metavar='FILE.yaml', help='a study file (scenario, grid, seeds, fixed overrides)')
    g.add_argument('--duration', type=float, help="study: override the duration (default: the scenario's)")
    g.add_argument('--scheduler', metavar='ADDR', help='run on Dask: tcp://HOST:8786 (an existing scheduler) '
                   'or local:N (a local cluster of N workers); default: local processes (--jobs)')
    g.add_argument('--check', default=None,
                   help="study: the check whose rate the figure shows (default 'all': every check)")
    g.add_argument('--no-figure', action='store_true', help='study: skip the figure')
    g.add_argument('--quiet', action='store_true', help='study: no progress bar')
    _engine_option(g)
    return p


def sweep_main(argv) -> int:
    p = _sweep_parser()
    a = p.parse_args(argv)
    if a.seeds is not None and a.seeds < 1:
        p.error('--seeds must be ≥ 1')
    if a.jobs < 1:
        p.error('--jobs must be ≥ 1')
    if a.first_seed < 0:
        p.error('--first-seed must be ≥ 0')
    if a.set or a.study:
        return study_main(p, a)
    if not a.scenarios:
        p.error('give at least one scenario (or --set / --study for a parameter study)')
    for flag in ('scheduler', 'duration', 'check'):
        if getattr(a, flag) is not None:
            p.error(f'--{flag} is for parameter studies (with --set or --study)')
    a.seeds = 20 if a.seeds is None else a.seeds
    over = {k: v for k, v in dict(dt=a.dt, integrator=a.integrator).items() if v is not None}
    for name in a.scenarios:
        _load_or_exit(name, **over)      # validate every scenario before spending time
    if a.out:
        _make_dir_or_exit('swarm sweep', Path(a.out).parent)
    tables, everything = [], {}
    interrupted = False
    for name in a.scenarios:
        seeds = range(a.first_seed, a.first_seed + a.seeds)
        t0 = time.perf_counter()
        try:
            res = sweep(name, seeds, jobs=a.jobs, **over)
        except SweepFailed as stop:
            print(f'swarm sweep: {stop.message}; the sweep stops', file=sys.stderr)
            return 1
        except SweepInterrupted as stop:
            res, interrupted = stop.results, True
        note = f' INTERRUPTED after {len(res)} of {a.seeds} seeds' if interrupted else ''
        if res or not interrupted:
            table = sweep_table(name, res)
            print(table + f'\n\n({time.perf_counter() - t0:.1f}s wall, {a.jobs} jobs{";" + note if note else ""})\n',
                  flush=True)
            tables.append(table + (f'\n\n({note.strip()})' if note else ''))
            everything[name] = res
        if interrupted:
            rest = a.scenarios[a.scenarios.index(name) + 1:]
            print(f'swarm sweep: interrupted during {name} ({len(res)}/{a.seeds} seeds finished)'
                  + (f'; not run: {", ".join(rest)}' if rest else ''), file=sys.stderr)
            break
    if a.out and everything:
        try:
            write_atomic(a.out, '\n\n'.join(tables) + '\n')
            write_atomic(Path(a.out).with_suffix('.json'), dumps(everything))
        except OSError as err:
            print(write_failed('swarm sweep', a.out, err), file=sys.stderr)
            return 1
        print(f'wrote {a.out} and {Path(a.out).with_suffix(".json")}', file=sys.stderr)
    return 130 if interrupted else 0


def study_main(p, a) -> int:
    """`swarm sweep --set ... / --study FILE`: validate every cell, run (cached), write
    runs.csv and runs.parquet (one row per run), rates.csv and rates.md (rate per cell and check, 95 % Wilson
    CI) and a figure into --out."""
    if a.study and a.scenarios:
        p.error('give a study file or a scenario with --set, not both')
    if not a.study and len(a.scenarios) != 1:
        p.error('a study with --set runs one scenario')
    if a.scheduler and not (a.scheduler.startswith(('tcp://', 'tls://')) or
                            (a.scheduler.startswith('local:') and a.scheduler[6:].isdigit()
                             and int(a.scheduler[6:]) >= 1)):
        p.error(f'--scheduler {a.scheduler!r}: give tcp://HOST:PORT or local:N')
    fixed = {k: v for k, v in dict(dt=a.dt, integrator=a.integrator, duration=a.duration).items() if v is not None}
    try:
        if a.study:
            study = st.load_study(a.study)
            extra = [st.parse_set(e) for e in a.set]
            for k, vals in extra:
                study.grid[k] = vals          # --set adds or replaces an axis of the file
            if a.seeds is not None:
                study.seeds = list(range(a.first_seed, a.first_seed + a.seeds))
            study.fixed.update(fixed)
        else:
            study = st.make_study(a.scenarios[0], a.set, seeds=20 if a.seeds is None else a.seeds,
                                  first_seed=a.first_seed, fixed=fixed)
        st.validate(study)
    except st.StudyError as err:
        print(f'swarm sweep: {err}', file=sys.stderr)
        return 2
    out = _make_dir_or_exit('swarm sweep', a.out or os.path.join('runs', f'study-{study.name}'))
    n_cells = len(study.cells())
    where = f'Dask {a.scheduler}' if a.scheduler else f'{a.jobs} local process{"es" if a.jobs > 1 else ""}'
    print(f'swarm sweep: study {study.name}: {study.source}, {n_cells} cells × {len(study.seeds)} seeds '
          f'= {n_cells * len(study.seeds)} runs on {where}; cache {out / "cache"}', file=sys.stderr)
    if a.engine == 'fast':              # compiled (or loaded) once here: forked workers inherit it
        fast.warm_up()
    t0 = time.perf_counter()
    interrupted = False
    counts = {}
    try:
        rows, counts = st.run_study(study, out / 'cache', jobs=a.jobs, scheduler=a.scheduler,
                                    progress=not a.quiet, engine=a.engine)
    except KeyboardInterrupt:
        interrupted = True
    except LawError as err:             # a run's law failed: the runs done stay cached
        print(f'swarm sweep: {err}; the study stops (the runs done are cached in {out / "cache"})',
              file=sys.stderr)
        return 1
    except OSError as err:              # the cache (a full or read-only disk)
        print(write_failed('swarm sweep', out, err), file=sys.stderr)
        return 1
    wall = time.perf_counter() - t0
    if interrupted:
        done = len(list((out / 'cache').glob('*.json')))
        print(f'swarm sweep: interrupted; finished runs are cached in {out / "cache"} ({done} files): '
              f'the same command resumes', file=sys.stderr)
        return 130
    try:
        figures = _write_study(out, study, rows, a)
    except OSError as err:
        print(write_failed('swarm sweep', out, err), file=sys.stderr)
        return 1
    print(f'swarm sweep: {counts["ran"]} runs done, {counts["cached"]} from the cache, {wall:.1f}s wall; '
          f'wrote {out}/runs.csv, runs.parquet, rates.csv, rates.md' + ''.join(f', {f}' for f in figures),
          file=sys.stderr)
    return 0


def _write_study(out, study, rows, a) -> list:
    """runs.csv, rates.csv, rates.md and the figures of a finished study into ``out``; the
    names of the figures written."""
    write_atomic(out / 'runs.csv', st.to_csv(study, rows))
    st.to_parquet(study, rows, out / 'runs.parquet')
    rr = st.rates(study, rows)
    write_atomic(out / 'rates.csv', st.rates_csv(study, rr))
    md = st.rates_markdown(study, rr)
    robots = st.robot_metrics_markdown(study, rows)
    md += f'\n\nOn the robot engine, means over the seeds:\n\n{robots}' if robots else ''
    write_atomic(out / 'rates.md', f'### {study.name} ({len(study.seeds)} seeds per cell)\n\n{md}\n')
    print(md)
    checks = [a.check] if a.check else (study.figure.get('checks') or [study.figure.get('check', 'all')])
    have = list(dict.fromkeys(r['check'] for r in rr))
    figures = []
    for check in ([] if a.no_figure else checks):
        if check not in have:
            print(f'swarm sweep: --check {check!r}: no such check (have: {", ".join(have)}); figure skipped',
                  file=sys.stderr)
            continue
        name = study.name if check == checks[0] else f'{study.name}-{check}'
        figures.append(st.plot_rates(study, rr, out / f'{name}.png', check=check).name)
    return figures


def scenarios_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm scenarios', description='List the shipped scenarios.')
    p.parse_args(argv)
    for name in scenario.shipped_scenarios():
        scn = scenario.load(name)
        desc = ' '.join(scn.spec.description.split())
        print(f'{name:<18} {len(scn.names)} agents, {scn.law.kind} law, t = {scn.duration:g}: {desc}')
    return 0
