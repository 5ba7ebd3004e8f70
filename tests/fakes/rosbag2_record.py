"""An emulation of ``ros2 bag record -a [--qos-profile-overrides-path FILE]`` (ROS 2 Jazzy) that
counts what it receives instead of writing it.  Used by tests/tools/bags/ (test_bag_qos.py,
ros/test_bag_qos_recorder.py) and scripts/bench_bag_qos.py; run it as a process and stop it
with SIGINT: it then prints one JSON line (per topic: messages received and the QoS it
subscribed with; per agent on /swarm/states: the sim-time stamps received).

What it copies from rosbag2 (jazzy branch):

* ``rosbag2_transport/src/rosbag2_transport/recorder.cpp`` ``topics_discovery``: every
  ``--polling-interval`` (100 ms, ``ros2bag/verb/record.py``) the graph is read, topics not yet
  subscribed are subscribed once, never again (a later incompatible publisher only warns,
  ``warn_if_new_qos_for_subscribed_topic``);
* ``topic_filter.cpp``: topics without a publisher are left out (``include_unpublished_topics``
  is false by default), hidden ones too;
* ``subscription_qos_for_topic``: the override for the topic if the file names it, else
  ``Rosbag2QoS::adapt_request_to_offers`` (``rosbag2_storage/src/rosbag2_storage/qos.cpp``):
  reliable only if every publisher offers reliable, transient-local only if every one offers
  it, history KEEP_LAST with depth ``rmw_qos_profile_default.depth`` = 10 (``qos.hpp``);
* the override file as ``ros2bag/api/__init__.py`` ``convert_yaml_to_qos_profile`` reads it
  (policies by short name, durations as {sec, nsec}, depth and
  avoid_ros_namespace_conventions as values);
* the subscription callback is called with the rmw message info (the recorder stores its
  ``received_timestamp`` / ``source_timestamp``); a rosbag2 recorder node spins a single
  threaded executor.

It is slower per message than rosbag2's C++ recorder (a Python callback), so what it loses at
depth 10 is an upper bound of what ``ros2 bag record`` loses.
"""
from __future__ import annotations

import argparse
import inspect
import json
import signal
import sys
import time

POLLING_INTERVAL = 0.1      # ros2bag record --polling-interval default, ms -> s
DEFAULT_DEPTH = 10          # rmw_qos_profile_default.depth (Rosbag2QoS's default history)


def overrides_from_yaml(text: str) -> dict:
    """{topic: QoSProfile} as ros2bag's convert_yaml_to_qos_profile builds it."""
    import yaml
    from rclpy.duration import Duration
    from rclpy.qos import QoSDurabilityPolicy, QoSHistoryPolicy, QoSLivelinessPolicy, QoSProfile, QoSReliabilityPolicy
    short = {'history': QoSHistoryPolicy.get_from_short_key,
             'reliability': QoSReliabilityPolicy.get_from_short_key,
             'durability': QoSDurabilityPolicy.get_from_short_key,
             'liveliness': QoSLivelinessPolicy.get_from_short_key}
    out = {}
    for topic, profile in (yaml.safe_load(text) or {}).items():
        kw = {}
        for key, value in profile.items():
            if key in ('deadline', 'lifespan', 'liveliness_lease_duration'):
                kw[key] = Duration(seconds=value['sec'], nanoseconds=value['nsec']) if value else Duration()
            elif key in short:
                kw[key] = short[key](value)
            elif key in ('depth', 'avoid_ros_namespace_conventions'):
                if value < 0:
                    raise ValueError(f'`{key}` may not be a negative value.')
                kw[key] = value
            else:
                raise ValueError(f'Unexpected key `{key}` for QoS profile.')
        out[topic] = QoSProfile(**kw)
    return out


def adapt_request_to_offers(infos):
    """Rosbag2QoS::adapt_request_to_offers (see the module docstring)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    q = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=DEFAULT_DEPTH)
    if not infos:
        return q
    if all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos):
        q.reliability = ReliabilityPolicy.RELIABLE
    else:
        q.reliability = ReliabilityPolicy.BEST_EFFORT
    if all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos):
        q.durability = DurabilityPolicy.TRANSIENT_LOCAL
    else:
        q.durability = DurabilityPolicy.VOLATILE
    return q


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n', 1)[0])
    p.add_argument('--qos-profile-overrides-path', default=None)
    a = p.parse_args(argv)
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from rclpy.topic_or_service_is_hidden import topic_or_service_is_hidden

    from swarm_tools.bags.mcap_io import parse_odometry
    from swarm_tools.bags.record import message_class

    overrides = {}
    if a.qos_profile_overrides_path:
        with open(a.qos_profile_overrides_path) as f:
            overrides = overrides_from_yaml(f.read())
    stop = []
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('rosbag2_recorder')
    received: dict[str, int] = {}
    requested: dict[str, dict] = {}
    states: dict[str, list] = {}
    subs = {}

    def callback(topic):
        def on_message(*args):
            data, _info = args if len(args) == 2 else args[0]
            received[topic] += 1
            if topic == '/swarm/states':
                o = parse_odometry(data)
                states.setdefault(o['child_frame_id'], []).append(o['stamp_ns'])
        return on_message

    def discover():
        for topic, types in node.get_topic_names_and_types():
            if topic in subs or topic_or_service_is_hidden(topic):
                continue
            infos = node.get_publishers_info_by_topic(topic)
            if not infos:
                continue            # include_unpublished_topics: false
            qos = overrides[topic] if topic in overrides else adapt_request_to_offers(infos)
            try:
                cls = message_class(types[0])
            except (ImportError, AttributeError, ValueError):
                continue
            received[topic] = 0
            requested[topic] = {'depth': qos.depth, 'reliability': qos.reliability.short_key,
                                'durability': qos.durability.short_key}
            cb = callback(topic)
            cb.__signature__ = inspect.Signature(
                [inspect.Parameter(n, inspect.Parameter.POSITIONAL_ONLY) for n in ('msg', 'info')])
            subs[topic] = node.create_subscription(cls, topic, cb, qos, raw=True)

    node.create_timer(POLLING_INTERVAL, discover)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    print('rosbag2_record: ready', file=sys.stderr, flush=True)
    while not stop:
        ex.spin_once(timeout_sec=0.1)
    t_end = time.monotonic() + 0.3
    while time.monotonic() < t_end:
        ex.spin_once(timeout_sec=0.05)
    print(json.dumps({'received': received, 'requested': requested, 'states': states}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
