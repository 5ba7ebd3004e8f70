"""The fast paths of the ROS swarm keep its behaviour: hand-serialised /swarm/states messages
are what rclpy would send, and a lockstep run over the large-n DDS profile (UDP loopback, no
shared memory) still equals `swarm simulate`."""
import math
import subprocess

import numpy as np
import pytest

from swarm_core.engine import simulate
from swarm_core.trajectory import Trajectory
from swarm_core.scenario import load
from swarm_ros import protocol as P

from conftest import short_homotopy


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
    assert (p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) == (0.0, 0.0, math.sin(0.3), math.cos(0.3))
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


@pytest.mark.ros
def test_lockstep_over_the_udp_profile_equals_simulate(tmp_path, ros_domain, processes, swarm_cmd):
    """Also with /clock only every 7 steps: lockstep inputs carry their own step and time."""
    path = short_homotopy(tmp_path / 'dds_short.yaml', name='dds_short', seed=3, duration=15, at=2,
                          lam={'kind': 'tanh_window', 'rise_at': 5, 'fall_at': 12, 'tau': 1})
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--dds', 'udp', '--clock-every', '7', '--out', out, '--no-figure'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    text = processes.communicate(p, 240)
    assert p.returncode == 0, text[-3000:]
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(load(str(path)))
    assert ref.leader.any() and ref.lam.max() > 0.5          # leaders and λ were exercised
    np.testing.assert_array_equal(got.r, ref.r)                # exact: the same law, the same order
    np.testing.assert_array_equal(got.u, ref.u)
    assert np.abs(got.theta - ref.theta).max() <= 1e-9         # θ comes back through the quaternion
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)
    assert 'stalled' not in text and 'XMLPARSER' not in text      # the profile parsed


def test_udp_profile_is_written_for_large_runs(tmp_path):
    from swarm_tools import dds
    env = dds.environment(98, tmp_path, base={'ROS_DOMAIN_ID': '5'})
    xml = (tmp_path / 'fastdds_loopback.xml').read_text()
    assert env['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(tmp_path / 'fastdds_loopback.xml')
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SYSTEM_DEFAULT'
    assert '<maxInitialPeersRange>130</maxInitialPeersRange>' in xml
    # small runs get the profile too (no shared memory); 'localhost' is rmw_fastrtps' own range
    (tmp_path / 'x').mkdir()
    small = dds.environment(8, tmp_path / 'x', base={})
    assert small['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(tmp_path / 'x' / 'fastdds_loopback.xml')
    assert '<useBuiltinTransports>false</useBuiltinTransports>' in (tmp_path / 'x' / 'fastdds_loopback.xml').read_text()
    shm = dds.environment(8, tmp_path / 'y', base={}, choice='localhost')
    assert shm['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST' and 'FASTRTPS_DEFAULT_PROFILES_FILE' not in shm
    own = dds.environment(8, tmp_path / 'z', base={'FASTRTPS_DEFAULT_PROFILES_FILE': '/my.xml'})
    assert own['FASTRTPS_DEFAULT_PROFILES_FILE'] == '/my.xml'        # the user's profile is kept
