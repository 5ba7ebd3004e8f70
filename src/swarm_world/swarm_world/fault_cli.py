"""``swarm kill AGENT`` and ``swarm pause AGENT SECONDS``: inject a fault into a running swarm.

Both publish a JSON request on ``/swarm/fault_request`` (std_msgs/String, see
`swarm_ros.protocol`); the world applies it at its next step, deterministically: the agent
leaves every table (killed for good, or frozen for SECONDS of sim time, then back with the
state it had), the event goes out on ``/swarm/events`` (recorded by ``swarm record``), and
in a ``swarm run --processes`` run the world also signals the agent's process (SIGKILL, or
SIGSTOP then SIGCONT), whose pid the launcher wrote to the run's ``pids.json``.
"""
from __future__ import annotations

import argparse
import json
import math
import sys

from swarm_ros import protocol as P
from swarm_ros.cliutil import add_wait


def _agent_name(text):
    name = text.strip('/')
    if not name or '/' in name or not name.replace('_', 'a').isalnum():
        return None
    return name


def _send(verb, request, wait):
    """Send ``request`` to the world of the one run on the domain; an exit code (0: sent)."""
    from std_msgs.msg import String

    from homotopy_commander.cli import RunRefused, _publish_once
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


def kill_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm kill', description=(
        'Kill an agent of a running swarm: the world drops it from the roster at its next step '
        'and SIGKILLs its process (swarm run --processes).'))
    p.add_argument('agent', help='agent name, e.g. agent_3')
    add_wait(p, 'the world')
    a = p.parse_args(argv)
    name = _agent_name(a.agent)
    if name is None:
        print(f'swarm kill: {a.agent!r} is not an agent name', file=sys.stderr)
        return 2
    code = _send('kill', dict(kind='kill', agent=name), a.wait)
    if code == 0:
        print(f'swarm kill: asked the world to kill {name}')
    return code


def pause_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm pause', description=(
        'Freeze an agent of a running swarm for SECONDS of sim time: it neither moves nor is '
        'heard, its process is stopped (SIGSTOP) and resumed (SIGCONT) with the state it had.'))
    p.add_argument('agent', help='agent name, e.g. agent_3')
    p.add_argument('seconds', type=float, help='sim seconds (> 0)')
    add_wait(p, 'the world')
    a = p.parse_args(argv)
    name = _agent_name(a.agent)
    if name is None:
        print(f'swarm pause: {a.agent!r} is not an agent name', file=sys.stderr)
        return 2
    if not (math.isfinite(a.seconds) and a.seconds > 0):
        print(f'swarm pause: {a.seconds!r} seconds rejected: must be finite and > 0', file=sys.stderr)
        return 2
    code = _send('pause', {'kind': 'freeze', 'agent': name, 'for': a.seconds}, a.wait)
    if code:
        return code
    print(f'swarm pause: asked the world to freeze {name} for {a.seconds:g} s')
    return 0
