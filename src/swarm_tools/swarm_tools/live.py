"""The live verbs: change a running swarm from the shell.

``swarm lambda`` and ``swarm steer`` (the commander's inputs)
    ``swarm lambda 1.0 --ramp 20`` publishes ``[1.0, 20]`` on ``/commander/lambda_setpoint``:
    the commander ramps λ smoothly from its current value to 1.0 over 20 sim seconds, from the
    next step it decides.  Without a commander (none subscribed within --wait seconds) it
    publishes the value on ``/swarm/lambda``, as ``ros2 topic pub --once /swarm/lambda
    std_msgs/msg/Float64 "{data: 1.0}"`` does (a running commander takes that as a set-point
    with its ``ramp`` parameter; docs/commands.md).  ``swarm steer agent_0 0.01`` publishes 0.01
    on ``/agent_0/steering`` (as ``ros2 topic pub`` would): the commander makes it that
    leader's constant steering program (the agent becomes a leader if it was not).

``swarm kill AGENT`` and ``swarm pause AGENT SECONDS`` (faults; docs/faults.md)
    A JSON request on ``/swarm/fault_request``; the world applies it at its next step: the
    agent leaves every table (killed for good, or frozen for SECONDS of sim time, then back with
    the state it had), the event goes out on ``/swarm/events``, and in a ``swarm run
    --processes`` run the world also signals the agent's process.

``swarm drop`` and ``swarm partition`` (the radio; docs/comms.md)
    One event on ``/swarm/events``, stamped with the sim time read from ``/clock``; every agent
    applies it on its receive side from the step it is at when the event arrives::

        swarm drop 0.3 --for 5        burst loss 0.3 on every link for 5 sim s
        swarm drop 0                  end a burst
        swarm partition agent_0,agent_1,agent_2 agent_3,agent_4,agent_5
        swarm partition --heal        one group again

    In lockstep runs the step at which agents apply a runtime radio event depends on when it
    arrives; for a reproducible run put the change in the scenario's ``comms.events``.

Every verb first reads the run's ``/swarm/run`` announcement, says which run it reached, and
refuses (exit 1) when two runs share the domain, or (exit 2) for an agent the run does not have.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time

from swarm_core.inputs import LAMBDA_BOUND, PAUSE_BOUND, RAMP_BOUND, STEERING_BOUND
from swarm_ros import protocol as P
from swarm_ros.cliutil import add_wait, cli_node

SETPOINT = P.LAMBDA_SETPOINT


# ---------------------------------------------------------------- λ and steering
class RunRefused(Exception):
    """The live verb must not act (two runs on the domain, an agent the run does not have)."""


def _publish_once(msg_type, topic, msg, wait, qos_depth=10, for_node=None, prog=None, agent=None):
    """Publish one message once a subscriber has matched (up to ``wait`` s); True if matched.

    ``for_node``: the node the message is for (e.g. 'commander'): wait until a subscription of
    that node is in the graph too, not just any (a recorder may match first), then publish and
    wait for the acknowledgements.  ``prog``: also read the run's ``/swarm/run`` announcement
    (swarm_ros.runinfo) and say which run was reached; raise `RunRefused` (nothing is sent)
    if two runs share the domain or ``agent`` is not one of the run's agents."""
    from rclpy.duration import Duration

    from swarm_ros import runinfo
    with cli_node('swarm_cli') as (node, ex):
        pub = node.create_publisher(msg_type, topic, qos_depth)
        watch = runinfo.RunWatch(node) if prog else None

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
        while time.monotonic() < settle:
            ex.spin_once(timeout_sec=0.05)
        if watch is not None:                    # ... and hear every run on the domain
            run, err = watch.decide(ex, prog, agent)
            if err:
                raise RunRefused(err)
            print(f'{prog}: reached {runinfo.describe(run)}' if run else
                  f'{prog}: reached a swarm that does not announce a run on /swarm/run', flush=True)
        pub.publish(msg)
        pub.wait_for_all_acked(Duration(seconds=2.0))
        return True


def lambda_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm lambda', description=(
        'Set the homotopy parameter λ of a running swarm: the commander ramps smoothly to it.'))
    p.add_argument('value', type=float, help='λ in [0, 1]')
    p.add_argument('--ramp', type=float, default=20.0, help='ramp duration in sim seconds (default 20; 0 = jump)')
    add_wait(p, 'the swarm')
    a = p.parse_args(argv)
    if not LAMBDA_BOUND.ok(a.value):
        print(f'swarm lambda: {LAMBDA_BOUND.error(a.value)}', file=sys.stderr)
        return 2
    if not RAMP_BOUND.ok(a.ramp):
        print(f'swarm lambda: --{RAMP_BOUND.error(a.ramp)}', file=sys.stderr)
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
    try:                                 # the same run checks as every verb
        sent = _publish_once(Float64, '/swarm/lambda', Float64(data=a.value), 1.0, prog='swarm lambda')
    except RunRefused as err:
        print(err, file=sys.stderr)
        return 1
    if sent:
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
    if not STEERING_BOUND.ok(a.value):
        print(f'swarm steer: {STEERING_BOUND.error(a.value)}', file=sys.stderr)
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


# ---------------------------------------------------------------- faults

def _agent_name(text):
    name = text.strip('/')
    if not name or '/' in name or not name.replace('_', 'a').isalnum():
        return None
    return name


def _send(verb, request, wait):
    """Send ``request`` to the world of the one run on the domain; an exit code (0: sent)."""
    from std_msgs.msg import String

    # transient-local: a world whose side of the match comes late still gets the request
    try:
        if _publish_once(String, P.FAULT_REQUEST, String(data=json.dumps(request)), wait, P.qos_latched(10),
                         for_node='world', prog=f'swarm {verb}', agent=request['agent']):
            return 0
    except RunRefused as err:            # two runs on the domain, or an agent the run lacks
        print(err, file=sys.stderr)
        return 2 if 'unknown agent' in str(err) else 1
    print(f'swarm {verb}: no running swarm found (no world subscribes {P.FAULT_REQUEST}); '
          "is ROS_DOMAIN_ID the same as the run's?", file=sys.stderr)
    return 1


def _fault_options(verb: str, description: str, argv, seconds: bool = False):
    """(options, agent name) of ``swarm kill`` / ``swarm pause`` (``seconds``: its SECONDS
    argument); the name None (said) if AGENT is not an agent name."""
    p = argparse.ArgumentParser(prog=f'swarm {verb}', description=description)
    p.add_argument('agent', help='agent name, e.g. agent_3')
    if seconds:
        p.add_argument('seconds', type=float, help='sim seconds (> 0)')
    add_wait(p, 'the world')
    a = p.parse_args(argv)
    name = _agent_name(a.agent)
    if name is None:
        print(f'swarm {verb}: {a.agent!r} is not an agent name', file=sys.stderr)
    return a, name


def kill_main(argv) -> int:
    a, name = _fault_options('kill', (
        'Kill an agent of a running swarm: the world drops it from the roster at its next step '
        'and SIGKILLs its process (swarm run --processes).'), argv)
    if name is None:
        return 2
    code = _send('kill', dict(kind='kill', agent=name), a.wait)
    if code == 0:
        print(f'swarm kill: asked the world to kill {name}')
    return code


def pause_main(argv) -> int:
    a, name = _fault_options('pause', (
        'Freeze an agent of a running swarm for SECONDS of sim time: it neither moves nor is '
        'heard, its process is stopped (SIGSTOP) and resumed (SIGCONT) with the state it had.'), argv, seconds=True)
    if name is None:
        return 2
    if not PAUSE_BOUND.ok(a.seconds):
        print(f'swarm pause: {PAUSE_BOUND.error(a.seconds)}', file=sys.stderr)
        return 2
    code = _send('pause', {'kind': 'freeze', 'agent': name, 'for': a.seconds}, a.wait)
    if code:
        return code
    print(f'swarm pause: asked the world to freeze {name} for {a.seconds:g} s')
    return 0


# ---------------------------------------------------------------- the radio

def _agents_in_graph(node):
    """Agent names of the running swarm (nodes ``/<name>/agent``)."""
    return sorted(ns.strip('/') for nm, ns in node.get_node_names_and_namespaces()
                  if nm == 'agent' and ns.strip('/'))


def publish_event(kind: str, fields: dict, wait: float, check_names=(), prog='swarm'):
    """Publish one event once the swarm is found; returns an exit code (messages printed)."""
    from rclpy.duration import Duration
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String

    from swarm_ros.runinfo import RunWatch, describe
    with cli_node('swarm_cli_events') as (node, ex):
        clock = {}
        node.create_subscription(Clock, P.CLOCK, lambda m: clock.__setitem__('t', P.stamp_to_time(m.clock)), 10)
        pub = node.create_publisher(String, P.EVENTS, P.qos_latched(100))
        watch = RunWatch(node)
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
        run, err = watch.decide(ex, prog)           # every run's announcement
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
