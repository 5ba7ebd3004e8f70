"""``swarm play BAG.mcap``: republish a recorded run with its ``/clock``.

Every topic is republished with the QoS it was recorded with (``offered_qos_profiles``:
latched topics are offered transient-local again, so a late RViz / Foxglove still gets the
target and the barrier).  The time base is the run's sim time: the stamps of the stamped
messages (``header.stamp``, ``rosgraph_msgs/Clock``) in the order they were received.  Play is
paced so that sim time advances ``--rate`` times as fast as wall time, and ``/clock`` follows:
the bag's own ``/clock`` messages if it has them, otherwise a ``/clock`` published at every
advance of the stamps of the bag's busiest stamped topic (``/swarm/states`` in a swarm run).
Nodes watching with ``use_sim_time`` see the run as it happened.  SIGINT / SIGTERM stop the
play between two messages; the summary is printed as usual.

A topic is played with one type: the project's for its own topics (`record.swarm_type`; a 3D
run's, by its ``/swarm/run`` announcement, has (s_u, s_v) steering),
else its first channel's; messages on its channels of another type are not played
(`foreign_lines`).
"""
from __future__ import annotations

import argparse
import signal
import sys
import time

from swarm_ros.rosutil import stop_on_signals
from swarm_tools.bags.mcap_io import announced_dim, bag_topics, iter_messages, replay_qos, resolve_bag
from swarm_tools.bags.msgdefs import has_leading_stamp, leading_stamp_ns
from swarm_tools.bags.record import message_class, swarm_type

CLOCK = '/clock'


def parse_args(argv):
    p = argparse.ArgumentParser(
        prog='swarm play',
        description='Republish an MCAP bag (recorded QoS, latched as latched) with /clock '
                    'driven from the bag\'s sim time, paced by --rate.')
    p.add_argument('bag', help='an .mcap file or a bag directory (DIR/metadata.yaml + DIR/DIR_0.mcap)')
    p.add_argument('--rate', '-r', type=float, default=1.0,
                   help='sim seconds per wall second (default 1; e.g. 20 to watch a long run)')
    p.add_argument('--loop', '-l', action='store_true', help='start again at the end')
    p.add_argument('--topics', nargs='+', metavar='TOPIC', help='republish only these topics')
    p.add_argument('--delay', type=float, default=0.5,
                   help='wall seconds to wait after creating the publishers (discovery; default 0.5)')
    p.add_argument('--wait-for-subscribers', type=float, default=0.0, metavar='SECONDS',
                   help='wait up to this long until every non-latched topic has a subscriber (default 0: do not wait)')
    p.add_argument('--quiet', '-q', action='store_true', help='no per-topic summary at the end')
    a = p.parse_args(argv)
    if not (a.rate > 0) or a.rate == float('inf'):
        p.error('--rate must be a positive number')
    if a.delay < 0 or a.wait_for_subscribers < 0:
        p.error('--delay / --wait-for-subscribers must be ≥ 0')
    return a


def foreign_lines(topics: dict, dim: int = 2) -> list[str]:
    """One line per topic with channels of a type not its own (`swarm_tools.bags.mcap_io.bag_topics`: for the
    project's topics, not the project's type): their messages are not played."""
    out = []
    for topic, info in sorted(topics.items()):
        if info['other']:
            what = ', '.join(f'{n} messages of type {k or "?"}' for k, n in sorted(info['other'].items()))
            own = swarm_type(topic, dim)
            want = f'the project\'s {topic} is {own}' if own else f'{topic} is {info["type"]}'
            out.append(f'{topic}: not playing {what} ({want})')
    return out


def _topics_to_play(a) -> dict | None:
    """`swarm_tools.bags.mcap_io.bag_topics` of the bag, those of ``--topics``, with a type to play; None (said
    in one line) if there are none."""
    try:
        a.bag = str(resolve_bag(a.bag))
        dim = announced_dim(a.bag)          # a 3D run's steering topics carry (s_u, s_v)
        topics = bag_topics(a.bag, lambda topic: swarm_type(topic, dim))
    except OSError as err:
        print(f'swarm play: {err}', file=sys.stderr)
        return None
    if a.topics:
        topics = {t: v for t, v in topics.items() if t in set(a.topics)}
    for line in foreign_lines(topics, dim):
        print(f'swarm play: {line}', file=sys.stderr)
    topics = {t: v for t, v in topics.items() if v['type'] is not None}
    if not topics:
        print(f'swarm play: {a.bag}: no topics to play', file=sys.stderr)
    return topics or None


def make_qos(spec: dict):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=max(1, int(spec['depth'])),
        reliability=(ReliabilityPolicy.RELIABLE if spec['reliability'] == 'reliable'
                     else ReliabilityPolicy.BEST_EFFORT),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if spec['durability'] == 'transient_local'
                    else DurabilityPolicy.VOLATILE))


def main(argv=None) -> int:
    a = parse_args(sys.argv[1:] if argv is None else argv)
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    topics = _topics_to_play(a)
    if not topics:
        return 2

    # SIGINT / SIGTERM only set a flag (``stop``): play ends between two messages and cleans up
    stop, _, restore_signals = stop_on_signals()
    rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('swarm_player', enable_rosout=False, start_parameter_services=False)
    pubs, stamped, specs = {}, {}, {}
    try:
        for topic, info in topics.items():
            try:
                cls = message_class(info['type'])
            except (ImportError, AttributeError, ValueError) as err:
                print(f'swarm play: skipping {topic} ({info["type"]}): {err}', file=sys.stderr)
                continue
            specs[topic] = replay_qos(info['qos'])
            pubs[topic] = node.create_publisher(cls, topic, make_qos(specs[topic]))
            stamped[topic] = has_leading_stamp(info['definition'], info['type'])
        # the time base: the bag's /clock, else its busiest stamped topic
        base = [t for t in pubs if t == CLOCK] or sorted(
            (t for t in pubs if stamped[t]), key=lambda t: -topics[t]['count'])[:1]
        for t in stamped:
            stamped[t] = bool(base) and t == base[0]
        clock_pub = None
        if CLOCK not in topics:
            from rosgraph_msgs.msg import Clock
            clock_pub = node.create_publisher(Clock, CLOCK, 10)
        volatile = [p for t, p in pubs.items() if specs[t]['durability'] != 'transient_local']
        if clock_pub is not None:
            volatile.append(clock_pub)
        t_wait = time.monotonic() + a.wait_for_subscribers
        while (not stop and time.monotonic() < t_wait
               and not all(p.get_subscription_count() > 0 for p in volatile)):
            time.sleep(0.05)
        t_delay = time.monotonic() + a.delay
        while not stop and time.monotonic() < t_delay:
            time.sleep(0.02)
        counts = {t: 0 for t in pubs}
        loops = 0
        while not stop:
            _play_once(a, pubs, stamped, clock_pub, counts, stop, {t: topics[t]['channels'] for t in pubs})
            loops += 1
            if not a.loop:
                break
        # reliable subscribers get the tail of the bag before the publishers go away
        from rclpy.duration import Duration
        t_acked = time.monotonic() + 2.0
        for p in list(pubs.values()) + ([clock_pub] if clock_pub is not None else []):
            left = t_acked - time.monotonic()
            if left <= 0 or stop:
                break
            p.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
        restore_signals()
    if not a.quiet:
        print(f'swarm play: {a.bag}: {loops} pass(es)' +
              (f', stopped ({signal.Signals(stop[0]).name})' if stop else ''))
        for t in sorted(counts):
            print(f'  {t}: {counts[t]} messages')
    return 0


def _play_once(a, pubs, stamped, clock_pub, counts, stop, channels):
    clock_msg = None
    if clock_pub is not None:
        from rosgraph_msgs.msg import Clock
        clock_msg = Clock()
    sim0 = None
    sim_now = None
    wall0 = None
    for m in iter_messages(a.bag, topics=list(pubs)):
        if stop:
            return
        if m.channel.id not in channels[m.topic]:
            continue            # a channel of another type on the topic (`foreign_lines`)
        stamp = leading_stamp_ns(m.data) if stamped[m.topic] else None
        if stamp is not None and (sim_now is None or stamp > sim_now):
            sim_now = stamp
            if sim0 is None:
                sim0, wall0 = sim_now, time.monotonic()
            due = wall0 + (sim_now - sim0) * 1e-9 / a.rate
            while not stop:
                left = due - time.monotonic()
                if left <= 0:
                    break
                time.sleep(min(left, 0.05))
            if clock_msg is not None:
                clock_msg.clock.sec, clock_msg.clock.nanosec = divmod(sim_now, 1_000_000_000)
                clock_pub.publish(clock_msg)
        pubs[m.topic].publish(bytes(m.data))
        counts[m.topic] += 1


if __name__ == '__main__':
    sys.exit(main())
