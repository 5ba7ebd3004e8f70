#!/usr/bin/env python3
"""Benchmark of the commander's watch for command writers (``CommanderNode._watch_commands``).

For each agent count n, in this one process (discovery off: ROS_AUTOMATIC_DISCOVERY_RANGE=OFF
and a ROS_DOMAIN_ID of its own, claimed as scripts/bench_ros.py does), the script builds a
CommanderNode for `homotopy_global` with n agents (the scenario file of bench_ros.py) and n
stand-in agent nodes (``/agent_k/agent``, nothing else) so that the node list is as long as
in a run.  Then it times ticks of ``_watch_commands``, interleaved in rounds:

- before: every command topic every tick (the commander's `CommandWatch` with a slice of n:
  what the commander did before, plus the node-list query, timed alone as ``nodes``);
- after: the commander's own `CommandWatch` (λ, set-point, every steering topic up to 64
  agents, else 4 a tick in turn, and the topics of nodes that appeared in the last 2 s).
Both include the node-list query of each tick.

Per tick: wall ms and this thread's CPU ms (the graph queries run in the calling thread).
Then the delay until a new writer gets its reader: of a new node (asked for its topics: next tick)
and of a node already in the graph (the turns: at most n/4 ticks), in ticks of 0.05 s.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_ros import claim_domain, loadavg, scenario_file


def agent_counts(text):
    try:
        out = [int(x) for x in text.split(',') if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r}: want comma-separated integers, e.g. 6,96,1000') from None
    if not out or min(out) < 1:
        raise argparse.ArgumentTypeError(f'{text!r}: want agent counts of at least 1')
    return out


def timed(fn, ticks):
    """(wall ms, CPU ms) per call of fn, each a list over `ticks` calls."""
    wall, cpu = [], []
    for _ in range(ticks):
        w0, c0 = time.perf_counter(), time.thread_time()
        fn()
        cpu.append((time.thread_time() - c0) * 1e3)
        wall.append((time.perf_counter() - w0) * 1e3)
    return wall, cpu


def ticks_until(node, cond, limit=400):
    """Ticks of node._watch_commands (0.05 s apart, as its timer) until cond() holds."""
    from homotopy_commander.commander_node import COMMAND_POLL
    for k in range(1, limit + 1):
        node._watch_commands()
        if cond():
            return k
        time.sleep(COMMAND_POLL)
    return None


def measure(n, dom, ticks, rounds, tmp):
    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter
    from std_msgs.msg import Float64

    from homotopy_commander.command_watch import NEW_NODE_LOOK, CommandWatch
    from homotopy_commander.commander_node import SETPOINT, CommanderNode
    from swarm_ros import protocol as P

    ctx = Context()
    rclpy.init(context=ctx, domain_id=dom)
    nodes = []
    try:
        path = scenario_file(n, 100, tmp)
        cmd = CommanderNode(context=ctx, parameter_overrides=[Parameter('scenario', value=str(path)),
                                                              Parameter('mode', value='lockstep')])
        nodes.append(cmd)
        bare = dict(context=ctx, start_parameter_services=False, enable_rosout=False,
                    parameter_overrides=[Parameter('start_type_description_service', value=False)])
        nodes += [rclpy.create_node('agent', namespace=f'/{nm}', **bare) for nm in cmd.names]
        writer = rclpy.create_node('bench_writer', **bare)      # a node already in the graph
        nodes.append(writer)
        cmd._watch_commands()
        time.sleep(NEW_NODE_LOOK + 0.2)                             # past the window of the start
        after = cmd.watch
        before = CommandWatch([P.LAMBDA, SETPOINT], cmd.names, per_tick=n, turn=n, ours=cmd.watch.ours)
        before.nodes_seen(0.0, cmd.get_node_names_and_namespaces())
        res = {'n': n, 'before': ([], []), 'after': ([], []), 'load': loadavg()}
        for watch in (before, after):                           # warm up, untimed
            cmd.watch = watch
            timed(cmd._watch_commands, 3)
        for _ in range(rounds):
            for label, watch in (('before', before), ('after', after)):
                cmd.watch = watch
                w, c = timed(cmd._watch_commands, ticks)
                res[label][0].extend(w)
                res[label][1].extend(c)
        cmd.watch = after
        res['nodes'] = timed(cmd.get_node_names_and_namespaces, ticks)
        res['per_tick'] = {k: len(v.pick(1e12)) for k, v in (('before', before), ('after', after))}
        # the delay until a new writer has its reader: a new node, then a node already there
        last = cmd.names[-1]
        tool = rclpy.create_node('bench_tool', **bare)
        nodes.append(tool)
        pub = tool.create_publisher(Float64, P.steering_topic(last), P.qos_reliable())
        res['new_node_ticks'] = ticks_until(cmd, lambda: cmd.commands[last].sub is not None)
        tool.destroy_publisher(pub)
        res['dropped_ticks'] = ticks_until(cmd, lambda: cmd.commands[last].sub is None)
        time.sleep(NEW_NODE_LOOK + 0.2)
        far = cmd.names[(after.cursor + len(cmd.names) - 1) % len(cmd.names)]   # the last in turn
        pub = writer.create_publisher(Float64, P.steering_topic(far), P.qos_reliable())
        res['old_node_ticks'] = ticks_until(cmd, lambda: cmd.commands[far].sub is not None)
        res['period'] = after.period()
        return res
    finally:
        for nd in nodes:
            nd.destroy_node()
        rclpy.shutdown(context=ctx)


def summary(r):
    def ms(label, i):
        return statistics.mean(r[label][i])
    return {'n': r['n'], 'topics before/after': f"{r['per_tick']['before']}/{r['per_tick']['after']}",
            'before wall/cpu ms': f"{ms('before', 0):.2f}/{ms('before', 1):.2f}",
            'after wall/cpu ms': f"{ms('after', 0):.2f}/{ms('after', 1):.2f}",
            'cpu ratio': f"{ms('before', 1) / max(ms('after', 1), 1e-9):.1f}",
            'node list ms': f"{statistics.mean(r['nodes'][1]):.3f}",
            'reader after (ticks): new node / old node':
                f"{r['new_node_ticks']} / {r['old_node_ticks']} (≤ {r['period']})",
            'load': r['load']}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0], epilog=__doc__.split('\n\n', 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--agents', type=agent_counts, default=[6, 96, 1000], help='agent counts (default 6,96,1000)')
    ap.add_argument('--ticks', type=int, default=20, help='ticks timed per round and variant (default 20)')
    ap.add_argument('--rounds', type=int, default=5, help='rounds of before, after (default 5)')
    ap.add_argument('--out', type=Path, help='also write the raw numbers to this JSON file')
    a = ap.parse_args(argv)
    if a.ticks < 1 or a.rounds < 1:
        ap.error('--ticks and --rounds must be at least 1')
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'
    os.environ.pop('ROS_STATIC_PEERS', None)
    dom, lock = claim_domain(91)
    rows = []
    try:
        with tempfile.TemporaryDirectory(prefix='bench_watch_') as tmp:
            for n in a.agents:
                r = measure(n, dom, a.ticks, a.rounds, Path(tmp))
                rows.append(r)
                print(json.dumps(summary(r), ensure_ascii=False), flush=True)
    except KeyboardInterrupt:
        print('interrupted: numbers so far above', file=sys.stderr)
    finally:
        lock.close()
    if rows:
        keys = list(summary(rows[0]))
        print('\n| ' + ' | '.join(keys) + ' |\n|' + '---|' * len(keys))
        for r in rows:
            print('| ' + ' | '.join(str(v) for v in summary(r).values()) + ' |')
    if a.out and rows:
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
