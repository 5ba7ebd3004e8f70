#!/usr/bin/env python3
"""The Python work of one lockstep step, in one process, without DDS delivering anything: what a
lone agent does with one ``/lockstep/step`` message (decode, the law, one move, its answer and
its state; ``agent-compiled``: with the compiled step of ``--compiled on``), and what the world
does with the answers of ``n`` lone agents (decode, checks, the
barrier, the plan's decision, the next step message, the metrics).

The messages are made up front (`homotopy_global`, the agents a little further each step) and
handed to the node's own callbacks (``driver.on_input``, ``driver.on_agent_states``); the nodes
publish as in a run, to no reader.  Each case runs in a process of its own, ``--rounds`` times
``--steps`` steps after a warm-up; the figure is the fastest round's time per step (the
machine is shared: the fastest round is the one least disturbed).

``--src LABEL=DIR`` (repeatable) measures a checkout's ``src`` (its packages put first on
``PYTHONPATH``) beside this one's, the cases interleaved, so that before/after share the load.
Compare these figures with the CPU per step of a real run (`bench_ros.py`): the difference is
the executor, DDS, and the same code run with cold caches among eight processes on the cores.

    .venv/bin/python scripts/bench_step_work.py --src base=/tmp/old/src --out bench/step_work.json
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ('swarm_core', 'swarm_ros', 'swarm_agent', 'swarm_world', 'homotopy_commander', 'swarm_tools',
            'swarm_robots')
KINDS = ('agent', 'agent-compiled', 'world')


def child(kind: str, steps: int, rounds: int, domain: int) -> dict:
    """One case in this process: the fastest round's µs per step."""
    import numpy as np
    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter

    from swarm_core.scenario.loader import load
    from swarm_ros.layouts import AgentStates, Step
    from swarm_tools.run.params import agent_parameters, node_parameters

    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain)
    scn = load('homotopy_global')
    n = len(scn.names)
    qz, qw = np.sin(scn.theta0 / 2), np.cos(scn.theta0 / 2)
    total = 200 + rounds * steps
    if kind.startswith('agent'):
        from swarm_agent.agent_node import AgentNode
        sums = 'compiled' if kind == 'agent-compiled' else 'numpy'      # `swarm run --compiled on` / off
        prm = dict(agent_parameters(scn, 0, 'lockstep', sums), use_sim_time=False)
        node = AgentNode('agent', namespace='agent_0', context=ctx,
                         parameter_overrides=[Parameter(k, value=v) for k, v in prm.items()])
        msgs = [Step(k, k * scn.dt, 0.0, np.zeros(n, bool), np.zeros(n), scn.pos0[:, 0] + 0.01 * k, scn.pos0[:, 1],
                     qz, qw, np.zeros(n), np.ones(n, bool), None, None, None).to_cdr(node.run_id)
                for k in range(total)]

        def run(a, b):
            for k in range(a, b):
                node.driver.on_input(msgs[k])
    else:
        from swarm_world.world_node import WorldNode
        prm = node_parameters(scn, 'homotopy_global', 'lockstep', duration=(total + 10) * scn.dt)['/world']
        node = WorldNode(context=ctx, parameter_overrides=[Parameter(k, value=v) for k, v in prm.items()],
                         log=lambda *a, **k: None)
        lock = node.driver.lock

        def answers(k):
            return [AgentStates(float(i + 1), [i], [k], np.array([[scn.pos0[i, 0] + 0.01 * k], [scn.pos0[i, 1]],
                                                                   [qz[i]], [qw[i]]]), [0.0]).to_cdr(node.run_id)
                    for i in range(n)]
        msgs = [answers(k) for k in range(total + 1)]
        for m in msgs[0]:
            node.driver.on_agent_states(m)
        node.carry_out(lock.start())            # step 0 held: the world goes (as its start watch would)

        def run(a, b):
            for k in range(a + 1, b + 1):
                for m in msgs[k]:
                    node.driver.on_agent_states(m)
            if lock.cur != b + 1:
                raise SystemExit(f'the world is at step {lock.cur}, not {b + 1}: an answer was refused')
    run(0, 200)
    best = []
    for r in range(rounds):
        a = 200 + r * steps
        t = time.perf_counter()
        run(a, a + steps)
        best.append((time.perf_counter() - t) / steps * 1e6)
    node.destroy_node()
    rclpy.shutdown(context=ctx)
    return dict(kind=kind, agents=n, us_per_step=round(min(best), 1), rounds_us=[round(v, 1) for v in best])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0], epilog=__doc__.split('\n\n', 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--src', action='append', default=[], metavar='LABEL=DIR',
                    help="another checkout's src directory to measure beside this one (repeatable)")
    ap.add_argument('--steps', type=int, default=600, help='steps per round (default 600)')
    ap.add_argument('--rounds', type=int, default=3, help='rounds per case; the fastest counts (default 3)')
    ap.add_argument('--repeat', type=int, default=2, help='times each case runs, interleaved (default 2)')
    ap.add_argument('--out', default='bench/step_work.json', help='results JSON (default bench/step_work.json)')
    ap.add_argument('--child', choices=KINDS, help=argparse.SUPPRESS)
    ap.add_argument('--domain', type=int, default=0, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.steps < 1 or a.rounds < 1 or a.repeat < 1:
        ap.error('--steps, --rounds and --repeat must be at least 1')
    if a.child:
        print(json.dumps(child(a.child, a.steps, a.rounds, a.domain)))
        return 0
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_ros as B
    trees = [('this', ROOT / 'src')]
    for spec in a.src:
        label, _, path = spec.partition('=')
        if not label or not Path(path, 'swarm_core').is_dir():
            ap.error(f'--src {spec!r}: want LABEL=DIR, DIR a src directory with swarm_core in it')
        trees.append((label, Path(path).resolve()))
    dom, _lock = B.claim_domain()
    results = dict(command=' '.join(['bench_step_work.py'] + (sys.argv[1:] if argv is None else argv)),
                   date=time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()), cpus=os.cpu_count(),
                   load_start=B.loadavg(), runs=[])
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    for rep in range(a.repeat):
        for kind in KINDS:
            for label, src in trees:
                env = dict(os.environ, PYTHONPATH=os.pathsep.join(
                    [str(src / p) for p in PACKAGES] + [os.environ.get('PYTHONPATH', '')]).rstrip(os.pathsep))
                p = subprocess.run([sys.executable, __file__, '--child', kind, '--steps', str(a.steps),
                                    '--rounds', str(a.rounds), '--domain', str(dom)],
                                   env=env, capture_output=True, text=True, timeout=600)
                if p.returncode != 0:
                    print(f'  [{label}] {kind}: failed ({p.returncode}): {p.stderr.strip()[-400:]}', flush=True)
                    continue
                r = dict(json.loads(p.stdout.strip().splitlines()[-1]), label=label, repeat=rep)
                results['runs'].append(r)
                print(f"  [{label}] {kind}: {r['us_per_step']} µs per step (rounds {r['rounds_us']})", flush=True)
                out.write_text(json.dumps(results, indent=1))
    results['load_end'] = B.loadavg()
    out.write_text(json.dumps(results, indent=1))
    print(f'bench_step_work: wrote {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
