"""``swarm drop`` and ``swarm partition``: change the radio of a running swarm.

Both publish one event on ``/swarm/events`` (std_msgs/String JSON, see swarm_ros.protocol;
reliable + transient-local, so ``swarm record`` keeps it in the bag), stamped with the sim time
read from ``/clock``.  Every agent applies it on its receive side (swarm_core.comms) from the
step it is at when the event arrives:

    swarm drop 0.3 --for 5        burst loss: every message lost with probability 0.3 for 5 sim s
    swarm drop 0                  end a burst
    swarm partition agent_0,agent_1,agent_2 agent_3,agent_4,agent_5
                                  groups that cannot hear each other (agents named in no group
                                  form one more group)
    swarm partition --heal        one group again

In lockstep runs the step at which agents apply a runtime event depends on when it arrives;
for a reproducible run put the change in the scenario's ``comms.events``.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

from swarm_ros.cliutil import add_wait


def _agents_in_graph(node):
    """Agent names of the running swarm (nodes ``/<name>/agent``)."""
    return sorted(ns.strip('/') for nm, ns in node.get_node_names_and_namespaces()
                  if nm == 'agent' and ns.strip('/'))


def publish_event(kind: str, fields: dict, wait: float, check_names=(), prog='swarm'):
    """Publish one event once the swarm is found; returns an exit code (messages printed)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.duration import Duration
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String

    from swarm_ros import protocol as P
    ctx = Context()
    rclpy.init(context=ctx)
    node = ex = None
    try:
        node = rclpy.create_node('swarm_cli_events', context=ctx, start_parameter_services=False)
        clock = {}
        node.create_subscription(Clock, P.CLOCK, lambda m: clock.__setitem__('t', P.stamp_to_time(m.clock)), 10)
        pub = node.create_publisher(String, P.EVENTS, P.qos_latched(100))
        from swarm_ros.runinfo import RunWatch, describe, one_run
        watch = RunWatch(node)
        from rclpy.executors import SingleThreadedExecutor
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        end = time.monotonic() + wait
        agents = []
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
            agents = _agents_in_graph(node)
            if agents and pub.get_subscription_count() > 0:
                break
        if not agents or pub.get_subscription_count() == 0:
            print(f'{prog}: no running swarm found (no agent subscribes {P.EVENTS}); '
                  "is ROS_DOMAIN_ID the same as the run's?", file=sys.stderr)
            return 1
        # let the other agents match too: until the count has not grown for 0.5 s (≤ 3 s)
        count, stable, limit = pub.get_subscription_count(), time.monotonic(), time.monotonic() + 3.0
        while time.monotonic() - stable < 0.5 and time.monotonic() < limit:
            ex.spin_once(timeout_sec=0.05)
            if pub.get_subscription_count() != count:
                count, stable = pub.get_subscription_count(), time.monotonic()
        # the graph's node names lag the matched readers (and an agent resumed after `swarm
        # pause` is rediscovered late): wait for every named agent, and for the sim time,
        # until --wait is up (at least 3 s more), before calling a name unknown
        limit = max(end, time.monotonic() + 3.0)
        while time.monotonic() < limit:
            unknown = [nm for nm in check_names if nm not in _agents_in_graph(node)]
            if not unknown and 't' in clock:
                break
            ex.spin_once(timeout_sec=0.05)
        from swarm_ros.runinfo import has_world      # the run's announcement(s), if a world is there
        limit = time.monotonic() + (0.5 if watch.runs else 2.0 if has_world(node) else 0.0)
        while time.monotonic() < limit:
            ex.spin_once(timeout_sec=0.05)
        run, err = one_run(watch.runs, prog)
        if err:
            print(err, file=sys.stderr)
            return 1
        print(f'{prog}: reached {describe(run)}' if run else
              f'{prog}: reached a swarm that does not announce a run on {P.RUN}', flush=True)
        unknown = [nm for nm in check_names if nm not in _agents_in_graph(node)]
        if unknown:
            print(f'{prog}: unknown agent {unknown[0]!r} (running: {", ".join(_agents_in_graph(node))})',
                  file=sys.stderr)
            return 2
        t = clock.get('t')
        pub.publish(String(data=P.event_json(kind, t, **fields)))
        pub.wait_for_all_acked(Duration(seconds=2.0))
        print(f'{prog}: {kind} {fields} at t={"?" if t is None else f"{t:.2f}"} '
              f'(sent to {pub.get_subscription_count()} readers of {P.EVENTS})')
        return 0
    finally:        # on every path (an early return left the executor to a GC after shutdown:
        if ex is not None:      # "Exception ignored in Executor.__del__ ... InvalidHandle")
            ex.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def drop_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm drop', description=(
        'Burst packet loss in a running swarm: every state message is lost with probability P '
        '(on top of the configured loss), for --for sim seconds or until the next `swarm drop`.'))
    p.add_argument('loss', type=float, help='loss probability P in [0, 1] (0 ends a burst)')
    p.add_argument('--for', dest='duration', type=float, help='duration in sim seconds (default: until changed)')
    add_wait(p, 'the swarm')
    a = p.parse_args(argv)
    if not (math.isfinite(a.loss) and 0.0 <= a.loss <= 1.0):
        print(f'swarm drop: loss {a.loss!r} rejected: must be in [0, 1]', file=sys.stderr)
        return 2
    if a.duration is not None and not (math.isfinite(a.duration) and a.duration > 0.0):
        print(f'swarm drop: --for {a.duration!r} rejected: must be a positive number of sim seconds',
              file=sys.stderr)
        return 2
    return publish_event('drop', dict(loss=a.loss, duration=a.duration), a.wait, prog='swarm drop')


def partition_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm partition', description=(
        'Partition a running swarm into groups that cannot hear each other '
        '(agents named in no group form one more group), or heal it.'))
    p.add_argument('groups', nargs='*', help='groups of agent names, comma-separated, e.g. agent_0,agent_1 agent_2')
    p.add_argument('--heal', action='store_true', help='remove the partition')
    add_wait(p, 'the swarm')
    a = p.parse_args(argv)
    if a.heal == bool(a.groups):
        print('swarm partition: give groups (a,b,c d,e) or --heal, not both / neither', file=sys.stderr)
        return 2
    groups = [[s.strip() for s in g.split(',') if s.strip()] for g in a.groups]
    names = [nm for g in groups for nm in g]
    if any(not g for g in groups):
        print('swarm partition: an empty group', file=sys.stderr)
        return 2
    if len(set(names)) != len(names):
        dup = next(nm for nm in names if names.count(nm) > 1)
        print(f'swarm partition: {dup!r} is in more than one group', file=sys.stderr)
        return 2
    return publish_event('partition', dict(groups=groups), a.wait, check_names=names, prog='swarm partition')
