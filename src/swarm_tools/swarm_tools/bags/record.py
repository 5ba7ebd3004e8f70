"""``swarm record``: record a running swarm (every topic, or a chosen set) to an MCAP bag.

The recorder finds topics itself: it polls the ROS graph, and for each new topic with a
publisher it subscribes with raw (serialized) messages, asking for the QoS the publishers offer
(reliable if all offer reliable, transient-local if all offer it: latched messages are then
received too), as rosbag2 does.  Messages are written as they arrive by
`swarm_tools.bags.mcap_io.BagWriter`, with rosbag2's times: log time = receive time, publish time
= send time (the rmw's received / source timestamps, wall time); sim time is in the header stamps.
``--out X.mcap`` writes one file; ``--out DIR`` a rosbag2 bag directory (``DIR/DIR_0.mcap`` and
``DIR/metadata.yaml``).  SIGINT / SIGTERM / ``--duration`` end the recording with a
complete, indexed file; the recorder then prints, per topic, messages received vs written.

No writer ends the recording.  A topic is recorded with one type: the project's own for its
topics (`swarm_type`), else the first type seen.  A writer of another type on it (a stray or
hostile peer) is not recorded, and never makes the recorder drop the topic's own writers: it
is counted, logged once and named in the summary.  A message or a writer that a callback or
a look at the graph cannot handle is counted and logged the same way, and the recording goes on.
"""
from __future__ import annotations

import argparse
import importlib
import inspect
import os
import re
import signal
import sys
import time
from types import SimpleNamespace

from swarm_ros import protocol as P
from swarm_ros.msg_checks import RejectLog, guard_subscriptions
from swarm_ros.rosutil import make_executor, stop_on_signals
from swarm_tools.bags.mcap_io import BagWriter, bag_paths, parse_odometry, qos_dict
from swarm_tools.bags.msgdefs import DefinitionNotFound, _msg_file

#: the graph is polled this often for new topics and publishers (seconds)
POLL_PERIOD = 0.2
#: subscription depth: the reader holds every message that waits for the recorder's thread, as
#: many as the publishers still hold (1000 agents' states at protocol.STATES_DEPTH each), so a
#: recorder starved of CPU for a while (a realtime run at a high rtf on a busy machine) loses
#: nothing when it catches up; a lockstep burst of many agents neither.  Memory is taken only
#: for the messages that wait.
SUB_DEPTH = 100_000


#: a message type name as it may come from the graph or a bag: ``pkg/msg/Type`` only
MESSAGE_TYPE = re.compile(r'([a-z][a-z0-9_]{0,63})/msg/([A-Z][A-Za-z0-9]{0,63})')


def message_class(type_name: str):
    """The Python class of a ROS message type name (``pkg/msg/Type``).

    The name comes from data (the DDS graph, a bag's schema), so nothing is imported unless
    it matches `MESSAGE_TYPE` and ``pkg`` is an installed interface package with that
    message (``share/pkg/msg/Type.msg``); ValueError otherwise."""
    m = MESSAGE_TYPE.fullmatch(type_name) if isinstance(type_name, str) else None
    if m is None:
        raise ValueError(f'{type_name!r}: not a pkg/msg/Type message name')
    pkg, name = m.groups()
    try:
        _msg_file(type_name)
    except DefinitionNotFound:
        raise ValueError(f'{type_name}: no installed interface package defines it') from None
    cls = getattr(importlib.import_module(f'{pkg}.msg'), name)
    if not hasattr(type(cls), '_TYPE_SUPPORT'):
        raise ValueError(f'{type_name}: not a ROS message class')
    return cls


def offered_profiles(infos) -> list[dict]:
    """rosbag2-style QoS dicts of the publishers (``TopicEndpointInfo``) of a topic."""
    out = []
    for info in infos:
        q = info.qos_profile
        out.append(qos_dict(
            history=int(q.history), depth=int(q.depth), reliability=int(q.reliability),
            durability=int(q.durability), deadline_ns=q.deadline.nanoseconds,
            lifespan_ns=q.lifespan.nanoseconds, liveliness=int(q.liveliness),
            liveliness_lease_ns=q.liveliness_lease_duration.nanoseconds,
            avoid_ros_namespace_conventions=q.avoid_ros_namespace_conventions))
    return out


def request_qos(profiles: list[dict]):
    """The subscription QoS that matches every offer (rosbag2's adapt_request_to_offers)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    reliable = all(p['reliability'] == 'reliable' for p in profiles)
    latched = bool(profiles) and all(p['durability'] == 'transient_local' for p in profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=SUB_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class TopicFilter:
    """``--topics`` (exact names; default all) minus ``--exclude`` (names or regexes)."""

    def __init__(self, topics=None, exclude=None):
        self.topics = set(topics or [])
        self.exclude = [re.compile(p) for p in (exclude or [])]

    def __call__(self, topic: str) -> bool:
        if self.topics and topic not in self.topics:
            return False
        return not any(p.fullmatch(topic) or p.pattern == topic for p in self.exclude)


#: the message type of each of the project's fixed topics (docs/ros-graph.md)
SWARM_TYPES = {
    '/swarm/states': 'nav_msgs/msg/Odometry', '/swarm/lambda': 'std_msgs/msg/Float64',
    '/swarm/leaders': 'std_msgs/msg/String', '/swarm/events': 'std_msgs/msg/String',
    '/swarm/fault_request': 'std_msgs/msg/String', '/swarm/run': 'std_msgs/msg/String',
    '/commander/lambda_setpoint': 'std_msgs/msg/Float64MultiArray',
    '/clock': 'rosgraph_msgs/msg/Clock', '/world/target': 'geometry_msgs/msg/PointStamped',
    '/world/barrier': 'geometry_msgs/msg/PolygonStamped',
    '/world/markers': 'visualization_msgs/msg/MarkerArray',
    '/world/metrics': 'diagnostic_msgs/msg/DiagnosticArray',
    '/lockstep/command': 'std_msgs/msg/String',
    '/lockstep/step': 'std_msgs/msg/Float64MultiArray',
    '/lockstep/agent_states': 'std_msgs/msg/Float64MultiArray',
    '/lockstep/robot_states': 'std_msgs/msg/Float64MultiArray',
    '/swarm/agent_states': 'std_msgs/msg/Float64MultiArray',
    '/swarm/decision': 'std_msgs/msg/Float64MultiArray',
}


#: an agent's ``/NAME/steering``: a curvature, or (s_u, s_v) in a 3D run
STEERING_TYPES = {2: 'std_msgs/msg/Float64', 3: 'std_msgs/msg/Float64MultiArray'}


def swarm_type(topic: str, dim: int = 2) -> str | None:
    """The type of one of the project's topics (an agent's ``/NAME/steering`` included: in a
    run of ``dim`` dimensions), or None for a topic that is not the project's."""
    if re.fullmatch(r'/[^/]+/steering', topic):
        return STEERING_TYPES[dim]
    return SWARM_TYPES.get(topic)


#: the project's fixed topics whose first messages matter (docs/ros-graph.md), with the durability
#: their publishers offer (rmw enum: 1 transient-local, 2 volatile): subscribed at start-up,
#: before any publisher exists, with the QoS the publishers will offer, so that step 0 of a
#: run is not missed while the graph is polled and no subscription has to be made again (a
#: re-made subscription can lose what the old one had not yet taken).  If the publishers turn
#: out to offer other QoS or another type, the subscription is re-made.
SWARM_TOPICS = {topic: (SWARM_TYPES[topic], durability) for topic, durability in (
    ('/swarm/states', 1), ('/swarm/events', 1), ('/swarm/lambda', 1), ('/clock', 2),
    ('/world/markers', 2), ('/world/metrics', 2))}


def presubscribed(agents=(), dim: int = 2) -> dict:
    """`SWARM_TOPICS` and the steering topic of each of ``agents`` (latched, as the commander
    offers it): subscribed at start-up, before the run's nodes exist.  Found in the graph later,
    a hundred steering topics cost the recorder one poll of 80-180 ms of CPU, at a time when a
    realtime run's clock may already be running."""
    steering = {P.steering_topic(nm): (swarm_type(P.steering_topic(nm), dim), 1) for nm in agents}
    return {**SWARM_TOPICS, **steering}


def command_topic(topic: str) -> bool:
    """λ and steering: the commander publishes what is in force (transient-local) and is the
    only VOLATILE reader, so that a one-shot ``ros2 topic pub`` matches only the commander
    (docs/commands.md).  The recorder reads the commander's offers only; the commands
    themselves are recorded as ``command`` events on /swarm/events."""
    return topic == '/swarm/lambda' or re.fullmatch(r'/[^/]+/steering', topic) is not None


def _qos_key(q):
    return (int(q.reliability), int(q.durability))


def _compatible(sub_qos, infos) -> bool:
    """Whether a subscription's QoS matches every offer (reliability, durability)."""
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
    for i in infos:
        q = i.qos_profile
        if (sub_qos.reliability == ReliabilityPolicy.RELIABLE
                and q.reliability != ReliabilityPolicy.RELIABLE):
            return False
        if (sub_qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
                and q.durability != DurabilityPolicy.TRANSIENT_LOCAL):
            return False
    return True


class Recorder:
    """Subscribes to the selected topics as they appear and writes what arrives.

    A topic's channel is registered with the publishers' offered QoS when the first publisher
    is seen (or when the first message arrives, whichever comes first)."""

    def __init__(self, node, writer: BagWriter, wanted: TopicFilter, log=print,
                 presubscribe: dict | None = None):
        self.node = node
        self.writer = writer
        self.wanted = wanted
        self.log = log
        self.received: dict[str, int] = {}
        self.failed: dict[str, int] = {}
        self.subs = {}
        self.sub_type: dict[str, str] = {}
        self.skipped: set[str] = set()
        self.dim = 2                 # the run's dimensions (its steering topics' type: `swarm_type`)
        self.states: dict[str, set] = {}
        self.write_error: OSError | None = None      # the disk is full or gone: the recording ends
        self.said_commands = False   # the line about commands' writers (`_events`) was said
        #: what could not be recorded (writers of another type, messages, looks at the graph), counted
        self.reject = RejectLog(SimpleNamespace(warning=lambda line: log(f'swarm record: {line}')))
        self.foreign: dict[str, dict[str, set]] = {}   # topic -> {another type: its writers' gids}
        for topic, (type_name, durability) in (presubscribe or {}).items():
            if wanted(topic):
                self._subscribe(topic, type_name, request_qos([qos_dict(reliability=1, durability=durability)]))
        self.timer = node.create_timer(POLL_PERIOD, self.poll)

    def _publishers(self, topic):
        infos = self.node.get_publishers_info_by_topic(topic)
        return [i for i in infos if i.node_name != self.node.get_name()
                or i.node_namespace != self.node.get_namespace()]

    def _subscribe(self, topic, type_name, qos):
        try:
            cls = message_class(type_name)
            self.writer.definition(type_name)
        except (ImportError, AttributeError, ValueError, DefinitionNotFound) as err:
            self.log(f'swarm record: skipping {topic} ({type_name}): {err}')
            self.skipped.add(topic)
            return
        old = self.subs.pop(topic, None)
        if old is not None:
            self.node.destroy_subscription(old)
        self.received.setdefault(topic, 0)
        self.failed.setdefault(topic, 0)
        self.sub_type[topic] = type_name
        try:
            self.subs[topic] = self.node.create_subscription(
                cls, topic, self._callback(topic), qos, raw=True, event_callbacks=self._events(topic))
        except Exception as err:     # rclpy refuses it (e.g. this node writes the topic with another type)
            self.reject(f'subscribe:{topic}', f'{topic} ({type_name}): cannot subscribe ({str(err)[:120]}); '
                        'not recorded')
            self.skipped.add(topic)
            return
        guard_subscriptions(self.node, self.reject)

    def _events(self, topic):
        """λ and steering (`command_topic`): a command's writer (volatile: ``ros2 topic pub``,
        ``swarm steer``) does not match the reader of the commander's transient-local output, by
        design; said once in one info line, not as rclpy's incompatible-QoS warning per writer."""
        if not command_topic(topic):
            return None
        from rclpy.event_handler import SubscriptionEventCallbacks

        def incompatible(_status):
            if not self.said_commands:
                self.said_commands = True
                self.log(f'swarm record: a command on {topic} (a volatile writer) is recorded as a command event '
                         f'on {P.EVENTS}; {P.LAMBDA} and the steering topics keep what the commander publishes')
        return SubscriptionEventCallbacks(incompatible_qos=incompatible)

    def _register(self, topic, infos=None):
        """Create the bag channel (once) with the offers known now."""
        if topic in self.writer.topics:
            return
        type_name = self.sub_type[topic]
        if infos is None:
            infos = self._publishers(topic)
        profiles = offered_profiles([i for i in infos if i.topic_type == type_name])
        self.writer.add_topic(topic, type_name, profiles)

    def topic_type(self, topic, infos, types) -> str:
        """The one type ``topic`` is recorded with: the project's own for its topics
        (`swarm_type`), else the type it was subscribed with, else its first writer's."""
        return swarm_type(topic, self.dim) or self.sub_type.get(topic) or infos[0].topic_type or types[0]

    def _note_foreign(self, topic, type_name, infos):
        """Count and log (once per writer) the writers of ``topic`` of another type than
        ``type_name``: they are not recorded."""
        for i in infos:
            if i.topic_type == type_name:
                continue
            seen = self.foreign.setdefault(topic, {}).setdefault(i.topic_type, set())
            gid = bytes(bytearray(i.endpoint_gid))
            if gid not in seen:
                seen.add(gid)
                self.reject(f'other-type:{topic}', f'{topic}: a writer of {i.topic_type} (node '
                            f'{i.node_namespace.rstrip("/")}/{i.node_name}), not {type_name}: not recorded')

    def poll(self):
        """Look at the graph for new topics and writers (a timer); whatever it cannot handle
        is counted and logged, and the next look goes on."""
        try:
            self._poll()
        except Exception as err:
            self.reject('poll', f'a look at the graph failed ({type(err).__name__}: {str(err)[:120]})')

    def _poll(self):
        self._polls = getattr(self, '_polls', 0) + 1
        recheck = self._polls % 5 == 0          # about once a second
        try:
            names = self.node.get_topic_names_and_types()
        except Exception:       # the context is going down
            return
        for topic, types in names:
            if topic in self.skipped or not self.wanted(topic):
                continue
            settled = topic in self.subs and topic in self.writer.topics
            if settled and (not recheck or self._all_matched(topic)):
                continue
            infos = self._publishers(topic)
            if not infos:
                continue        # only subscribers so far: wait for a publisher's offer
            type_name = self.topic_type(topic, infos, types)
            same = [i for i in infos if i.topic_type == type_name]
            if len(same) < len(infos):
                self._note_foreign(topic, type_name, infos)
            if not same:
                continue        # writers of another type only: wait for one of the topic's own
            if command_topic(topic):
                latched = [i for i in same if int(i.qos_profile.durability) == 1]
                same = latched or same
            want = request_qos(offered_profiles(same))
            if settled:
                # a publisher that joined later with an offer the subscription cannot match
                # (best effort, or volatile on a latched topic): subscribe again, as it asks.
                # (Never the other way: a working subscription is left alone.)
                have = self.subs[topic].qos_profile
                if type_name == self.sub_type[topic] and not _compatible(have, same):
                    self.log(f'swarm record: {topic}: mixed QoS offers, subscribing again '
                             'as best effort / volatile')
                    self._subscribe(topic, type_name, want)
                continue
            if topic not in self.subs:
                self._subscribe(topic, type_name, want)
            elif topic not in self.writer.topics and (
                    self.sub_type[topic] != type_name
                    or _qos_key(self.subs[topic].qos_profile) != _qos_key(want)):
                # a pre-subscription that does not match the offers: make it again
                self._subscribe(topic, type_name, want)
            if topic in self.subs:
                self._register(topic, infos)

    def _all_matched(self, topic) -> bool:
        """Is every publisher of ``topic`` matched by its subscription?  Then a recheck has
        nothing to find.  Two counts, not every publisher's info: the infos of a hundred topics
        cost a poll 20-50 ms of CPU once a second, in bursts a realtime run's agents feel."""
        return self.node.count_publishers(topic) <= self.subs[topic].get_publisher_count()

    def _callback(self, topic):
        writer = self.writer
        received = self.received
        track = topic == '/swarm/states' and self.sub_type.get(topic) == 'nav_msgs/msg/Odometry'

        def on_message(*args):
            # (data, info); rclpy's EventsExecutor (events_executor.cpp, HandleSubscriptionReady)
            # passes the pair as one tuple
            data, info = args if len(args) == 2 else args[0]
            now = info.get('received_timestamp') or time.time_ns()
            received[topic] += 1
            if track:
                self._track_state(data)
            try:
                if topic not in writer.topics:
                    self._register(topic)
                writer.write(topic, data, now, info.get('source_timestamp'))
            except OSError as err:
                self.failed[topic] += 1
                self.write_error = self.write_error or err
            except Exception as err:   # keep recording the rest; counted as lost
                self.failed[topic] += 1
                if self.failed[topic] == 1:
                    self.log(f'swarm record: write failed on {topic}: {err}')
        # two parameters: rclpy passes the message info (send and receive time stamps) too
        on_message.__signature__ = inspect.Signature(
            [inspect.Parameter(n, inspect.Parameter.POSITIONAL_ONLY) for n in ('data', 'info')])
        return on_message

    def _track_state(self, data):
        try:
            o = parse_odometry(data)
        except Exception:
            return
        self.states.setdefault(o['child_frame_id'], set()).add(o['stamp_ns'])

    def state_gaps(self) -> dict:
        """Per agent on /swarm/states: states received and states missing between its first
        and last stamp (from the smallest stamp step seen): messages DDS never delivered."""
        out = {}
        steps = []
        for st in self.states.values():
            a = sorted(st)
            steps += [b - c for b, c in zip(a[1:], a) if b > c]
        if not steps:
            return {name: (len(st), 0) for name, st in self.states.items()}
        step = min(steps)
        for name, st in self.states.items():
            a = sorted(st)
            expected = round((a[-1] - a[0]) / step) + 1
            out[name] = (len(a), max(0, expected - len(a)))
        return out

    def refused_lines(self) -> list[str]:
        """What was not recorded, in lines: each topic's writers of another type, and the
        count of everything refused (`reject`)."""
        own = lambda topic: self.sub_type.get(topic) or swarm_type(topic, self.dim)     # noqa: E731
        lines = [f'{topic}: {sum(len(g) for g in by_type.values())} writer(s) of another type '
                 f'({", ".join(sorted(by_type))}) not recorded; {own(topic)} '
                 'recorded' for topic, by_type in sorted(self.foreign.items())]
        return lines + ([self.reject.summary()] if self.reject.count else [])

    def summary(self) -> list[tuple[str, int, int]]:
        return [(t, self.received[t],
                 self.writer.topics[t].written if t in self.writer.topics else 0)
                for t in sorted(self.received) if t in self.writer.topics or self.received[t]]


def parse_args(argv):
    p = argparse.ArgumentParser(
        prog='swarm record',
        description='Record a running swarm to an MCAP bag (rosbag2 layout: profile ros2, '
                    'ros2msg schemas, cdr messages, offered QoS per topic, zstd chunks). '
                    'Ctrl-C (SIGINT) or SIGTERM ends it with a complete, indexed file.')
    p.add_argument('--out', '-o', required=True,
                   help='X.mcap: one file; DIR: a rosbag2 bag directory (DIR/DIR_0.mcap and '
                        'DIR/metadata.yaml; DIR must not exist yet)')
    p.add_argument('--topics', nargs='+', metavar='TOPIC',
                   help='record only these topics (default: every topic with a publisher)')
    p.add_argument('--exclude', nargs='+', metavar='PATTERN', default=[],
                   help='topics not to record (exact names or regular expressions)')
    p.add_argument('--duration', type=float, default=None,
                   help='stop after this many (wall-clock) seconds')
    p.add_argument('--chunk-size', type=int, default=64 * 1024,
                   help='MCAP chunk size in bytes (default 64 KiB; small chunks survive a crash)')
    p.add_argument('--flush-interval', type=float, default=0.5,
                   help='close the open chunk at least this often, in seconds (default 0.5)')
    p.add_argument('--no-presubscribe', action='store_true',
                   help="do not subscribe to the swarm's fixed topics before they have publishers")
    p.add_argument('--agents', nargs='+', metavar='NAME', default=[],
                   help="the run's agents: their /NAME/steering topics are subscribed at start-up too "
                        '(swarm run passes its roster)')
    p.add_argument('--dim', type=int, choices=(2, 3), default=2,
                   help="the run's dimensions: its steering topics carry (s_u, s_v) in 3D (swarm run passes it)")
    p.add_argument('--quiet', '-q', action='store_true', help='no per-topic summary')
    a = p.parse_args(argv)
    if a.duration is not None and not a.duration > 0:
        p.error('--duration must be > 0')
    if not a.out.endswith('.mcap') and os.path.exists(a.out):
        p.error(f'--out {a.out}: already exists (a bag directory must be new)')
    return a


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    try:
        mcap_path, metadata_yaml = bag_paths(args.out)
        writer = BagWriter(mcap_path, chunk_size=args.chunk_size, flush_interval=args.flush_interval,
                           metadata_yaml=metadata_yaml)
    except OSError as err:
        print(f'swarm record: cannot write {args.out}: {err.strerror or err}', file=sys.stderr)
        return 2
    # SIGINT / SIGTERM only set a flag: the loop below ends, drains and closes the bag
    stop, _, restore_signals = stop_on_signals()
    rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('swarm_recorder', enable_rosout=False,
                             start_parameter_services=False)
    rec = Recorder(node, writer, TopicFilter(args.topics, args.exclude),
                   log=lambda s: print(s, file=sys.stderr, flush=True),
                   presubscribe=None if args.no_presubscribe else presubscribed(args.agents, args.dim))
    rec.dim = args.dim
    executor = make_executor(node.context)      # the EventsExecutor: ~10x cheaper per message (measured)
    executor.add_node(node)
    print(f'swarm record: ready, recording to {args.out}', file=sys.stderr, flush=True)
    t_end = time.monotonic() + args.duration if args.duration else None
    why = None
    try:
        rec.poll()
        while why is None and rec.write_error is None:
            executor.spin_once(timeout_sec=0.1)
            writer.maybe_flush()
            if stop:
                why = signal.Signals(stop[0]).name
            elif t_end is not None and time.monotonic() >= t_end:
                why = 'duration'
        # take what is already delivered before closing
        drain_until = time.monotonic() + 0.3
        while time.monotonic() < drain_until and rec.write_error is None:
            executor.spin_once(timeout_sec=0.05)
        if rec.write_error is None:
            writer.close()
    except OSError as err:
        rec.write_error = rec.write_error or err
    finally:
        for sub in list(rec.subs.values()):
            node.destroy_subscription(sub)
        if rec.write_error is not None:
            writer.abort()
        writer.close()
        executor.shutdown()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
        restore_signals()
    if rec.write_error is not None:
        err = rec.write_error
        print(f'swarm record: cannot write {args.out}: {err.strerror or err}; the recording stopped '
              '(the bag keeps what was written before; `swarm bag recover` makes it whole)',
              file=sys.stderr, flush=True)
        return 1
    return _report(args, rec, why)


def _report(args, rec, why) -> int:
    """The recorder's exit: per topic, messages received and written; 1 if any was lost."""
    rows = rec.summary()
    lost = sum(r - w for _, r, w in rows)
    if not args.quiet:
        width = max([len(t) for t, _, _ in rows] + [5])
        print(f'swarm record: stopped ({why}); {args.out}')
        print(f'  {"topic":<{width}}  received   written')
        for t, r, w in rows:
            print(f'  {t:<{width}}  {r:>8}  {w:>8}')
        print(f'  {"total":<{width}}  {sum(r for _, r, _ in rows):>8}  '
              f'{sum(w for _, _, w in rows):>8}   lost: {lost}', flush=True)
        gaps = rec.state_gaps()
        if gaps:
            missing = sum(m for _, m in gaps.values())
            counts = [c for c, _ in gaps.values()]
            print(f'  /swarm/states: {len(gaps)} agents, {min(counts)}..{max(counts)} states each, '
                  f'missing between first and last: {missing}', flush=True)
    for line in rec.refused_lines():        # said even with --quiet: what the bag does not hold
        print(f'  {line}', flush=True)
    return 0 if lost == 0 else 1


if __name__ == '__main__':
    sys.exit(main())
