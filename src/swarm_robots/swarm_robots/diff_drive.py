"""The command path and wheel odometry of ros2_controllers' ``diff_drive_controller`` (Jazzy),
for N robots at once (numpy arrays over robots; no ROS).

Emulated from the Jazzy sources of ros-controls/ros2_controllers:

* ``diff_drive_controller/src/diff_drive_controller.cpp``:
  ``update_reference_from_subscribers`` (a command older than ``cmd_vel_timeout`` makes the
  reference zero, "Velocity command timed out. Braking."; a command with NaN leaves the
  reference as it was) and ``update_and_write_commands`` (each axis through its SpeedLimiter
  against the previous limited command, then
  ``velocity_left = (linear - angular·wheel_separation/2) / wheel_radius``, right with ``+``);
  the command subscriber drops a message already older than ``cmd_vel_timeout``.
* ``diff_drive_controller/include/diff_drive_controller/speed_limiter.hpp`` over
  control_toolbox's ``rate_limiter.hpp`` (Jazzy): ``limit`` = jerk (off: NaN by default), then
  ``limit_first_derivative`` (clamp v - v0 to ±max_acceleration·dt when only
  ``max_acceleration`` is set, as here), then ``limit_value`` (clamp to ±max_velocity).
* ``diff_drive_controller/src/odometry.cpp``: ``update`` (wheel positions, the default
  ``position_feedback: true``) → ``updateFromVelocity`` → ``integrateExact`` (exact arc,
  second-order Runge-Kutta below |Δθ| = 1e-6), linear and angular velocity as rolling means
  over ``velocity_rolling_window_size`` (10) updates.  Wheel odometry knows only the wheels'
  turning, so wheel slip shows up as drift.
* ``diff_drive_controller_parameter.yaml``: ``cmd_vel_timeout`` 0.5 s,
  ``velocity_rolling_window_size`` 10, ``position_feedback`` true.
"""
from __future__ import annotations

import numpy as np

from swarm_robots.description import RobotDescription

#: odometry.cpp: intervals shorter than this are not integrated
MIN_ODOM_INTERVAL = 0.0001
#: diff_drive_controller_parameter.yaml: velocity_rolling_window_size
VELOCITY_ROLLING_WINDOW = 10


class DiffDriveControllers:
    """N diff_drive_controllers' command path: cmd_vel timeout, speed limits, wheel speeds."""

    def __init__(self, description: RobotDescription, n: int):
        self.description = description
        self.n = n
        self._msg = np.zeros((2, n))                  # the last cmd_vel (linear.x, angular.z)
        self._stamp = np.full(n, -np.inf)             # its header.stamp (none yet: timed out)
        self._finite = np.ones(n, dtype=bool)         # which robots' last cmd_vel is finite
        self._reference = np.zeros((2, n))            # the reference interfaces
        self._previous = np.zeros((2, n))             # the last limited command (reset_buffers: 0)
        self._max_velocity = np.array([[description.max_linear], [description.max_angular]])
        self._min_velocity = -self._max_velocity
        self._never = np.zeros(n, dtype=bool)         # no cmd_vel_timeout: never timed out
        self._timed_out = self._never
        self._quiet_until = -np.inf                   # see `update`
        self._settled = False                         # `update` may repeat its last answer
        self._unsaturated = np.zeros(n, dtype=bool)   # (what a repeat returns; not to be changed)
        self._wheels = None
        self._max_acceleration = np.array([[description.max_linear_accel],
                                           [description.max_angular_accel]])

    def command(self, i, v, omega, now: float):
        """A cmd_vel (TwistStamped stamped `now`) for robot(s) `i` (an index or an index array)."""
        self._msg[0, i] = v
        self._msg[1, i] = omega
        self._stamp[i] = now
        self._finite = np.isfinite(self._msg).all(axis=0)
        self._settled = False

    def update(self, now: float, dt: float):
        """One controller update at `now` over `dt`: returns (left, right) wheel velocities
        (rad/s, arrays over robots), whether a limit changed each robot's command, and whether
        the wheel velocities are those of the update before (``same``: the caller may keep what
        it made of them).

        Settled (every robot's limited command equal to its reference), with no cmd_vel since
        and no robot's timeout passing, the update gives what it gave last time: that is
        returned without the arithmetic (the lockstep world holds one command for many updates)."""
        if self._settled and now < self._quiet_until:           # no timeout can have passed
            return self._wheels, self._unsaturated, True
        timeout = self.description.cmd_vel_timeout
        timed_out = now - self._stamp > timeout if timeout > 0 else self._never
        if self._settled and not (timed_out != self._timed_out).any():
            return self._wheels, self._unsaturated, True
        self._timed_out = timed_out
        # the first `now` at which a running command may time out, less a margin far above the
        # rounding of now - stamp: before it the comparison above cannot change
        self._quiet_until = (np.min(self._stamp[~timed_out], initial=np.inf) + timeout - 1e-6
                             if timeout > 0 else np.inf)
        reference = np.where(timed_out, 0.0, np.where(self._finite, self._msg, self._reference))
        self._reference = reference
        step = self._max_acceleration * dt
        limited = np.subtract(reference, self._previous)
        np.minimum(np.maximum(limited, -step, out=limited), step, out=limited)     # np.clip, fewer calls
        limited += self._previous
        np.minimum(np.maximum(limited, self._min_velocity, out=limited), self._max_velocity, out=limited)
        saturated = np.logical_or(limited[0] != reference[0], limited[1] != reference[1])
        self._previous = limited
        self._wheels = wheel_velocities(self.description, limited[0], limited[1])
        self._settled = not saturated.any()
        return self._wheels, saturated, False

    @property
    def limited_command(self) -> np.ndarray:
        """(2, N) the last limited (v, ω), as the controller's ``cmd_vel_out`` would publish."""
        return self._previous.copy()

    def fresh(self, now: float, stamp: float) -> bool:
        """Whether the subscriber accepts a command stamped `stamp` at `now` (it drops one
        older than cmd_vel_timeout)."""
        timeout = self.description.cmd_vel_timeout
        return timeout == 0 or now - stamp < timeout


def wheel_velocities(description: RobotDescription, v, omega):
    """(v, ω) → (left, right) wheel angular velocities, rad/s (diff_drive_controller.cpp)."""
    half = omega * description.wheel_separation / 2.0        # in the C++ order of operations
    return (v - half) / description.wheel_radius, (v + half) / description.wheel_radius


class WheelOdometry:
    """N robots' wheel odometry as odometry.cpp integrates it: pose from (0, 0, 0) in each
    robot's own odom frame, velocities as rolling means."""

    def __init__(self, description: RobotDescription, n: int, now: float = 0.0):
        self.wheel_radius = description.wheel_radius
        self.wheel_separation = description.wheel_separation
        self.pose = np.zeros((3, n))                  # x, y, heading
        self._old = np.zeros((2, n))                  # left, right wheel distance (m)
        self._timestamp = now
        self._window = np.zeros((VELOCITY_ROLLING_WINDOW, 2, n))
        self._count = 0

    @property
    def velocity(self) -> np.ndarray:
        """(2, N) linear (m/s) and angular (rad/s): the rolling means."""
        k = min(self._count, VELOCITY_ROLLING_WINDOW)
        return self._window[:k].mean(axis=0) if k else np.zeros(self._window.shape[1:])

    def update(self, left_position, right_position, now: float) -> bool:
        """Odometry::update: wheel joint positions (rad) at `now`."""
        return self.update_many(np.asarray(left_position)[None], np.asarray(right_position)[None], [now])

    def update_many(self, left_positions, right_positions, times) -> bool:
        """`update` at each of ``times`` (K,) in turn, the wheel positions (K, N) of each, in
        whole-array operations: the same numbers as K calls (sums in the same order)."""
        times = np.asarray(times, dtype=float)
        dt = np.diff(times, prepend=self._timestamp)
        if (dt < MIN_ODOM_INTERVAL).any():
            if len(times) == 1:
                return False
            done = [self.update_many(left_positions[k:k + 1], right_positions[k:k + 1], times[k:k + 1])
                    for k in range(len(times))]
            return any(done)
        left = np.concatenate([self._old[:1], left_positions * self.wheel_radius])
        right = np.concatenate([self._old[1:], right_positions * self.wheel_radius])
        moved_left, moved_right = np.diff(left, axis=0), np.diff(right, axis=0)
        self._old[0], self._old[1] = left[-1], right[-1]
        linear = (moved_left + moved_right) * 0.5
        angular = (moved_right - moved_left) / self.wheel_separation
        self._integrate_exact(linear, angular)
        self._timestamp = times[-1]
        last = min(len(times), VELOCITY_ROLLING_WINDOW)
        slots = (self._count + np.arange(len(times) - last, len(times))) % VELOCITY_ROLLING_WINDOW
        self._window[slots, 0] = linear[-last:] / dt[-last:, None]
        self._window[slots, 1] = angular[-last:] / dt[-last:, None]
        self._count += len(times)
        return True

    def _integrate_exact(self, linear, angular):
        """Odometry::integrateExact over K updates ((K, N) arrays): the exact arc, or RK2
        where |angular| < 1e-6.  The headings and positions are running sums (np.cumsum adds
        in order: the same numbers as one update after another)."""
        heading = np.cumsum(np.concatenate([self.pose[2:], angular]), axis=0)
        old, new = heading[:-1], heading[1:]
        small = np.abs(angular) < 1e-6
        r = linear / (np.where(small, 1.0, angular) if small.any() else angular)
        dx = r * (np.sin(new) - np.sin(old))
        dy = -r * (np.cos(new) - np.cos(old))
        if small.any():
            direction = old + angular * 0.5
            dx = np.where(small, linear * np.cos(direction), dx)
            dy = np.where(small, linear * np.sin(direction), dy)
        self.pose[0] = np.cumsum(np.concatenate([self.pose[:1], dx]), axis=0)[-1]
        self.pose[1] = np.cumsum(np.concatenate([self.pose[1:2], dy]), axis=0)[-1]
        self.pose[2] = heading[-1]
