"""The hand-serialised messages of `swarm_ros.protocol` (the fast paths of the ROS swarm) are
the bytes rclpy would send, and its raw readers decode what rclpy serialises (rclpy's
serialisation only: no DDS)."""
import math

import pytest

from swarm_ros import protocol as P


@pytest.mark.parametrize('name', ['agent_0', 'a', 'ab', 'agent_123', 'ünï'])
def test_odometry_bytes_round_trip_through_rclpy(name):
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message, serialize_message
    raw = P.OdometryWriter(name)(12, 345_000_000, 1.5, -2.25, math.sin(0.3), math.cos(0.3), -0.01)
    m = deserialize_message(raw, Odometry)
    assert (m.header.frame_id, m.child_frame_id) == ('world', name)
    assert (m.header.stamp.sec, m.header.stamp.nanosec) == (12, 345_000_000)
    p = m.pose.pose
    assert (p.position.x, p.position.y, p.position.z) == (1.5, -2.25, 0.0)
    q = p.orientation
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, math.sin(0.3), math.cos(0.3))
    assert (m.twist.twist.linear.x, m.twist.twist.angular.z) == (1.0, -0.01)
    assert not any(m.pose.covariance) and not any(m.twist.covariance)
    # and the world's raw reader decodes what rclpy serialises
    m.pose.pose.orientation.x = 0.5
    assert P.cdr_to_odometry_tagged(serialize_message(m)) == (
        name, 12, 345_000_000, (1.5, -2.25, 0.5, 0.0, math.sin(0.3), math.cos(0.3)), -0.01, 0.0)


@pytest.mark.parametrize('frame', ['', 'a', 'agent_0/base_link', 'agent_12/base_link'])
def test_twist_bytes_round_trip_through_rclpy(frame):
    """A robot agent's cmd_vel bytes are the message rclpy would send (padding aside), and the
    robot world's raw reader decodes what rclpy serialises, stamped or not."""
    from geometry_msgs.msg import Twist, TwistStamped
    from rclpy.serialization import deserialize_message, serialize_message
    m = deserialize_message(P.TwistWriter(frame)(12, 345, 0.15, -1.25), TwistStamped)
    assert (m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id) == (12, 345, frame)
    t = m.twist
    assert (t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z) == (0.15, 0, 0, 0, 0, -1.25)
    m.twist.linear.y = 7.0                      # a field the reader must skip, not read
    assert P.cdr_to_twist(serialize_message(m)) == (12, 345, 0.15, -1.25)
    plain = deserialize_message(P.TwistWriter(frame, stamped=False)(12, 345, 0.2, 0.3), Twist)
    assert (plain.linear.x, plain.angular.z) == (0.2, 0.3)
    plain.angular.x = 5.0
    assert P.cdr_to_twist(serialize_message(plain), stamped=False) == (0, 0, 0.2, 0.3)
