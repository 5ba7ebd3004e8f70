#!/usr/bin/env python3
"""Benchmark of the batch engine (no ROS): steps/s against swarm size, and the wall time of
the paper's homotopy_global run to t = 1000.

    .venv/bin/python scripts/bench_core.py [--quick] [--out bench/core] [--compare REV]

Writes bench/core.json and bench/core.png (steps/s vs n, log-log) and prints Markdown tables.
Also measures one call of the control law `swarm_control` on the paper's n = 6 table
(homotopy_global at t = 450, λ ≈ 0.97, and at λ = 0), for the whole swarm and for ONE
receiver (what every ROS agent computes per step), and `AgentCore.control`; each the median
over batches of 200 calls.  ``--global-n`` / ``--local-n`` choose the swarm sizes (comma
lists; empty: none), ``--no-runs`` skips the full homotopy_global runs.  ``--dim 2,3`` measures
the same swarms in 3D too (natural frames, the same grid, headings in a π/4 cap about +x), each
3D row right after its planar one, and for full runs only the 3D Fig. 3 run (homotopy_3d) beside
homotopy_global on the reference engine; ``--volume`` adds 3D swarms on a cubic lattice.  ``--compare REV``
measures revision REV's engine too, each measurement right before this checkout's; the fast
engine's runs and start-up as well where REV has the fast engine.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------ worker (one measurement)

def compiled_engine():
    """The study fast path of the checkout this worker runs: `swarm_core.engine.fast`, or
    `swarm_core.engine.compiled` (revisions before the laws chose their compiled runs), or
    `swarm_core.fast` in revisions before the sub-packages."""
    try:
        from swarm_core.engine import fast as compiled
    except ImportError:
        try:
            from swarm_core.engine import compiled
        except ImportError:
            from swarm_core import fast as compiled
    return compiled


def swarm(n, kind, spacing=1.5, seed=0):
    """n agents on a square grid at the paper's spacing, random headings in a 90° cone."""
    from swarm_core import scenario
    data = dict(name=f'bench_{kind}_{n}', seed=seed, dt=0.05, duration=1.0,
                agents=dict(count=n, positions={'rule': 'grid', 'spacing': spacing},
                            headings={'rule': 'cone'}),
                law=dict(kind='homotopy' if kind == 'local' else 'global', q0=0.0 if kind == 'local' else 1.0))
    if kind == 'local':        # the homotopy law at λ = 1: leader following, local coupling within w
        data['lambda'] = {'kind': 'constant', 'value': 1.0}
        data['leaders'] = {'fixed': {'agent_0': {'kind': 'constant', 'curvature': 0.01},
                                     f'agent_{n - 1}': {'kind': 'constant', 'curvature': -0.01}}}
    return scenario.parse(data)


def swarm_3d(n, kind, layout='grid', spacing=1.5, seed=0):
    """`swarm` in 3D: the same grid (or a cubic lattice, ``layout`` 'cube'), headings in a π/4
    cap about +x, leaders' programs (±0.01, 0) in their own (y, z)."""
    import numpy as np

    from swarm_core import scenario
    data = dict(name=f'bench3_{kind}_{n}', dim=3, seed=seed, dt=0.05, duration=1.0,
                agents=dict(count=n, positions={'rule': 'grid', 'spacing': spacing},
                            headings={'rule': 'cap', 'axis': [1, 0, 0]}),
                law=dict(kind='homotopy' if kind == 'local' else 'global', q0=0.0 if kind == 'local' else 1.0))
    if kind == 'local':
        data['lambda'] = {'kind': 'constant', 'value': 1.0}
        data['leaders'] = {'fixed': {'agent_0': {'kind': 'constant', 'curvature': [0.01, 0.0]},
                                     f'agent_{n - 1}': {'kind': 'constant', 'curvature': [-0.01, 0.0]}}}
    scn = scenario.parse(data)
    if layout == 'cube':
        side = int(np.ceil(n ** (1 / 3) - 1e-9))
        cube = np.stack(np.meshgrid(*(np.arange(side),) * 3, indexing='ij'), -1).reshape(-1, 3)[:n] * spacing
        scn.pos0 = cube - cube.mean(axis=0)
    return scn


def natural_stepper(n, kind, search, layout):
    """A 3D stepper and its step(); search 'kdtree' (the numpy sums at any n) raises the
    compiled limit in this worker process."""
    from swarm_core.engine.natural import NaturalStepper
    from swarm_core.laws.paper import compiled_sums
    if search == 'kdtree':
        compiled_sums.COMPILED_LIMIT = 1 << 62
    st = NaturalStepper(swarm_3d(n, kind, layout))

    def step():
        t, lam, is_leader, steering = st.inputs()
        st.advance(t, st.control(t, st.pos, (st.x, st.y, st.z), lam, is_leader, steering), is_leader)
    if not (n >= compiled_sums.COMPILED_LIMIT and compiled_sums.available()):
        return step, 'numpy (dense)'
    return step, 'compiled, ' + ('all pairs' if kind == 'global' else 'cell list')


def steps_per_second(n, kind, min_seconds=1.0, search='auto', dim=2, layout='grid'):
    """(steps/s by wall time, steps/s by process CPU time, pair search) of a SwarmStepper
    (a NaturalStepper in 3D); search 'kdtree' keeps the reference numpy path at any n (no
    compiled kernels)."""
    from swarm_core import engine
    if dim == 3:
        step, how = natural_stepper(n, kind, search, layout)
    else:
        stepper = engine.SwarmStepper(swarm(n, kind), neighbour_search=search)
        step = stepper.step
    step()                                           # warm-up (caches, scratch arrays)
    steps, t0, c0 = 0, time.perf_counter(), time.process_time()
    while True:
        step()
        steps += 1
        el = time.perf_counter() - t0
        if el >= min_seconds and steps >= 3:
            cpu = time.process_time() - c0
            if dim == 3:
                return steps / el, steps / max(cpu, 1e-9), how
            pairs = stepper._pairs(stepper.pos, stepper.plan.schedule.value(0.0))
            search = pairs if isinstance(pairs, str) else 'kdtree' if pairs is not None else 'all pairs'
            return steps / el, steps / max(cpu, 1e-9), search


def full_run(name, dt, comms=None, duration=None, engine_name='reference'):
    """(wall s, CPU s) of one simulate() of a shipped scenario to its duration at dt, with the
    radio ``comms`` (a scenario ``comms`` mapping) or its own, on the reference engine or the
    fast one (`swarm_core.engine.fast`, compiled or loaded first; the median of as many runs as fill
    0.3 s of CPU)."""
    from swarm_core import engine, scenario
    simulate = engine.simulate
    if engine_name == 'fast':
        fast = compiled_engine()
        fast.warm_up()
        simulate = fast.simulate
    scn = scenario.load(name, dt=dt, comms=comms, duration=duration)
    walls, cpus = [], []
    while not cpus or (engine_name == 'fast' and sum(cpus) < 0.3):   # short runs: the median of many
        t0, c0 = time.perf_counter(), time.process_time()
        simulate(scn)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return statistics.median(walls), statistics.median(cpus)


def fast_start(cold):
    """(wall s, CPU s) of importing the fast path and compiling its kernels (``cold``: into
    an empty numba cache) or loading them from the cache."""
    if cold:
        os.environ['NUMBA_CACHE_DIR'] = tempfile.mkdtemp()
    t0, c0 = time.perf_counter(), time.process_time()
    fast = compiled_engine()
    fast.warm_up()
    return time.perf_counter() - t0, time.process_time() - c0


def law_call(receivers, lam, min_seconds):
    """µs (wall, CPU) per swarm_control call on homotopy_global's n = 6 table at t = 450
    (two leaders; λ ≈ 0.97, or ``lam``), for receivers 'one' (agent 2) or 'all'."""
    import numpy as np

    from swarm_core import engine, laws, scenario
    st = engine.SwarmStepper(scenario.load('homotopy_global'))
    for _ in range(9000):
        st.step()
    t, lam_t, is_leader, steering, (c, s) = st.inputs()
    lam = lam_t if lam is None else lam
    recv = np.array([2]) if receivers == 'one' else np.arange(st.n)
    steer = steering[recv]
    pos, law = st.pos.copy(), st.law
    return per_call(lambda: laws.swarm_control(pos, c, s, recv, law, lambda_=lam, is_leader=is_leader,
                                               steering=steer), min_seconds)


def per_call(f, min_seconds, batch=200):
    """µs (wall, CPU) per call of f: the median over batches of ``batch`` calls for
    ``min_seconds`` (a burst of load from other processes spoils a few batches, not the median)."""
    import statistics
    f()
    walls, cpus = [], []
    start = time.perf_counter()
    while time.perf_counter() - start < min_seconds or len(walls) < 5:
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(batch):
            f()
        walls.append((time.perf_counter() - t0) / batch * 1e6)
        cpus.append((time.process_time() - c0) / batch * 1e6)
    return statistics.median(walls), statistics.median(cpus)


def agent_call(min_seconds):
    """µs (wall, CPU) per `AgentCore.control` (an agent node's own arithmetic for one step:
    the table from the received states, then swarm_control with itself as the only receiver)
    on homotopy_global's states at t = 450, agent 2."""
    try:                      # module names since the layout change, then older revisions'
        from swarm_agent.agent_core import AgentCore
        try:
            from swarm_core.model import frenet as model
        except ImportError:
            from swarm_core import frenet as model
    except ImportError:
        from swarm_agent.core import AgentCore
        from swarm_core import model
    from swarm_core import engine, scenario
    st = engine.SwarmStepper(scenario.load('homotopy_global'))
    for _ in range(9000):
        st.step()
    t, lam, is_leader, steering, _ = st.inputs()
    qz, qw = model.quaternion_from_heading(st.theta)
    x, y = st.pos[:, 0].copy(), st.pos[:, 1].copy()
    core = AgentCore(2, st.n, x[2], y[2], st.theta[2], st.law, st.dt)
    return per_call(lambda: core.control(x, y, qz, qw, lam, is_leader, steering[2]), min_seconds)


def worker(spec):
    import swarm_core
    out = {}
    if spec['what'] == 'law':
        wall, cpu = law_call(spec['receivers'], spec['lam'], spec['min_seconds'])
        out = dict(wall=wall, cpu=cpu)
    elif spec['what'] == 'agent':
        import swarm_agent
        wall, cpu = agent_call(spec['min_seconds'])
        out = dict(wall=wall, cpu=cpu, agent_module=swarm_agent.__file__)
    elif spec['what'] == 'sps':
        wall, cpu, search = steps_per_second(spec['n'], spec['kind'], spec['min_seconds'],
                                             spec.get('search', 'auto'), spec.get('dim', 2),
                                             spec.get('layout', 'grid'))
        out = dict(wall=wall, cpu=cpu, search=search)
    elif spec['what'] == 'start':
        wall, cpu = fast_start(spec['cold'])
        out = dict(wall=wall, cpu=cpu)
    else:
        wall, cpu = full_run(spec['name'], spec['dt'], spec.get('comms'), spec.get('duration'),
                             spec.get('engine', 'reference'))
        out = dict(wall=wall, cpu=cpu)
    out['module'] = swarm_core.__file__
    print(json.dumps(out))


# ------------------------------------------------------------------ driver

def run_worker(spec, src=None):
    env = dict(os.environ)
    if src is not None:            # a baseline swarm_core (and swarm_agent) first on the path
        env['PYTHONPATH'] = os.pathsep.join([src, str(Path(src).parent / 'swarm_agent'),
                                             env.get('PYTHONPATH', '')])
    r = subprocess.run([sys.executable, __file__, '--worker', json.dumps(spec)], env=env,
                       capture_output=True, text=True, check=True)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    if src is not None and not out['module'].startswith(src):
        raise SystemExit(f'baseline not imported: got {out["module"]}')
    if src is not None and 'agent_module' in out and not out['agent_module'].startswith(str(Path(src).parent)):
        raise SystemExit(f'baseline swarm_agent not imported: got {out["agent_module"]}')
    return out


def extract(rev, into):
    """swarm_core and swarm_agent of git revision ``rev`` into directory ``into``; returns
    swarm_core's import root (swarm_agent's is beside it)."""
    r = subprocess.run(['git', '-C', str(ROOT), 'archive', rev, 'src/swarm_core', 'src/swarm_agent'],
                       capture_output=True)
    if r.returncode:
        raise SystemExit(f'bench_core: cannot read src/swarm_core at {rev!r}: '
                         f'{r.stderr.decode(errors="replace").strip()}')
    tar = r.stdout
    subprocess.run(['tar', '-x', '-C', into], input=tar, check=True)
    return str(Path(into) / 'src' / 'swarm_core')


def loadavg():
    try:
        return os.getloadavg()
    except OSError:
        return None


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--quick', action='store_true', help='fewer sizes, shorter timings')
    p.add_argument('--out', default='bench/core', help='output path stem (default bench/core)')
    p.add_argument('--compare', metavar='REV', help='also measure git revision REV, side by side')
    p.add_argument('--repeats', type=int, default=None, help='runs per measurement (median; default 3, quick 1)')
    p.add_argument('--global-n', help='swarm sizes of the global law, comma list (default: a sweep 6 … 4000)')
    p.add_argument('--local-n', help='swarm sizes of the local law, comma list (default: a sweep 6 … 30000)')
    p.add_argument('--no-runs', action='store_true', help='skip the full homotopy_global runs')
    p.add_argument('--reference', action='store_true',
                   help='also measure the reference numpy path (KD-tree / all pairs) at the sizes '
                        'where the engine takes compiled kernels')
    p.add_argument('--duration', type=float, help='length of the full runs (default: the scenario\'s, t = 1000)')
    p.add_argument('--radio-breakdown', action='store_true',
                   help='also the fast engine over radios that leave out one cost at a time (what bounds '
                        'the lossy radio against the perfect one)')
    p.add_argument('--dim', default='2', help='dimensions of the steps/s rows, a comma list of 2 and 3 '
                   '(default 2); with 3 the full runs are the 3D Fig. 3 run and the planar one')
    p.add_argument('--volume', action='store_true', help='with --dim 3: also 3D swarms on a cubic lattice')
    p.add_argument('--worker', help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.worker:
        worker(json.loads(a.worker))
        return 0
    sizes = {'global': [6, 24, 100, 300, 1000, 2000, 4000],
             'local': [6, 100, 1000, 3000, 10000, 30000]}
    if a.quick:
        sizes = {'global': [6, 100, 1000, 2000], 'local': [100, 1000, 10000]}
    for kind, arg in (('global', a.global_n), ('local', a.local_n)):
        if arg is not None:
            try:
                sizes[kind] = [int(v) for v in arg.split(',') if v.strip()]
            except ValueError:
                p.error(f'--{kind}-n: a comma list of integers, got {arg!r}')
    try:
        dims = sorted({int(v) for v in a.dim.split(',') if v.strip()})
    except ValueError:
        dims = None
    if not dims or not set(dims) <= {2, 3}:
        p.error(f'--dim: a comma list of 2 and 3, got {a.dim!r}')
    layouts = [(d, 'grid') for d in dims] + ([(3, 'cube')] if a.volume and 3 in dims else [])
    repeats = a.repeats or (1 if a.quick else 3)
    min_s = 0.5 if a.quick else 1.5
    specs = [dict(what='law', receivers=r, lam=lam, min_seconds=min_s)
             for r in ('one', 'all') for lam in (None, 0.0)]
    specs += [dict(what='agent', min_seconds=min_s)]
    specs += [sps_spec(kind, n, min_s, d, lay) for kind, ns in sizes.items() for n in ns for d, lay in layouts]
    if a.reference:
        from swarm_core.laws.paper.compiled_sums import COMPILED_LIMIT
        specs += [sps_spec(kind, n, min_s, d, lay, search='kdtree')
                  for kind, ns in sizes.items() for n in ns if n >= COMPILED_LIMIT for d, lay in layouts]
    if not a.no_runs and 3 in dims:       # Fig. 3 in 3D beside the planar run, the same steps
        specs += [dict(what='run', name=name, dt=0.1, duration=a.duration, engine='reference')
                  for name in ('homotopy_global', 'homotopy_3d')]
    if not a.no_runs and dims == [2]:
        specs += [dict(what='run', name='homotopy_global', dt=dt, duration=a.duration, engine=eng)
                  for dt in (0.05, 0.1) for eng in ('reference', 'fast')]
        specs += [dict(what='run', name='homotopy_global', dt=0.1, duration=a.duration, comms=dict(loss=0.5),
                       engine=eng) for eng in ('reference', 'fast')]
        if a.radio_breakdown:         # the radio's machinery with nothing lost, loss without dead reckoning, latency
            specs += [dict(what='run', name='homotopy_global', dt=0.1, duration=a.duration, comms=c, engine='fast')
                      for c in RADIO_BREAKDOWN]
        specs += [dict(what='start', cold=cold) for cold in (True, False)]
    res = dict(command='scripts/bench_core.py ' + ' '.join(sys.argv[1:] if argv is None else argv),
               load_before=loadavg(), cpus=os.cpu_count(), repeats=repeats, compare=a.compare,
               current={}, baseline={})
    with tempfile.TemporaryDirectory() as tmp:
        base_src = extract(a.compare, tmp) if a.compare else None
        base_fast = base_src is not None and (Path(base_src) / 'swarm_core' / 'fast.py').exists()
        runs = {spec_key(spec): {'current': [], 'baseline': []} for spec in specs}
        try:
            for _ in range(repeats):          # interleaved: every measurement once per round
                for spec in specs:            # the fast engine only where the baseline has one
                    key = spec_key(spec)
                    if base_src and (base_fast or (spec['what'] != 'start' and spec.get('engine') != 'fast')):
                        runs[key]['baseline'].append(run_worker(spec, base_src))
                    runs[key]['current'].append(run_worker(spec))
                    print(f'{key:28s} {json.dumps(runs[key]["current"][-1])}', file=sys.stderr, flush=True)
        except KeyboardInterrupt:
            print('interrupted: writing what was measured', file=sys.stderr)
        for spec in specs:
            key = spec_key(spec)
            for side, rr in runs[key].items():
                if not rr:
                    continue
                row = dict(spec, wall=statistics.median(r['wall'] for r in rr),
                           cpu=statistics.median(r['cpu'] for r in rr), runs=rr)
                if 'search' in rr[0]:
                    row['search'] = rr[0]['search']
                res[side][key] = row
    res['load_after'] = loadavg()

    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix('.json').write_text(json.dumps(res, indent=1))
    plot(res, out.with_suffix('.png'))
    print(table(res))
    return 0


#: radios of ``--radio-breakdown``: every message delivered at once (fates, beliefs and the law on
#: them), loss without dead reckoning, and loss with latency (messages in flight)
RADIO_BREAKDOWN = (dict(radio_range=1e9), dict(loss=0.5, dead_reckoning=False), dict(loss=0.5, latency=0.3))


def sps_spec(kind, n, min_seconds, dim=2, layout='grid', **more):
    """The spec of one steps/s measurement (planar ones as before: no dim key)."""
    spec = dict(what='sps', kind=kind, n=n, min_seconds=min_seconds, **more)
    return spec if dim == 2 else dict(spec, dim=dim, layout=layout)


def spec_key(spec):
    if spec['what'] == 'sps':
        where = '' if spec.get('dim', 2) == 2 else ' 3D' + (' cube' if spec.get('layout') == 'cube' else '')
        return f'{spec["kind"]} n={spec["n"]}{where}' + (' reference' if spec.get('search') == 'kdtree' else '')
    if spec['what'] == 'law':
        lam = 'λ=0.97' if spec['lam'] is None else f'λ={spec["lam"]:g}'
        return f'law {spec["receivers"]} {lam}'
    if spec['what'] == 'agent':
        return 'AgentCore.control'
    if spec['what'] == 'start':
        return 'fast import + ' + ('compile' if spec['cold'] else 'cached load')
    radio = ' ' + ', '.join(f'{k} {v:g}' for k, v in spec['comms'].items()) if spec.get('comms') else ''
    return f'{spec["name"]} dt={spec["dt"]}{radio} {spec.get("engine", "reference")}'


def table(res):
    cmp_ = bool(res['baseline'])
    lines = [f'load average (1, 5, 15 min): before {fmt_load(res["load_before"])}, '
             f'after {fmt_load(res["load_after"])}; {res["cpus"]} CPUs; median of {res["repeats"]} run(s)']

    def section(whats, head, base_head, label, digits, speed_up):
        """One Markdown table: the rows of kinds ``whats``, label cells, wall and CPU numbers,
        and with a baseline its numbers and ``speed_up(row, baseline row)``."""
        head += base_head if cmp_ else ''
        lines.extend(['', head, '|' + '---|' * (head.count('|') - 1)])
        for key, row in res['current'].items():
            if row['what'] not in whats:
                continue
            line = f'{label(key, row)} {row["wall"]:.{digits}f} | {row["cpu"]:.{digits}f} |'
            if cmp_ and key in res['baseline']:
                b = res['baseline'][key]
                line += f' {b["wall"]:.{digits}f} | {b["cpu"]:.{digits}f} | {speed_up(row, b)} |'
            lines.append(line)

    def call_label(key, row):
        if row['what'] == 'agent':
            return '| `AgentCore.control`: an agent\'s table + its own u, λ ≈ 0.97 |'
        who = 'one receiver (an agent)' if row['receivers'] == 'one' else 'all 6 receivers (batch)'
        lam = 'λ ≈ 0.97, two leaders' if row['lam'] is None else f'λ = {row["lam"]:g}'
        return f'| {who}, {lam} |'

    section(('sps',), '| law | n | space | pair search | steps/s | steps/s per CPU s |',
            f' before ({res["compare"]}) steps/s | before, per CPU s | speed-up (wall) |',
            lambda key, row: f'| {row["kind"]} | {row["n"]} | {space(row)} | {row.get("search", "")} |', 1,
            lambda row, b: f'{row["wall"] / b["wall"]:.1f}×')
    lines.extend(dim_ratios(res))
    section(('run',), '| run (engine) | steps | wall (s) | CPU (s) |',
            ' before: wall (s) | before: CPU (s) | speed-up (CPU) |',
            lambda key, row: f'| {key} to t = {row.get("duration") or 1000:g} | '
                             f'{int(round((row.get("duration") or 1000) / row["dt"]))} |', 4,
            lambda row, b: f'{b["cpu"] / row["cpu"]:.2f}×')
    lines.extend(radio_ratios(res))
    section(('start',), '| fast engine start-up (per process) | wall (s) | CPU (s) |',
            ' before: wall (s) | before: CPU (s) | speed-up (CPU) |',
            lambda key, row: f'| {key} |', 2, lambda row, b: f'{b["cpu"] / row["cpu"]:.2f}×')
    section(('law', 'agent'), '| one call, n = 6 (homotopy_global states at t = 450) | µs/call | µs CPU/call |',
            ' before: µs/call | before: µs CPU/call | speed-up (CPU) |', call_label, 1,
            lambda row, b: f'{b["cpu"] / row["cpu"]:.2f}×')
    return '\n'.join(lines)


def space(row):
    """2D, 3D (the planar grid, headings in a cap) or 3D cube."""
    return f'{row.get("dim", 2)}D' + (' cube' if row.get('layout') == 'cube' else '')


def dim_ratios(res):
    """Lines of 3D against 2D, measured side by side: steps/s of each swarm (3D / 2D) and the
    CPU of the 3D Fig. 3 run over the planar one (homotopy_3d / homotopy_global, same steps)."""
    cur, out = res['current'], []
    for key, row in cur.items():
        twin = cur.get(f'{row.get("kind")} n={row.get("n")}' + (' reference' if row.get('search') == 'kdtree' else ''))
        if row['what'] == 'sps' and row.get('dim') == 3 and twin is not None:
            out.append(f'{key}: {row["wall"] / twin["wall"]:.2f}× the planar steps/s (wall), '
                       f'{row["cpu"] / twin["cpu"]:.2f}× per CPU s')
    for side, who in (('current', ''), ('baseline', f' (before, {res["compare"]})')):
        runs = {r['name']: r for r in res[side].values() if r['what'] == 'run' and r.get('engine') == 'reference'
                and r['dt'] == 0.1 and not r.get('comms')}
        if {'homotopy_3d', 'homotopy_global'} <= set(runs):
            per = [b['cpu'] / a['cpu'] for a, b in zip(runs['homotopy_global']['runs'], runs['homotopy_3d']['runs'])]
            out.append(f'Fig. 3 run{who}, 3D / 2D CPU (homotopy_3d / homotopy_global, dt = 0.1): median '
                       f'{runs["homotopy_3d"]["cpu"] / runs["homotopy_global"]["cpu"]:.2f}×, per round '
                       + ', '.join(f'{r:.2f}' for r in per))
    return ['', *out] if out else []


def radio_ratios(res):
    """Lines of the CPU ratios of the runs over the lossy radio (``comms.loss`` 0.5) against the
    same runs over the perfect one and on the other engine (of the baseline too where it has
    the fast engine)."""
    out = []
    for side, who in (('current', ''), ('baseline', f' (before, {res["compare"]})')):
        runs = {(r['dt'], r.get('engine', 'reference'), bool(r.get('comms'))): r['cpu']
                for r in res[side].values() if r['what'] == 'run' and r.get('comms') in (None, dict(loss=0.5))}
        for dt in sorted({k[0] for k in runs}):
            got = {k[1:]: v for k, v in runs.items() if k[0] == dt}
            if not {('fast', True), ('fast', False), ('reference', True)} <= set(got):
                continue
            line = (f'loss 0.5 at dt = {dt:g}{who}, CPU ratios: fast radio / fast perfect radio '
                    f'{got["fast", True] / got["fast", False]:.2f}; fast radio / reference radio '
                    f'{got["fast", True] / got["reference", True]:.4f}')
            if ('reference', False) in got:
                line += ('; reference radio / reference perfect radio '
                         f'{got["reference", True] / got["reference", False]:.2f}')
            out += ['', line]
    return out


def fmt_load(la):
    return 'n/a' if la is None else ', '.join(f'{x:.1f}' for x in la)


def plot(res, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    labels = {'global': 'global law (all pairs)', 'local': 'local law, λ = 1 (KD-tree within w)'}
    for side, style in (('current', 'o-'), ('baseline', 'o--')):
        for i, (kind, where) in enumerate((k, w) for k in ('global', 'local') for w in ('2D', '3D', '3D cube')):
            rows = [r for r in res[side].values() if r['what'] == 'sps' and r['kind'] == kind and space(r) == where]
            if not rows:
                continue
            label = labels[kind] + ('' if where == '2D' else f', {where}') + \
                ('' if side == 'current' else f' — before ({res["compare"]})')
            ax.loglog([r['n'] for r in rows], [r['wall'] for r in rows], style, color=f'C{i}',
                      alpha=1.0 if side == 'current' else 0.5, label=label)
    ax.axhline(10, color='k', ls=':', lw=1, label='10 steps/s')
    ax.set_xlabel('agents n')
    ax.set_ylabel('steps per second (wall)')
    ax.set_title(f'batch engine throughput (one process; load average {fmt_load(res["load_before"])})', fontsize=9)
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)


if __name__ == '__main__':
    sys.exit(main())
