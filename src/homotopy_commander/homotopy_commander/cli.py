"""``swarm lambda`` and ``swarm steer``: set λ or a leader's steering in a running swarm.

``swarm lambda 1.0 --ramp 20`` publishes ``[1.0, 20]`` on ``/commander/lambda_setpoint``: the
commander ramps λ smoothly from its current value to 1.0 over 20 sim seconds, from the next
step it decides.  Without a commander (none subscribed within --wait seconds) it publishes the
value on ``/swarm/lambda``, as ``ros2 topic pub --once /swarm/lambda std_msgs/msg/Float64
"{data: 1.0}"`` does (a running commander takes that as a set-point with its ``ramp``
parameter, 20 s by default; docs/commands.md).
``swarm steer agent_0 0.01`` publishes 0.01 on ``/agent_0/steering`` (as ``ros2 topic pub``
would): the commander makes it that leader's constant steering program (the agent becomes a
leader if it was not); a realtime agent applies it at once.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

from swarm_ros.cliutil import add_wait

SETPOINT = '/commander/lambda_setpoint'


class RunRefused(Exception):
    """The live verb must not act (two runs on the domain, an agent the run does not have)."""


def _publish_once(msg_type, topic, msg, wait, qos_depth=10, for_node=None, prog=None, agent=None):
    """Publish one message once a subscriber has matched (up to ``wait`` s); True if matched.

    ``for_node``: the node the message is for (e.g. 'commander'): wait until a subscription of
    that node is in the graph too, not just any (a recorder may match first), then publish and
    wait for the acknowledgements.  ``prog``: also read the run's ``/swarm/run`` announcement
    (swarm_ros.runinfo) and say which run was reached; raise `RunRefused` (nothing is sent)
    if two runs share the domain or ``agent`` is not one of the run's agents."""
    import rclpy
    from rclpy.context import Context
    from rclpy.duration import Duration
    from rclpy.executors import SingleThreadedExecutor

    from swarm_ros import runinfo
    ctx = Context()
    rclpy.init(context=ctx)
    ex = node = None
    try:
        node = rclpy.create_node('swarm_cli', context=ctx, start_parameter_services=False)
        pub = node.create_publisher(msg_type, topic, qos_depth)
        watch = runinfo.RunWatch(node) if prog else None
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)

        def ready():
            if pub.get_subscription_count() == 0:
                return False
            return for_node is None or any(
                i.node_name == for_node for i in node.get_subscriptions_info_by_topic(topic))

        end = time.monotonic() + wait
        while not ready() and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        if pub.get_subscription_count() == 0:
            return False
        settle = time.monotonic() + 0.2          # let the subscribers' side of the match settle
        if watch is not None:                    # ... and hear the run (every run on the domain)
            limit = time.monotonic() + (2.0 if runinfo.has_world(node) else 0.0)
            while not watch.runs and time.monotonic() < limit:
                ex.spin_once(timeout_sec=0.05)
            if watch.runs:                       # a second run's announcement may come just after
                settle = time.monotonic() + 0.5
        while time.monotonic() < settle:
            ex.spin_once(timeout_sec=0.05)
        if watch is not None:
            run, err = runinfo.one_run(watch.runs, prog)
            err = err or (runinfo.unknown_agent(run, agent, prog) if agent else None)
            if err:
                raise RunRefused(err)
            print(f'{prog}: reached {runinfo.describe(run)}' if run else
                  f'{prog}: reached a swarm that does not announce a run on /swarm/run', flush=True)
        pub.publish(msg)
        pub.wait_for_all_acked(Duration(seconds=2.0))
        return True
    finally:
        if ex is not None:
            ex.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def lambda_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm lambda', description=(
        'Set the homotopy parameter λ of a running swarm: the commander ramps smoothly to it.'))
    p.add_argument('value', type=float, help='λ in [0, 1]')
    p.add_argument('--ramp', type=float, default=20.0, help='ramp duration in sim seconds (default 20; 0 = jump)')
    add_wait(p, 'the swarm')
    a = p.parse_args(argv)
    if not (math.isfinite(a.value) and 0.0 <= a.value <= 1.0):
        print(f'swarm lambda: λ={a.value!r} rejected: must be finite and in [0, 1]', file=sys.stderr)
        return 2
    if not (math.isfinite(a.ramp) and a.ramp >= 0.0):
        print(f'swarm lambda: --ramp {a.ramp!r} rejected: must be finite and ≥ 0', file=sys.stderr)
        return 2
    from std_msgs.msg import Float64, Float64MultiArray
    try:
        if _publish_once(Float64MultiArray, SETPOINT, Float64MultiArray(data=[a.value, a.ramp]), a.wait,
                         for_node='commander', prog='swarm lambda'):
            print(f'swarm lambda: set-point λ={a.value:g}, ramp {a.ramp:g} s (sent to the commander)')
            return 0
    except RunRefused as err:
        print(err, file=sys.stderr)
        return 1
    if _publish_once(Float64, '/swarm/lambda', Float64(data=a.value), 1.0):
        print(f'swarm lambda: no commander found; published λ={a.value:g} on /swarm/lambda')
        return 0
    print('swarm lambda: no running swarm found (nothing subscribes /swarm/lambda); '
          'is ROS_DOMAIN_ID the same as the run\'s?', file=sys.stderr)
    return 1


def steer_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm steer', description=(
        "Set a leader's steering program (a constant curvature s_k) in a running swarm."))
    p.add_argument('agent', help='agent name, e.g. agent_0')
    p.add_argument('value', type=float, help='curvature s_k (finite; + turns anticlockwise)')
    add_wait(p, 'the agent')
    a = p.parse_args(argv)
    if not math.isfinite(a.value):
        print(f'swarm steer: steering {a.value!r} rejected: not finite', file=sys.stderr)
        return 2
    name = a.agent.strip('/')
    if not name or '/' in name or not name.replace('_', 'a').isalnum():
        print(f'swarm steer: {a.agent!r} is not an agent name', file=sys.stderr)
        return 2
    from std_msgs.msg import Float64
    try:
        if _publish_once(Float64, f'/{name}/steering', Float64(data=a.value), a.wait, for_node='commander',
                         prog='swarm steer', agent=name):
            print(f'swarm steer: {name} steering {a.value:g}')
            return 0
    except RunRefused as err:
        print(err, file=sys.stderr)
        return 2 if 'unknown agent' in str(err) else 1
    print(f'swarm steer: unknown agent {name!r}: nothing subscribes /{name}/steering', file=sys.stderr)
    return 1
