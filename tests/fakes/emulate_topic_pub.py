"""A faithful emulation of ``ros2 topic pub --once TOPIC TYPE VALUES`` (ROS 2 Jazzy).

Read from ros2/ros2cli, branch jazzy:
- ``ros2topic/ros2topic/verb/pub.py``: the QoS is the preset ``default`` (RELIABLE,
  VOLATILE, KEEP_LAST 10, `rclpy.qos.qos_profile_default`); ``--once`` sets times = 1 and
  ``--wait-matching-subscriptions`` to 1; ``publisher()`` creates the publisher, then loops
  ``while pub.get_subscription_count() < 1: time.sleep(0.1)`` (DEFAULT_WAIT_TIME, no time
  limit without ``--max-wait-time-secs``), fills the message from the YAML values
  (``set_message_fields``), publishes once and sleeps ``--keep-alive`` (default 0.1 s);
- ``ros2cli/ros2cli/node/direct.py`` (``DirectNode``, used by ``main``): ``rclpy.init()``,
  a hidden node ``_ros2cli_<pid>`` with ``start_parameter_services=False`` and the overrides
  ``use_sim_time=False``, ``start_type_description_service=True``, then it spins the node for
  ``--spin-time`` (DEFAULT_TIMEOUT 0.5 s) before the verb runs; on exit ``destroy_node()``
  and ``rclpy.try_shutdown()``.
The message is filled as ``set_message_fields`` does for flat messages (rosidl_runtime_py is
not in the pip wheels).  Run as its own process (``python emulate_topic_pub.py TOPIC TYPE VALUES``): a fresh process
has a fresh DDS participant, which is the point (it must discover the run from scratch).
Prints ``published`` once it has published; exit code 0.
"""
from __future__ import annotations

import importlib
import os
import sys
import time


def main(argv, context=None) -> int:
    """``ros2 topic pub --once TOPIC TYPE VALUES``; ``context``: an rclpy Context of its own
    (not yet initialised) instead of the process's default one."""
    topic, type_name, values = argv[:3]
    import rclpy
    import rclpy.executors
    import yaml
    from rclpy.parameter import Parameter
    from rclpy.qos import qos_profile_default

    rclpy.init(context=context)
    node = rclpy.create_node(
        f'_ros2cli_{os.getpid()}', context=context, start_parameter_services=False,
        parameter_overrides=[Parameter('use_sim_time', value=False),
                             Parameter('start_type_description_service', value=True)],
        automatically_declare_parameters_from_overrides=True)
    try:
        # DirectNode: spin for the spin time (0.5 s) to let discovery start
        done = []
        timer = node.create_timer(0.5, lambda: done.append(True))
        ex = rclpy.executors.SingleThreadedExecutor(context=node.context)
        ex.add_node(node)
        while not done:
            ex.spin_once()
        ex.remove_node(node)
        ex.shutdown()
        node.destroy_timer(timer)
        # pub.py publisher(): wait for >= 1 matching subscription, checking every 0.1 s
        pkg, _, name = type_name.split('/')
        msg_type = getattr(importlib.import_module(f'{pkg}.msg'), name)
        pub = node.create_publisher(msg_type, topic, qos_profile_default)
        while pub.get_subscription_count() < 1:
            time.sleep(0.1)
        msg = msg_type()
        for key, value in yaml.safe_load(values).items():     # flat messages (set_message_fields)
            setattr(msg, key, type(getattr(msg, key))(value))
        pub.publish(msg)
        print('published', flush=True)
        time.sleep(0.1)              # --keep-alive default
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
