"""A faithful emulation of ``ros2 topic pub`` (ROS 2 Jazzy); ros2cli is not in the pip wheels.

Read from ros2/ros2cli, branch jazzy:
- ``ros2topic/ros2topic/verb/pub.py`` ``main``: the QoS is the preset ``default``
  (``QoSPresetProfiles.get_from_short_key('default')`` = `rclpy.qos.qos_profile_default`:
  RELIABLE, VOLATILE, KEEP_LAST 10; ``ros2topic/api/__init__.py``
  ``profile_configure_short_keys`` leaves it so without ``--qos-*`` options); ``--once`` sets
  times = 1; ``--wait-matching-subscriptions`` defaults to 1 with ``--once``/``--times``, else 0;
  ``-r`` 1 Hz; ``--keep-alive`` 0.1 s.
- ``pub.py`` ``publisher()``: creates the publisher, then loops ``while
  pub.get_subscription_count() < wait_matching_subscriptions: time.sleep(0.1)``
  (``DEFAULT_WAIT_TIME``; printing ``Waiting for at least N matching subscription(s)...`` every
  10th look; no time limit without ``--max-wait-time-secs``), fills the message from the YAML
  values (``set_message_fields``), prints ``publisher: beginning loop``, publishes once
  (``timer_callback``); with times == 1 it sleeps ``--keep-alive`` without spinning; else a
  timer at the rate publishes and ``rclpy.spin_once(node)`` runs until ``times`` messages went
  out (for ever with times = 0), then it sleeps ``--keep-alive``.  Spinning is what delivers
  the publisher's QoS events: rclpy's default handler (``rclpy/event_handler.py``) logs
  ``New subscription discovered on topic ..., requesting incompatible QoS`` for each reader
  the writer cannot match, so only the rate / ``--times`` forms print those warnings.
- ``ros2cli/ros2cli/node/direct.py`` ``DirectNode`` (used by ``main``): ``rclpy.init()``,
  a hidden node ``_ros2cli_<pid>`` with ``start_parameter_services=False`` and the overrides
  ``use_sim_time=False``, ``start_type_description_service=True``, then it spins the node for
  ``--spin-time`` (DEFAULT_TIMEOUT 0.5 s) before the verb runs; on exit ``destroy_node()``
  and ``rclpy.try_shutdown()``.
The message is filled as ``set_message_fields`` does for flat messages (rosidl_runtime_py is
not in the pip wheels).  Run as its own process (``python emulate_topic_pub.py TOPIC TYPE
VALUES [--once | -t N] [-r HZ] [-w N]``; without ``--once`` or ``-t`` it publishes until
SIGINT, as the tool does): a fresh process has a fresh DDS participant, which is the point
(it must discover the run from scratch).  Prints ``published`` after each message.
`main` (``main([TOPIC, TYPE, VALUES])``) is ``ros2 topic pub --once``, in-process.
"""
from __future__ import annotations

import argparse
import array
import importlib
import os
import sys
import time

DEFAULT_WAIT_TIME = 0.1          # pub.py
SPIN_TIME = 0.5                  # ros2cli/node/direct.py DEFAULT_TIMEOUT


def publish(topic, type_name, values, *, times=1, rate=1.0, wait_matching=None, keep_alive=0.1, context=None):
    """``ros2 topic pub [-t TIMES | --once] [-r RATE] [-w N] TOPIC TYPE VALUES`` (``times`` 0:
    until the context is shut down, e.g. by SIGINT); ``context``: an rclpy Context of its own
    (not yet initialised) instead of the process's default one."""
    import rclpy
    import rclpy.executors
    import yaml
    from rclpy.parameter import Parameter
    from rclpy.qos import qos_profile_default

    if wait_matching is None:
        wait_matching = int(times != 0)
    rclpy.init(context=context)
    node = rclpy.create_node(
        f'_ros2cli_{os.getpid()}', context=context, start_parameter_services=False,
        parameter_overrides=[Parameter('use_sim_time', value=False),
                             Parameter('start_type_description_service', value=True)],
        automatically_declare_parameters_from_overrides=True)
    ex = rclpy.executors.SingleThreadedExecutor(context=node.context)
    ex.add_node(node)
    try:
        # DirectNode: spin for the spin time (0.5 s) to let discovery start
        done = []
        timer = node.create_timer(SPIN_TIME, lambda: done.append(True))
        while not done:
            ex.spin_once()
        node.destroy_timer(timer)
        # pub.py publisher(): wait for the matching subscriptions, checking every 0.1 s
        pkg, _, name = type_name.split('/')
        msg_type = getattr(importlib.import_module(f'{pkg}.msg'), name)
        pub = node.create_publisher(msg_type, topic, qos_profile_default)
        looks = 0
        while pub.get_subscription_count() < wait_matching:
            if not looks:
                print(f'Waiting for at least {wait_matching} matching subscription(s)...', flush=True)
            looks = (looks + 1) % 10
            time.sleep(DEFAULT_WAIT_TIME)
        msg = msg_type()
        for key, value in yaml.safe_load(values).items():     # flat messages (set_message_fields)
            field = getattr(msg, key)
            if isinstance(field, array.array):                 # a sequence (Float64MultiArray's data)
                setattr(msg, key, array.array(field.typecode, value))
            else:
                setattr(msg, key, type(field)(value))
        print('publisher: beginning loop', flush=True)
        count = [0]

        def timer_callback():
            count[0] += 1
            pub.publish(msg)
            print('published', flush=True)

        timer_callback()
        if times != 1:
            timer = node.create_timer(1.0 / rate, timer_callback)
            try:
                while times == 0 or count[0] < times:
                    ex.spin_once()
            except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
                return 0
            time.sleep(keep_alive)
            node.destroy_timer(timer)
        else:
            time.sleep(keep_alive)
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return 0


def main(argv, context=None) -> int:
    """``ros2 topic pub --once TOPIC TYPE VALUES`` (``argv``: the three); ``context``: an
    rclpy Context of its own (not yet initialised) instead of the process's default one."""
    topic, type_name, values = argv[:3]
    return publish(topic, type_name, values, times=1, context=context)


def cli(argv) -> int:
    """The tool's own options (pub.py ``add_arguments``): without ``--once`` or ``-t`` it
    publishes at the rate until SIGINT."""
    p = argparse.ArgumentParser(prog='ros2 topic pub')
    p.add_argument('topic_name')
    p.add_argument('message_type')
    p.add_argument('values', nargs='?', default='{}')
    p.add_argument('-r', '--rate', type=float, default=1.0)
    g = p.add_mutually_exclusive_group()
    g.add_argument('-1', '--once', action='store_true')
    g.add_argument('-t', '--times', type=int, default=0)
    p.add_argument('-w', '--wait-matching-subscriptions', type=int, default=None)
    p.add_argument('--keep-alive', type=float, default=0.1)
    a = p.parse_args(argv)
    return publish(a.topic_name, a.message_type, a.values, times=1 if a.once else a.times, rate=a.rate,
                   wait_matching=a.wait_matching_subscriptions, keep_alive=a.keep_alive)


if __name__ == '__main__':
    sys.exit(cli(sys.argv[1:]))
