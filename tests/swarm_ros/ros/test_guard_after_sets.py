"""A reader that rclpy makes after a node started is guarded too: ``ros2 param set NODE
use_sim_time true`` makes the ``/clock`` reader then, and a negative stamp on it raised inside
rclpy and ended the node (`msg_checks.guard_subscriptions` hooks a post-set callback)."""
from __future__ import annotations

import rclpy
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from swarm_ros.msg_checks import RejectLog, guard_subscriptions


def test_the_clock_reader_made_by_use_sim_time_is_guarded(rclpy_context):
    node = rclpy.create_node('late_clock', context=rclpy_context)
    try:
        reject = RejectLog(node.get_logger())
        guard_subscriptions(node, reject)
        assert not [s for s in node.subscriptions if s.topic_name == '/clock']
        assert node.set_parameters([Parameter('use_sim_time', value=True)])[0].successful
        clock = [s for s in node.subscriptions if s.topic_name == '/clock']
        assert len(clock) == 1 and getattr(clock[0].callback, 'guarded', False)
        bad = Clock()
        bad.clock.sec = -5                  # rclpy raises on a negative time
        clock[0].callback(bad)
        assert 'unreadable:/clock' in reject.kinds
    finally:
        node.destroy_node()
