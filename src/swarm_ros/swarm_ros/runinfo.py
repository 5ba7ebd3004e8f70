"""The identity of a run: ``run_id`` (given by ``swarm run`` to every node) and the world's
``/swarm/run`` announcement, which the live verbs read to say which run they reached.

Pure helpers (no ROS import) plus `RunWatch`, which subscribes ``/swarm/run`` on a node."""
from __future__ import annotations

import json
import math
import numbers
import os
import re
import secrets
from types import SimpleNamespace

from swarm_core.checks import MAX_COORD, json_value
from swarm_ros import protocol as P
from swarm_ros.msg_checks import RejectLog
from swarm_ros.rosutil import ParameterError, declare

#: longest ``/swarm/run`` text (the agent list of the largest run is about 40 kB)
MAX_RUN_CHARS = 1 << 20
#: how long a live verb listens for the announcements of every ``/swarm/run`` writer it sees
ANNOUNCE_WAIT = 3.0
#: wall s a new participant may take to discover a swarm already on the domain (measured 0.15-3.0 s
#: on a busy 2-core machine): how long a world listens before its first step, and `Swarm.start`
#: before it starts a run, for another run
DISCOVERY_SETTLE = 3.0
#: the environment variable that sets `discovery_settle` (wall s, 0-60), e.g. 0 where a
#: ROS_DOMAIN_ID is held for one run alone (the pytest plugin's ``ros_domain`` does so)
SETTLE_ENV = 'SWARM_DISCOVERY_SETTLE'
#: most runs a `RunWatch` keeps (more are counted as ignored: a peer announcing run after run
#: must not grow it without end; two are already enough to refuse)
MAX_RUNS = 64


def discovery_settle() -> float:
    """Wall s to listen for another run before starting one: `SETTLE_ENV` if set, else
    `DISCOVERY_SETTLE`; ValueError naming the variable if it is not a number in [0, 60]."""
    text = os.environ.get(SETTLE_ENV, '').strip()
    if not text:
        return DISCOVERY_SETTLE
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 <= value <= 60.0:
        raise ValueError(f'{SETTLE_ENV}={text!r}: want wall seconds in [0, 60]')
    return value


#: the highest ROS_DOMAIN_ID there is: Fast DDS computes its UDP ports from it, and past 232
#: they do not fit in 16 bits (its participant then fails, and rclpy ends the process);
#: 0-101 stay below Linux's ephemeral ports (docs.ros.org, "The ROS_DOMAIN_ID")
MAX_DOMAIN = 232


def check_domain(domain, name: str = 'domain'):
    """``domain`` (a ROS_DOMAIN_ID given as an argument ``name``; None: the environment's) as an
    int, or ValueError naming the argument and the range [0, `MAX_DOMAIN`] for anything else (a
    negative or too large number, a string, a bool, a float).  None stays None, unless
    ROS_DOMAIN_ID holds a decimal number past `MAX_DOMAIN`: ValueError naming the variable
    (rclpy would take it, and Fast DDS end the process)."""
    if domain is None:
        text = os.environ.get('ROS_DOMAIN_ID', '').strip()
        if text.isdigit() and int(text) > MAX_DOMAIN:
            raise ValueError(f'ROS_DOMAIN_ID={text}: must be a ROS_DOMAIN_ID, an integer in [0, {MAX_DOMAIN}] '
                             '(0-101 are safe on Linux)')
        return None
    if isinstance(domain, bool) or not isinstance(domain, numbers.Integral) or not 0 <= domain <= MAX_DOMAIN:
        raise ValueError(f'{name}={domain!r}: must be a ROS_DOMAIN_ID, an integer in [0, {MAX_DOMAIN}] '
                         '(0-101 are safe on Linux)')
    return int(domain)


_ID = re.compile(r'^[A-Za-z0-9_-]{1,32}$')


def new_run_id() -> str:
    """A fresh random run id (8 hex digits)."""
    return secrets.token_hex(4)


def valid_run_id(text: str) -> bool:
    return text == '' or bool(_ID.match(text))


def declare_run_id(node, what: str) -> str:
    """Declare a node's ``run_id`` parameter (``what``: what the node does with it) and return it;
    ParameterError for one that is not 1-32 letters, digits, _ or -."""
    run_id = declare(node, 'run_id', '', f"this run's id (swarm run sets it; '' = none): {what}", read_only=True)
    if not valid_run_id(run_id):
        raise ParameterError(f'parameter run_id: {run_id!r} is not 1-32 letters, digits, _ or -')
    return run_id


def run_json(run_id: str, scenario: str, mode: str, agents, since: float, scenario_hash: str = '',
             remote=(), robots=None, dim: int = 2, ground=None) -> str:
    """The text of a ``/swarm/run`` message; ``since``: when its world started (wall s, epoch),
    so that of two runs on one domain the younger one gives way; ``scenario_hash``: the
    content hash of its scenario (`swarm_core.scenario.loader.Scenario.content_hash`), ``remote``:
    the agents other hosts start, which ``swarm join`` checks (`join_error`), and ``robots``:
    {agent: robot kind} of those that drive a robot (``swarm join`` starts them so); ``dim``: the
    scenario's dimension (2 or 3: ``swarm steer`` sends one curvature or two).  A 3D run's also
    has ``ground``: its floor's height, null for none (`run_ground`; ``swarm report`` reads it
    from a bag); a planar run's has no ``ground``."""
    doc = dict(run_id=run_id, scenario=scenario, mode=mode, agents=list(agents), since=since,
               scenario_hash=scenario_hash, remote=list(remote), robots=dict(robots or {}), dim=int(dim))
    if doc['dim'] == 3:
        doc['ground'] = None if ground is None else float(ground)
    return json.dumps(doc)


def run_ground(run) -> tuple[bool, float | None]:
    """What the announcement ``run`` (a dict, or None) tells of its 3D run's floor: (True, the
    floor's height or None for no floor), or (False, None) where it does not tell (an older
    run's announcement has no ``ground``; one that is not a finite number of at most
    `MAX_COORD` tells nothing)."""
    if not isinstance(run, dict) or 'ground' not in run:
        return False, None
    g = run['ground']
    if g is None:
        return True, None
    if isinstance(g, bool) or not isinstance(g, numbers.Real) or not abs(g) <= MAX_COORD:
        return False, None
    return True, float(g)


def robots_text(robots: dict) -> str:
    """{agent: robot kind} as the world's parameter ``remote_robots`` takes it: NAME=KIND,..."""
    return ','.join(f'{nm}={kind}' for nm, kind in robots.items())


def parse_robots_text(text: str, remote, kinds) -> dict:
    """{agent: kind} of a `robots_text`; ValueError for an agent not in ``remote`` or a kind
    not in ``kinds``."""
    out = {}
    for item in (s.strip() for s in text.split(',')):
        if not item:
            continue
        nm, _, kind = item.partition('=')
        if nm not in remote or kind not in kinds:
            raise ValueError(f'{item!r}: want NAME=KIND with NAME a remote agent and KIND one of {", ".join(kinds)}')
        out[nm] = kind
    return out


def run_robots(run: dict, names) -> dict:
    """{agent: robot kind} the announcement ``run`` gives for the agents ``names`` (those on no
    robot left out; a malformed entry counts as none)."""
    robots = run.get('robots') if isinstance(run.get('robots'), dict) else {}
    return {nm: robots[nm] for nm in names if isinstance(robots.get(nm), str)}


def join_error(run: dict, names, scenario_hash: str, prog: str = 'swarm join'):
    """Why agents ``names`` of a scenario with ``scenario_hash`` must not join ``run`` (an
    announcement), or None: the run's scenario (with its seed, dt and duration) is another,
    or the run starts some of them itself (only its ``remote`` agents come from other hosts)."""
    if run.get('scenario_hash') != scenario_hash:
        return (f'{prog}: {describe(run)} runs another scenario (hash {run.get("scenario_hash") or "?"}, '
                f'here {scenario_hash}): give the same scenario and options as the run')
    remote = run.get('remote') if isinstance(run.get('remote'), list) else []
    have = [nm for nm in names if nm not in remote]
    if have:
        return (f'{prog}: {describe(run)} already has {", ".join(have[:8])}{", ..." if len(have) > 8 else ""} '
                f'(it waits for {", ".join(remote[:8]) or "no agent"} from other hosts)')
    return None


def older_runs(runs: dict, run_id: str, since: float) -> list:
    """The runs heard that are not ``run_id`` and started before ``since``."""
    return [r for rid, r in runs.items() if rid != run_id and r['since'] < since]


def run_error(text: str):
    """Why a ``/swarm/run`` text is not an announcement the give-way rule can use (None if it
    is one): JSON (bounded, `json_value`) holding a valid ``run_id`` ('' for a world started
    without one), ``agents`` a list of names and ``since`` a finite number."""
    try:
        d = json_value(text, MAX_RUN_CHARS)
    except ValueError as err:
        return f'not JSON ({err})'
    if not isinstance(d, dict):
        return 'not a JSON object'
    if not (isinstance(d.get('run_id'), str) and valid_run_id(d['run_id'])):
        return f'run_id {d.get("run_id")!r} is not 1-32 letters, digits, _ or - (or empty: no id)'
    if not (isinstance(d.get('agents'), list) and all(isinstance(a, str) for a in d['agents'])):
        return 'agents is not a list of names'
    since = d.get('since')
    if isinstance(since, bool) or not isinstance(since, numbers.Real) or not math.isfinite(since):
        return f'since {since!r} is not a finite number'
    return None


def parse_run(text: str):
    """The dict of a ``/swarm/run`` message, or None if it is not one (`run_error`)."""
    return None if run_error(text) else json_value(text, MAX_RUN_CHARS)


def give_way(runs: dict, run_id: str, since: float, worlds: int, started: bool, domain: str):
    """Why this run must not start (the error line), or None: an older run heard on the
    domain, or a second ``/world`` node (whose announcement may not have come yet).  The older
    run goes on; the younger one gives way.  Once started a run never stops for an
    announcement: a peer's late (or forged) one would cost its trajectory; the live verbs
    refuse to act while two runs are announced (`one_run`)."""
    if started:
        return None
    others = older_runs(runs, run_id, since)
    if not others and worlds <= 1:
        return None
    what = '; '.join(describe(r) for r in others) if others else 'a second /world node'
    return (f'another swarm run is on ROS_DOMAIN_ID={domain} ({what}): '
            'refusing to start this one; give each run its own ROS_DOMAIN_ID')


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


def heard_every_writer(runs: dict, ignored: int, writers: int) -> bool:
    """Whether each of the ``writers`` of ``/swarm/run`` in the graph has been heard (an
    announcement kept in ``runs`` or one ``ignored``): a live verb decides only then."""
    return len(runs) + ignored >= writers


def verb_refusal(runs: dict, ignored: int, writers: int, prog: str, agent=None):
    """(the run, None) where a live verb may act, else (None, the one error line), the same
    for every verb: two runs announced, a second ``/swarm/run`` writer whose announcement
    was not heard (a QoS that cannot be read, or silence), or an ``agent`` the run lacks."""
    run, err = one_run(runs, prog)
    if err is None and writers > 1 and not heard_every_writer(runs, ignored, writers):
        err = (f'{prog}: {writers} writers announce runs on this ROS_DOMAIN_ID and only '
               f'{len(runs) + ignored} could be heard; refusing to act on an unknown one '
               '(give each run its own ROS_DOMAIN_ID)')
    if err is None and agent:
        err = unknown_agent(run, agent, prog)
    return (None, err) if err else (run, None)


class RunWatch:
    """Collects the ``/swarm/run`` announcements heard on ``node`` ({run id: dict}, at most
    `MAX_RUNS`); one that is not an announcement (`run_error`) is ignored with one line to
    ``log`` (if given; rate-limited, `RejectLog`)."""

    def __init__(self, node, log=None):
        from std_msgs.msg import String
        self.node = node
        self.log = None if log is None else RejectLog(SimpleNamespace(warning=log))
        self.runs = {}
        self.ignored = 0
        # depth 10: several worlds on one domain are each heard (transient-local, one sample each)
        self.sub = node.create_subscription(String, P.RUN, self._on_run, P.qos_latched(10))

    def _on_run(self, msg):
        why = run_error(msg.data)
        if why is None:
            d = parse_run(msg.data)
            if d['run_id'] in self.runs or len(self.runs) < MAX_RUNS:
                self.runs[d['run_id']] = d
                return
            why = f'more than {MAX_RUNS} runs announced'
        self.ignored += 1
        if self.log is not None:
            self.log('run-announcement', f'{P.RUN}: ignored an announcement {msg.data[:80]!r}: {why}')

    def heard_all(self) -> bool:
        """Every writer of ``/swarm/run`` in the graph has been heard (and one is there if a
        world is): a live verb waits for this, at most `ANNOUNCE_WAIT` s, then decides."""
        writers = self.node.count_publishers(P.RUN)
        return heard_every_writer(self.runs, self.ignored, writers) and bool(writers or not has_world(self.node))

    def refusal(self, prog: str, agent=None):
        """`verb_refusal` on what has been heard: (the run, None) or (None, the error line)."""
        return verb_refusal(dict(self.runs), self.ignored, self.node.count_publishers(P.RUN), prog, agent)
