"""``swarm record``: record a running swarm (every topic, or a chosen set) to an MCAP bag.

The recorder finds topics itself: it polls the ROS graph, and for each new topic with a
publisher it subscribes with raw (serialized) messages, asking for the QoS the publishers offer
(reliable if all offer reliable, transient-local if all offer it: latched messages are then
received too), as rosbag2 does.  Messages are written as they arrive (log time = receive time)
by `swarm_tools.bag.BagWriter`.  SIGINT / SIGTERM / ``--duration`` end the recording with a
complete, indexed file; the recorder then prints, per topic, messages received vs written.
"""
from __future__ import annotations

import argparse
import importlib
import re
import signal
import sys
import time

from .bag import BagWriter, DefinitionNotFound, qos_dict

#: the graph is polled this often for new topics and publishers (seconds)
POLL_PERIOD = 0.2
#: subscription depth: deep enough that a lockstep burst of many agents is never dropped
SUB_DEPTH = 1000


def message_class(type_name: str):
    """The Python class of a ROS message type name (``pkg/msg/Type``)."""
    pkg, ns, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{ns}'), name)


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


class Recorder:
    """Subscribes to the selected topics as they appear and writes what arrives."""

    def __init__(self, node, writer: BagWriter, wanted: TopicFilter, log=print):
        self.node = node
        self.writer = writer
        self.wanted = wanted
        self.log = log
        self.received: dict[str, int] = {}
        self.failed: dict[str, int] = {}
        self.subs = {}
        self.skipped: set[str] = set()
        self.timer = node.create_timer(POLL_PERIOD, self.poll)

    def poll(self):
        try:
            names = self.node.get_topic_names_and_types()
        except Exception:       # the context is going down
            return
        for topic, types in names:
            if topic in self.subs or topic in self.skipped or not self.wanted(topic):
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            infos = [i for i in infos if i.node_name != self.node.get_name()
                     or i.node_namespace != self.node.get_namespace()]
            if not infos:
                continue        # only subscribers so far: wait for a publisher's offer
            type_name = infos[0].topic_type if infos[0].topic_type else types[0]
            try:
                cls = message_class(type_name)
                profiles = offered_profiles([i for i in infos if i.topic_type == type_name])
                self.writer.add_topic(topic, type_name, profiles)
            except (ImportError, AttributeError, ValueError, DefinitionNotFound) as err:
                self.log(f'swarm record: skipping {topic} ({type_name}): {err}')
                self.skipped.add(topic)
                continue
            self.received[topic] = 0
            self.failed[topic] = 0
            self.subs[topic] = self.node.create_subscription(
                cls, topic, self._callback(topic), request_qos(profiles), raw=True)

    def _callback(self, topic):
        writer = self.writer
        received = self.received

        def on_message(data):
            now = time.time_ns()
            received[topic] += 1
            try:
                writer.write(topic, data, now)
            except Exception as err:   # keep recording the rest; counted as lost
                self.failed[topic] += 1
                if self.failed[topic] == 1:
                    self.log(f'swarm record: write failed on {topic}: {err}')
        return on_message

    def summary(self) -> list[tuple[str, int, int]]:
        return [(t, self.received[t], self.writer.topics[t].written) for t in sorted(self.received)]


def parse_args(argv):
    p = argparse.ArgumentParser(
        prog='swarm record',
        description='Record a running swarm to an MCAP bag (rosbag2 layout: profile ros2, '
                    'ros2msg schemas, cdr messages, offered QoS per topic, zstd chunks). '
                    'Ctrl-C (SIGINT) or SIGTERM ends it with a complete, indexed file.')
    p.add_argument('--out', '-o', required=True, help='the .mcap file to write')
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
    p.add_argument('--quiet', '-q', action='store_true', help='no per-topic summary')
    a = p.parse_args(argv)
    if a.duration is not None and not a.duration > 0:
        p.error('--duration must be > 0')
    if not a.out.endswith('.mcap'):
        p.error('--out must name a .mcap file')
    return a


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    stop = {'why': None}

    def on_signal(signum, _frame):
        stop['why'] = signal.Signals(signum).name

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('swarm_recorder', enable_rosout=False,
                             start_parameter_services=False)
    writer = BagWriter(args.out, chunk_size=args.chunk_size, flush_interval=args.flush_interval)
    rec = Recorder(node, writer, TopicFilter(args.topics, args.exclude),
                   log=lambda s: print(s, file=sys.stderr, flush=True))
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    print(f'swarm record: recording to {args.out}', file=sys.stderr, flush=True)
    t_end = time.monotonic() + args.duration if args.duration else None
    try:
        rec.poll()
        while stop['why'] is None:
            executor.spin_once(timeout_sec=0.1)
            writer.maybe_flush()
            if t_end is not None and time.monotonic() >= t_end:
                stop['why'] = 'duration'
        # take what is already delivered before closing
        drain_until = time.monotonic() + 0.3
        while time.monotonic() < drain_until:
            executor.spin_once(timeout_sec=0.05)
    finally:
        for sub in list(rec.subs.values()):
            node.destroy_subscription(sub)
        writer.close()
        executor.shutdown()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    rows = rec.summary()
    lost = sum(r - w for _, r, w in rows)
    if not args.quiet:
        width = max([len(t) for t, _, _ in rows] + [5])
        print(f'swarm record: stopped ({stop["why"]}); {args.out}')
        print(f'  {"topic":<{width}}  received   written')
        for t, r, w in rows:
            print(f'  {t:<{width}}  {r:>8}  {w:>8}')
        print(f'  {"total":<{width}}  {sum(r for _, r, _ in rows):>8}  '
              f'{sum(w for _, _, w in rows):>8}   lost: {lost}', flush=True)
    return 0 if lost == 0 else 1


if __name__ == '__main__':
    sys.exit(main())
