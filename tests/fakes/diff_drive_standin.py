"""A stand-in for ros2_controllers' ``diff_drive_controller`` (Jazzy) on a perfect unicycle,
for tests of robot agents: one node per robot, no hardware, no controller_manager.

Usage: ``python tests/fakes/diff_drive_standin.py NAME [NAME ...]`` starts one node
``/NAME/diff_drive_controller`` per robot, with ``~/cmd_vel`` remapped to ``/NAME/cmd_vel`` and
``~/odom`` to ``/NAME/odom`` as a user remaps the real controller; its odometry starts at the
origin of its own odom frame, as the controller's does.

What it copies from the controller, cited from ros-controls/ros2_controllers, branch jazzy
(commit ed360c97d6e9), diff_drive_controller/src/diff_drive_controller.cpp (``cpp``) and
diff_drive_controller/src/diff_drive_controller_parameter.yaml (``yaml``):
- topics ``~/cmd_vel`` (geometry_msgs/TwistStamped) and ``~/odom`` (nav_msgs/Odometry):
  cpp 35-37;
- QoS ``rclcpp::SystemDefaultsQoS()`` for both (cpp 460-461, 498-499): rclpy's
  ``qos_profile_system_default`` is the same rmw profile;
- a command with a zero stamp is stamped now (cpp 469-476); a command older than
  ``cmd_vel_timeout`` on arrival is ignored (cpp 478-494);
- brake (zero velocity) when the newest command is older than ``cmd_vel_timeout``
  (default 0.5 s, yaml 94; cpp 120-131); a non-finite command is not taken (cpp 132-142);
- velocity and acceleration limits per axis (``linear.x.max_velocity``, ``.max_acceleration``,
  the same for ``angular.z``; NaN = no limit), applied to each update's command (cpp 174-175;
  control_toolbox's rate limiter: the acceleration bound, then the velocity bound).  Simplified:
  one symmetric acceleration bound, no jerk limit.  The controller's limits default to NaN (off);
  here the velocity limits default to a TurtleBot3 Burger's (0.22 m/s, 2.84 rad/s);
- odometry published at ``publish_rate`` (default 50 Hz, yaml 109; cpp 236-252, 535-536)
  stamped with the update's time, pose integrated from (0, 0, 0), twist in the body frame
  (cpp 255-266); frames ``<ns>/odom`` → ``<ns>/base_link`` (``tf_frame_prefix_enable`` true
  and an empty prefix: the controller's namespace, yaml 49-68, cpp 504-532).
The controller's update runs at the controller manager's ``update_rate`` (here 100 Hz).
Not copied: /tf (tf2_msgs), wheel joints, the velocity rolling window.
"""
from __future__ import annotations

import math
import sys

import rclpy
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_system_default
from rclpy.time import Time


def limited(v, last, dt, max_velocity, max_acceleration):
    """One axis through the rate limiter: acceleration, then velocity (NaN: no limit)."""
    if math.isfinite(max_acceleration):
        dv = max_acceleration * dt
        v = min(max(v, last - dv), last + dv)
    if math.isfinite(max_velocity):
        v = min(max(v, -max_velocity), max_velocity)
    return v


class DiffDriveStandin(Node):
    def __init__(self, robot: str, context=None, update_rate: float = 100.0):
        super().__init__('diff_drive_controller', namespace=robot, context=context,
                         cli_args=['--ros-args', '-r', f'~/cmd_vel:=/{robot}/cmd_vel', '-r', f'~/odom:=/{robot}/odom'])
        def p(name, default):
            return self.declare_parameter(name, default).value
        self.cmd_vel_timeout = p('cmd_vel_timeout', 0.5)
        self.publish_period = 1.0 / p('publish_rate', 50.0)
        # velocity limits of a TurtleBot3 Burger; acceleration: the controller's default (NaN, off)
        self.limits = {'linear': (p('linear.x.max_velocity', 0.22), p('linear.x.max_acceleration', math.nan)),
                       'angular': (p('angular.z.max_velocity', 2.84), p('angular.z.max_acceleration', math.nan))}
        prefix = self.get_namespace().strip('/') + '/'
        self.odom_frame, self.base_frame = prefix + p('odom_frame_id', 'odom'), prefix + p('base_frame_id', 'base_link')
        self.command = None            # the newest command taken: (stamp ns, v, ω)
        self.v = self.w = 0.0          # the velocities applied (after the limits)
        self.x = self.y = self.yaw = 0.0
        self.last_update = None
        self.last_publish = None
        self.create_subscription(TwistStamped, '~/cmd_vel', self.on_cmd, qos_profile_system_default)
        self.pub = self.create_publisher(Odometry, '~/odom', qos_profile_system_default)
        self.create_timer(1.0 / update_rate, self.update)

    def on_cmd(self, msg):
        now = self.get_clock().now().nanoseconds
        stamp = Time.from_msg(msg.header.stamp).nanoseconds or now      # zero stamp: now
        if self.cmd_vel_timeout > 0 and now - stamp >= self.cmd_vel_timeout * 1e9:
            self.get_logger().warning('Ignoring the received message: older than cmd_vel_timeout')
            return
        self.command = (stamp, msg.twist.linear.x, msg.twist.angular.z)

    def update(self):
        now = self.get_clock().now().nanoseconds
        dt = 0.0 if self.last_update is None else (now - self.last_update) * 1e-9
        self.last_update = now
        v = w = 0.0
        if self.command is not None and (self.cmd_vel_timeout == 0
                                         or now - self.command[0] <= self.cmd_vel_timeout * 1e9):
            if math.isfinite(self.command[1]) and math.isfinite(self.command[2]):
                v, w = self.command[1], self.command[2]
        self.v = limited(v, self.v, dt, *self.limits['linear'])
        self.w = limited(w, self.w, dt, *self.limits['angular'])
        # exact unicycle over dt (the controller's odometry integrates the wheels alike)
        if abs(self.w) > 1e-9:
            r = self.v / self.w
            self.x += r * (math.sin(self.yaw + self.w * dt) - math.sin(self.yaw))
            self.y -= r * (math.cos(self.yaw + self.w * dt) - math.cos(self.yaw))
        else:
            self.x += self.v * dt * math.cos(self.yaw)
            self.y += self.v * dt * math.sin(self.yaw)
        self.yaw += self.w * dt
        period = int(self.publish_period * 1e9)
        if self.last_publish is None:            # cpp 244-249: the first update publishes
            self.last_publish = now
        elif self.last_publish + period < now:   # cpp 239-243
            self.last_publish += period
        else:
            return
        self.publish(now)

    def publish(self, now):
        m = Odometry()
        m.header.stamp = Time(nanoseconds=now).to_msg()
        m.header.frame_id, m.child_frame_id = self.odom_frame, self.base_frame
        m.pose.pose.position.x, m.pose.pose.position.y = self.x, self.y
        m.pose.pose.orientation.z, m.pose.pose.orientation.w = math.sin(self.yaw / 2), math.cos(self.yaw / 2)
        m.twist.twist.linear.x, m.twist.twist.angular.z = self.v, self.w
        self.pub.publish(m)


def main(argv=None):
    names = [a for a in (sys.argv[1:] if argv is None else argv) if not a.startswith('-')]
    rclpy.init()
    nodes = [DiffDriveStandin(nm) for nm in names]
    ex = SingleThreadedExecutor()
    for nd in nodes:
        ex.add_node(nd)
    try:
        ex.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for nd in nodes:
            nd.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == '__main__':
    main()
