"""The one client path to a running swarm: an rclpy node in a Context of its own, spun by its
own executor in a background thread, that finds the run (its ``/swarm/run`` announcement) and
sends the live commands.  `swarm_tools.api.Swarm` and the ``swarm`` live verbs
(`swarm_tools.live.verbs`) both use it; the verbs turn its errors into their messages and exit codes.

Every command first reads the run's announcement and refuses (`TwoRuns`) when two runs share
the domain, or (`UnknownAgent`) for an agent the run does not have; `NoSwarm` when nothing
takes the command within ``wait`` wall seconds.  Bad values raise ValueError before anything
is sent.  A command returns once the readers it is for have acknowledged it (DDS reliable
acknowledgement); docs/python-api.md says what each waits for.
"""
from __future__ import annotations

import json
import math
import numbers
import threading
import time

from swarm_core.checks import LAMBDA_BOUND, PAUSE_BOUND, RAMP_BOUND, STEERING_BOUND
from swarm_ros import protocol as P
from swarm_ros import runinfo
from swarm_ros.msg_checks import RejectLog, guard_subscriptions


class SwarmError(RuntimeError):
    """A command, wait or start that could not be done; the message says why."""


class NoSwarm(SwarmError):
    """Nothing on the domain takes the command (no run, or another ROS_DOMAIN_ID)."""


class TwoRuns(SwarmError):
    """Two runs share the domain: a command would reach an unknown one."""


class UnknownAgent(SwarmError):
    """The run has no agent of that name."""


def agent_name(text: str):
    """The agent name in ``text`` ('/agent_3' → 'agent_3'), or None if it is not one."""
    name = str(text).strip('/')
    if not name or '/' in name or not name.replace('_', 'a').isalnum():
        return None
    return name


def _quiet(_line):
    pass


def check_lambda(value: float, ramp: float) -> None:
    """ValueError for a λ outside [0, 1] (`LAMBDA_BOUND`) or a ramp outside `RAMP_BOUND`."""
    if not LAMBDA_BOUND.ok(value):
        raise ValueError(LAMBDA_BOUND.error(value))
    if not RAMP_BOUND.ok(ramp):
        raise ValueError(f'--{RAMP_BOUND.error(ramp)}')


def check_steering(value) -> tuple:
    """A steering value (a number, or a sequence of one or two) as a tuple of floats;
    ValueError for a value outside `STEERING_BOUND` or more than two."""
    values = (value,) if isinstance(value, numbers.Real) else tuple(value)
    if not 1 <= len(values) <= 2:
        raise ValueError(f'give one curvature s_k, or in a 3D run two (s_u s_v), not {len(values)}')
    for v in values:
        if not STEERING_BOUND.ok(v):
            raise ValueError(STEERING_BOUND.error(v))
    return tuple(float(v) for v in values)


def check_partition(groups) -> list:
    """``groups`` (lists of agent names) as lists of str; ValueError for an empty group or a
    name in two groups."""
    groups = [[str(nm).strip() for nm in g] for g in groups]
    names = [nm for g in groups for nm in g]
    if any(not g or not all(g) for g in groups):
        raise ValueError('an empty group')
    if len(set(names)) != len(names):
        dup = next(nm for nm in names if names.count(nm) > 1)
        raise ValueError(f'{dup!r} is in more than one group')
    return groups


class Client:
    """An rclpy node on ``domain`` (None: ROS_DOMAIN_ID) spun in a background thread.

    ``runs``: the ``/swarm/run`` announcements heard ({run id: dict}).  Use it as a context
    manager, or call `close`."""

    def __init__(self, domain=None, name: str = 'swarm_client'):
        domain = runinfo.check_domain(domain)       # Fast DDS ends the process past 232

        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        self.ctx = Context()
        rclpy.init(context=self.ctx, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name, context=self.ctx, start_parameter_services=False)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.lock = threading.Lock()
        #: the messages its readers (and those others make on its node: `api.Swarm`) could not read
        self.reject = RejectLog(self.node.get_logger())
        self.watch = runinfo.RunWatch(self.node)
        self.clock = None             # sim time of the newest /clock (`follow_clock`)
        self._clock_sub = None
        self._pubs = {}
        self._stop = False
        self._thread = threading.Thread(target=self._spin, name=f'{name}_executor', daemon=True)
        self._thread.start()

    @property
    def runs(self) -> dict:
        return dict(self.watch.runs)

    def _spin(self):
        """Spin until `close`.  No message ends this thread: every reader on the node, those
        made since the last turn too, is guarded (`msg_checks.guard_subscriptions`: what it
        cannot read is counted in `reject` and logged once), and whatever else a callback
        raises is counted there too."""
        while not self._stop and self.ctx.ok():
            try:
                guard_subscriptions(self.node, self.reject)
                self.ex.spin_once(timeout_sec=0.05)
            except Exception as err:  # shutdown under our feet: the loop ends with the context
                if self._stop or not self.ctx.ok():
                    return
                self.reject('callback', f'{self.node.get_name()}: a callback failed ({type(err).__name__}: '
                            f'{str(err)[:120]})')
                time.sleep(0.01)      # a fault that repeats must not spin the thread hot

    def close(self):
        """Stop the executor thread and shut the node and its Context down."""
        import rclpy
        if self._stop:
            return
        self._stop = True
        self._thread.join(timeout=5.0)
        self.ex.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ------------------------------------------------------------ helpers
    @staticmethod
    def until(cond, seconds: float) -> bool:
        """Poll ``cond()`` every 50 ms for up to ``seconds`` wall seconds; gives cond()."""
        end = time.monotonic() + seconds
        while not cond() and time.monotonic() < end:
            time.sleep(0.05)
        return bool(cond())

    def follow_clock(self):
        """Subscribe ``/clock`` (once): `clock` is the newest sim time."""
        from rosgraph_msgs.msg import Clock
        if self._clock_sub is None:
            self._clock_sub = self.node.create_subscription(
                Clock, P.CLOCK, lambda m: setattr(self, 'clock', P.stamp_to_time(m.clock)), 10)

    def publisher(self, msg_type, topic: str, qos):
        key = (topic, msg_type)
        if key not in self._pubs:
            self._pubs[key] = self.node.create_publisher(msg_type, topic, qos)
        return self._pubs[key]

    def agents_in_graph(self) -> list:
        """Agent names of the running swarm (nodes ``/<name>/agent``)."""
        return sorted(ns.strip('/') for nm, ns in self.node.get_node_names_and_namespaces()
                      if nm == 'agent' and ns.strip('/'))

    def one_run(self, prog: str, agent=None):
        """The one run on the domain (None if the swarm does not announce one), once every
        writer of ``/swarm/run`` in the graph has been heard (at most `runinfo.ANNOUNCE_WAIT`
        s: every verb decides after this same wait); `TwoRuns` for two runs or a writer that
        cannot be heard, `UnknownAgent` (the line says why)."""
        self.until(self.watch.heard_all, runinfo.ANNOUNCE_WAIT)
        run, err = self.watch.refusal(prog)
        if err:
            raise TwoRuns(err)
        err = runinfo.unknown_agent(run, agent, prog) if agent else None
        if err:
            raise UnknownAgent(err)
        return run

    # ------------------------------------------------------------ one message to one node
    def send(self, msg_type, topic, msg, wait: float, qos=10, for_node=None, prog='swarm', agent=None,
             say=_quiet) -> bool:
        """Publish ``msg`` once a subscriber has matched (up to ``wait`` s) and wait for the
        acknowledgements; False (nothing sent) if none matched.  ``for_node``: wait for a
        subscription of that node (e.g. 'commander'), not just any (a recorder may match
        first).  With ``agent``, the run must have that agent.  ``say``: gets the line naming
        the run reached."""
        from rclpy.duration import Duration
        pub = self.publisher(msg_type, topic, qos)

        def ready():
            if pub.get_subscription_count() == 0:
                return False
            return for_node is None or any(
                i.node_name == for_node for i in self.node.get_subscriptions_info_by_topic(topic))

        if not self.until(ready, wait) and pub.get_subscription_count() == 0:
            return False
        time.sleep(0.2)                  # let the subscribers' side of the match settle
        run = self.one_run(prog, agent)
        say(f'{prog}: reached {runinfo.describe(run)}' if run else
            f'{prog}: reached a swarm that does not announce a run on {P.RUN}')
        pub.publish(msg)
        pub.wait_for_all_acked(Duration(seconds=2.0))
        return True

    def set_lambda(self, value: float, ramp: float = 20.0, wait: float = 10.0, prog='swarm lambda',
                   say=_quiet) -> str:
        """λ set-point [value, ramp] to the commander ('commander'), or without one λ on
        ``/swarm/lambda`` ('topic'); `NoSwarm` if neither has a reader."""
        from std_msgs.msg import Float64, Float64MultiArray
        check_lambda(value, ramp)
        if self.send(Float64MultiArray, P.LAMBDA_SETPOINT, Float64MultiArray(data=[value, ramp]), wait,
                     for_node='commander', prog=prog, say=say):
            return 'commander'
        if self.send(Float64, P.LAMBDA, Float64(data=value), 1.0, prog=prog, say=say):
            return 'topic'
        raise NoSwarm(f'{prog}: no running swarm found (nothing subscribes {P.LAMBDA}); '
                      "is ROS_DOMAIN_ID the same as the run's?")

    def steer(self, agent: str, curvature, wait: float = 10.0, prog='swarm steer', say=_quiet) -> str:
        """Leader steering for ``agent`` (to the commander): a curvature s_k, or in a 3D run
        (s_u, s_v); gives the name.  ValueError for a count that does not match the run's
        dimension (`steering_dim`)."""
        from std_msgs.msg import Float64, Float64MultiArray
        values = check_steering(curvature)
        name = agent_name(agent)
        if name is None:
            raise ValueError(f'{agent!r} is not an agent name')
        topic = P.steering_topic(name)
        dim, run = self.steering_dim(topic, wait, prog)
        if dim is None:
            raise NoSwarm(f'{prog}: unknown agent {name!r}: nothing subscribes {topic}')
        if len(values) != dim - 1:
            raise ValueError(f'{runinfo.describe(run) if run else "the run"} is {dim}D: give '
                             f'{"one number, s_k" if dim == 2 else "two numbers, s_u s_v"} (got {len(values)})')
        msg = Float64(data=values[0]) if dim == 2 else Float64MultiArray(data=list(values))
        if not self.send(type(msg), topic, msg, wait, for_node='commander', prog=prog, agent=name, say=say):
            raise NoSwarm(f'{prog}: unknown agent {name!r}: nothing subscribes {topic}')
        return name

    def steering_dim(self, topic: str, wait: float, prog: str):
        """(the run's dimension, the run) once the run announces it or the commander publishes
        ``topic`` (up to ``wait`` s; (None, None) if neither): the announcement says it, else the
        topic's type does (Float64 in 2D, Float64MultiArray in 3D; a discovery server's plain
        client sees no topic it does not use).  `TwoRuns` as `one_run`."""
        def commander_type():
            return next((i.topic_type for i in self.node.get_publishers_info_by_topic(topic)
                         if i.node_name == 'commander'), None)

        if not self.until(lambda: any('dim' in r for r in self.runs.values()) or commander_type(), wait):
            return None, None
        run = self.one_run(prog)
        if run and run.get('dim') in (2, 3):
            return run['dim'], run
        return (3 if (commander_type() or '').endswith('Float64MultiArray') else 2), run

    def fault(self, kind: str, agent: str, seconds=None, wait: float = 10.0, prog='swarm', say=_quiet) -> str:
        """A live fault request (``kind`` 'kill', or 'freeze' for ``seconds``) to the world; gives
        the agent's name.  Transient-local: a world whose side of the match comes late still
        gets it."""
        from std_msgs.msg import String
        name = agent_name(agent)
        if name is None:
            raise ValueError(f'{agent!r} is not an agent name')
        request = dict(kind=kind, agent=name)
        if kind == 'freeze':
            if not PAUSE_BOUND.ok(seconds):
                raise ValueError(PAUSE_BOUND.error(seconds))
            request['for'] = float(seconds)
        if not self.send(String, P.FAULT_REQUEST, String(data=json.dumps(request)), wait, P.qos_latched(10),
                         for_node='world', prog=prog, agent=name, say=say):
            raise NoSwarm(f'{prog}: no running swarm found (no world subscribes {P.FAULT_REQUEST}); '
                          "is ROS_DOMAIN_ID the same as the run's?")
        return name

    # ------------------------------------------------------------ the radio: one event to every agent
    def publish_event(self, kind: str, fields: dict, wait: float, check_names=(), prog='swarm', say=_quiet):
        """Publish one radio event (stamped with the sim time of ``/clock``) once the swarm's
        agents have matched; gives (t, readers).  `NoSwarm`, `TwoRuns`, `UnknownAgent`."""
        from rclpy.duration import Duration
        from std_msgs.msg import String
        self.follow_clock()
        pub = self.publisher(String, P.EVENTS, P.qos_latched(100))
        end = time.monotonic() + wait
        if not self.until(lambda: self.agents_in_graph() and pub.get_subscription_count() > 0, wait):
            raise NoSwarm(f'{prog}: no running swarm found (no agent subscribes {P.EVENTS}); '
                          "is ROS_DOMAIN_ID the same as the run's?")
        # let the other agents match too: until the count has not grown for 0.5 s (≤ 3 s)
        count, stable, limit = pub.get_subscription_count(), time.monotonic(), time.monotonic() + 3.0
        while time.monotonic() - stable < 0.5 and time.monotonic() < limit:
            time.sleep(0.05)
            if pub.get_subscription_count() != count:
                count, stable = pub.get_subscription_count(), time.monotonic()
        # the graph's node names lag the matched readers (and an agent resumed after a pause is
        # rediscovered late): wait for every named agent, and for the sim time, until ``wait``
        # is up (at least 3 s more), before calling a name unknown
        self.until(lambda: self.clock is not None and all(nm in self.agents_in_graph() for nm in check_names),
                   max(end - time.monotonic(), 3.0))
        run = self.one_run(prog)
        say(f'{prog}: reached {runinfo.describe(run)}' if run else
            f'{prog}: reached a swarm that does not announce a run on {P.RUN}')
        unknown = [nm for nm in check_names if nm not in self.agents_in_graph()]
        if unknown:
            raise UnknownAgent(f'{prog}: unknown agent {unknown[0]!r} (running: {", ".join(self.agents_in_graph())})')
        t = self.clock
        pub.publish(String(data=P.event_json(kind, t, **fields, run_id=(run or {}).get('run_id', ''))))   # its run's
        pub.wait_for_all_acked(Duration(seconds=2.0))
        return t, pub.get_subscription_count()

    def drop(self, loss: float, duration=None, wait: float = 10.0, prog='swarm drop', say=_quiet):
        """Burst loss ``loss`` on every link for ``duration`` sim s (None: until changed)."""
        if not (math.isfinite(loss) and 0.0 <= loss <= 1.0):
            raise ValueError(f'loss {loss!r} rejected: must be in [0, 1]')
        if duration is not None and not (math.isfinite(duration) and duration > 0.0):
            raise ValueError(f'--for {duration!r} rejected: must be a positive number of sim seconds')
        return self.publish_event('drop', dict(loss=loss, duration=duration), wait, prog=prog, say=say)

    def partition(self, groups, wait: float = 10.0, prog='swarm partition', say=_quiet):
        """Groups of agents that cannot hear each other (``[]`` heals)."""
        groups = check_partition(groups)
        return self.publish_event('partition', dict(groups=groups), wait,
                                  check_names=[nm for g in groups for nm in g], prog=prog, say=say)
