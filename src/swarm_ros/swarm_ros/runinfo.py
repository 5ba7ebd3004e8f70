"""The identity of a run: ``run_id`` (given by ``swarm run`` to every node) and the world's
``/swarm/run`` announcement, which the live verbs read to say which run they reached.

Pure helpers (no ROS import) plus `RunWatch`, which subscribes ``/swarm/run`` on a node."""
from __future__ import annotations

import json
import re
import secrets

from . import protocol as P

_ID = re.compile(r'^[A-Za-z0-9_-]{1,32}$')


def new_run_id() -> str:
    """A fresh random run id (8 hex digits)."""
    return secrets.token_hex(4)


def valid_run_id(text: str) -> bool:
    return text == '' or bool(_ID.match(text))


def declare_run_id(node, what: str) -> str:
    """Declare a node's ``run_id`` parameter (``what``: what the node does with it) and return it;
    ParameterError for one that is not 1-32 letters, digits, _ or -."""
    from .rosutil import ParameterError, declare
    run_id = declare(node, 'run_id', '', f"this run's id (swarm run sets it; '' = none): {what}")
    if not valid_run_id(run_id):
        raise ParameterError(f'parameter run_id: {run_id!r} is not 1-32 letters, digits, _ or -')
    return run_id


def run_json(run_id: str, scenario: str, mode: str, agents, since: float = 0.0) -> str:
    """The text of a ``/swarm/run`` message; ``since``: when its world started (wall s, epoch),
    so that of two runs on one domain the younger one gives way."""
    return json.dumps(dict(run_id=run_id, scenario=scenario, mode=mode, agents=list(agents), since=since))


def older_runs(runs: dict, run_id: str, since: float) -> list:
    """The runs heard that are not ``run_id`` and started before ``since`` (or do not say when)."""
    return [r for rid, r in runs.items()
            if rid != run_id and not (isinstance(r.get('since'), (int, float)) and r['since'] > since)]


def parse_run(text: str):
    """The dict of a ``/swarm/run`` message, or None if it is not one."""
    try:
        d = json.loads(text)
    except ValueError:
        return None
    if not (isinstance(d, dict) and isinstance(d.get('run_id'), str) and isinstance(d.get('agents'), list)):
        return None
    return d


def give_way(runs: dict, run_id: str, since: float, worlds: int, started: bool, domain: str):
    """Why this run must stop (the error line), or None: an older run heard on the domain, or
    (before the start, when no announcement may have come yet) a second ``/world`` node.  The
    older run goes on; the younger one gives way, also when discovery finds the other late."""
    others = older_runs(runs, run_id, since)
    if not others and (started or worlds <= 1):
        return None
    what = '; '.join(describe(r) for r in others) if others else 'a second /world node'
    return (f'another swarm run is on ROS_DOMAIN_ID={domain} ({what}): '
            f'{"stopping" if started else "refusing to start"} this one; give each run its own ROS_DOMAIN_ID')


def describe(run) -> str:
    """'run 1a2b3c4d (homotopy_global, lockstep, 6 agents)'."""
    rid = run.get('run_id') or '(no id)'
    return f'run {rid} ({run.get("scenario", "?")}, {run.get("mode", "?")}, {len(run.get("agents", []))} agents)'


def one_run(runs: dict, prog: str):
    """(run, None) if exactly one run was heard, else (None, the error line)."""
    if len(runs) > 1:
        return None, (f'{prog}: {len(runs)} runs share this ROS_DOMAIN_ID: '
                      + '; '.join(describe(r) for r in runs.values())
                      + '; refusing to act on an unknown one (give each run its own ROS_DOMAIN_ID)')
    if not runs:
        return None, None
    return next(iter(runs.values())), None


def unknown_agent(run, name: str, prog: str):
    """The error line if ``name`` is not an agent of ``run`` (None if it is, or if unknown)."""
    if run is None or name in run.get('agents', []):
        return None
    agents = run.get('agents', [])
    shown = ', '.join(agents[:8]) + (', ...' if len(agents) > 8 else '')
    return f'{prog}: unknown agent {name!r} in {describe(run)}: agents are {shown}'


def has_world(node) -> bool:
    """A ``/world`` node is in the graph (then its ``/swarm/run`` is worth waiting for)."""
    return any(nm == 'world' for nm, _ in node.get_node_names_and_namespaces())


class RunWatch:
    """Collects the ``/swarm/run`` announcements heard on ``node`` ({run id: dict})."""

    def __init__(self, node):
        from std_msgs.msg import String
        self.runs = {}
        # depth 10: several worlds on one domain are each heard (transient-local, one sample each)
        self.sub = node.create_subscription(String, P.RUN, self._on_run, P.qos_latched(10))

    def _on_run(self, msg):
        d = parse_run(msg.data)
        if d is not None:
            self.runs[d['run_id']] = d
