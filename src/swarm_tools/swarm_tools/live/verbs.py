"""The live verbs: change a running swarm from the shell.

``swarm lambda`` and ``swarm steer`` (the commander's inputs)
    ``swarm lambda 1.0 --ramp 20`` publishes ``[1.0, 20]`` on ``/commander/lambda_setpoint``:
    the commander ramps λ smoothly from its current value to 1.0 over 20 sim seconds, from the
    next step it decides.  Without a commander (none subscribed within --wait seconds) it
    publishes the value on ``/swarm/lambda``, as ``ros2 topic pub --once /swarm/lambda
    std_msgs/msg/Float64 "{data: 1.0}"`` does (a running commander takes that as a set-point
    with its ``ramp`` parameter; docs/commands.md).  ``swarm steer agent_0 0.01`` publishes 0.01
    on ``/agent_0/steering`` (as ``ros2 topic pub`` would): the commander makes it that
    leader's constant steering program (the agent becomes a leader if it was not).  In a 3D
    run (``dim`` in ``/swarm/run``) ``swarm steer agent_1 0 0.02`` sends ``[s_u, s_v]``; a
    count that does not match the run's dimension is refused (exit 2).

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
The verbs are thin wrappers over `swarm_tools.live.client.Client`, the client of the Python API
(`swarm_tools.api.Swarm`): one client path; exit 2 for a bad value, 1 when nothing takes it.
"""
from __future__ import annotations

import argparse
import sys

from swarm_ros import protocol as P
from swarm_ros.cliutil import add_wait
from swarm_tools.live.client import Client, SwarmError, UnknownAgent


def _say(line):
    print(line, flush=True)


def _client_call(prog: str, call) -> int:
    """Run ``call(client)`` on a `Client` of the domain: 0, or the exit code of its error
    (said): 2 for a bad value or an agent the run does not have, 1 when no swarm takes it or
    two runs share the domain."""
    try:
        with Client(name='swarm_cli') as client:
            call(client)
        return 0
    except ValueError as err:
        print(f'{prog}: {err}', file=sys.stderr)
        return 2
    except UnknownAgent as err:
        print(err, file=sys.stderr)
        return 2
    except SwarmError as err:         # NoSwarm, TwoRuns
        print(err, file=sys.stderr)
        return 1


# ---------------------------------------------------------------- λ and steering
def lambda_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm lambda', description=(
        'Set the homotopy parameter λ of a running swarm: the commander ramps smoothly to it.'))
    p.add_argument('value', type=float, help='λ in [0, 1]')
    p.add_argument('--ramp', type=float, default=20.0, help='ramp duration in sim seconds (default 20; 0 = jump)')
    add_wait(p, 'the swarm')
    a = p.parse_args(argv)

    def call(client):
        how = client.set_lambda(a.value, a.ramp, a.wait, say=_say)
        print(f'swarm lambda: set-point λ={a.value:g}, ramp {a.ramp:g} s (sent to the commander)'
              if how == 'commander' else f'swarm lambda: no commander found; published λ={a.value:g} on /swarm/lambda')
    return _client_call('swarm lambda', call)


def steer_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm steer', description=(
        "Set a leader's steering program (a constant curvature s_k; in a 3D run (s_u, s_v)) in a running swarm."))
    p.add_argument('agent', help='agent name, e.g. agent_0')
    p.add_argument('value', type=float, nargs='+', metavar='S',
                   help='curvature s_k (finite; + turns anticlockwise); in a 3D run two: s_u s_v')
    add_wait(p, 'the agent')
    a = p.parse_args(argv)
    shown = f'{a.value[0]:g}' if len(a.value) == 1 else '(' + ', '.join(f'{v:g}' for v in a.value) + ')'

    def call(client):
        name = client.steer(a.agent, a.value[0] if len(a.value) == 1 else a.value, a.wait, say=_say)
        print(f'swarm steer: {name} steering {shown}')
    return _client_call('swarm steer', call)


# ---------------------------------------------------------------- faults
def _fault_options(verb: str, description: str, argv, seconds: bool = False):
    p = argparse.ArgumentParser(prog=f'swarm {verb}', description=description)
    p.add_argument('agent', help='agent name, e.g. agent_3')
    if seconds:
        p.add_argument('seconds', type=float, help='sim seconds (> 0)')
    add_wait(p, 'the world')
    return p.parse_args(argv)


def kill_main(argv) -> int:
    a = _fault_options('kill', (
        'Kill an agent of a running swarm: the world drops it from the roster at its next step '
        'and SIGKILLs its process (swarm run --processes).'), argv)

    def call(client):
        name = client.fault('kill', a.agent, wait=a.wait, prog='swarm kill', say=_say)
        print(f'swarm kill: asked the world to kill {name}')
    return _client_call('swarm kill', call)


def pause_main(argv) -> int:
    a = _fault_options('pause', (
        'Freeze an agent of a running swarm for SECONDS of sim time: it neither moves nor is '
        'heard, its process is stopped (SIGSTOP) and resumed (SIGCONT) with the state it had.'), argv, seconds=True)

    def call(client):
        name = client.fault('freeze', a.agent, a.seconds, wait=a.wait, prog='swarm pause', say=_say)
        print(f'swarm pause: asked the world to freeze {name} for {a.seconds:g} s')
    return _client_call('swarm pause', call)


# ---------------------------------------------------------------- the radio
def _event_said(prog, kind, fields):
    def said(result):
        t, readers = result
        print(f'{prog}: {kind} {fields} at t={"?" if t is None else f"{t:.2f}"} '
              f'(sent to {readers} readers of {P.EVENTS})')
    return said


def drop_main(argv) -> int:
    p = argparse.ArgumentParser(prog='swarm drop', description=(
        'Burst packet loss in a running swarm: every state message is lost with probability P '
        '(on top of the configured loss), for --for sim seconds or until the next `swarm drop`.'))
    p.add_argument('loss', type=float, help='loss probability P in [0, 1] (0 ends a burst)')
    p.add_argument('--for', dest='duration', type=float, help='duration in sim seconds (default: until changed)')
    add_wait(p, 'the swarm')
    a = p.parse_args(argv)
    said = _event_said('swarm drop', 'drop', dict(loss=a.loss, duration=a.duration))
    return _client_call('swarm drop', lambda client: said(client.drop(a.loss, a.duration, a.wait, say=_say)))


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
    said = _event_said('swarm partition', 'partition', dict(groups=groups))
    return _client_call('swarm partition', lambda client: said(client.partition(groups, a.wait, say=_say)))
