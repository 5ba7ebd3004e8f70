"""Realtime: a node of a run takes its sim time from its run's clock alone.

The world sends its sim time each tick on ``/clock`` (for the recorder and the tools) and, with
the run id and its sender tag, on ``/swarm/clock`` (`layouts.RunClock`).  A realtime node with a
run id (an agent process, the commander, the robot world) reads no ``/clock``: rclpy's reader
goes, and the node sets its clock by hand from ``/swarm/clock`` (`follow_run_clock`), as a
lockstep node does from each step message.  So a peer's ``rosgraph_msgs/Clock``, ahead or stuck
in the past, never reaches the run's nodes.

`ClockGuard` (no ROS) decides which values of the run's clock a node takes.  It binds the clock
to the first sender tag; another tag is a second writer.  The clock never goes back.  It cannot
run ahead of what the run can do: from the first value taken, ``rtf`` sim s per wall s, plus
`AHEAD` wall s for the delivery of that first value.  Anything else is refused with one line
per kind (`msg_checks.RejectLog`).  A node without a run id (a test, a launch of its own) follows
``/clock`` as before.
"""
from __future__ import annotations

import time

from swarm_ros import protocol as P
from swarm_ros.layouts import RunClock
from swarm_ros.msg_checks import MAX_SIM_TIME, decoded, reason, refused

#: wall s the run's clock may be ahead of ``rtf`` × the wall time since the first value a node
#: took: slack for how late that first value came (a node busy at its start)
AHEAD = 2.0


class ClockGuard:
    """The values of one run's clock a node takes (`check`, then `take`): ``tag`` and ``rtf``
    bound by the first taken, ``t`` and ``wall`` (monotonic s) of the newest taken."""

    def __init__(self, ahead: float = AHEAD):
        self.ahead = ahead
        self.tag = self.rtf = None
        self.t0 = self.wall0 = None
        self.t = None

    def check(self, c, wall: float):
        """Why the run clock message ``c`` (a decoded `layouts.RunClock`), received at monotonic
        wall s ``wall``, must be refused (a `msg_checks.Reason`), or None to take it."""
        if not (0.0 <= c.t < MAX_SIM_TIME) or not (0.0 < c.rtf <= 1e6):
            return reason('clock-time', f'{P.RUN_CLOCK}: t={c.t!r} at rtf {c.rtf!r} is no sim time of a run')
        if self.tag is None:
            return None
        if c.tag != self.tag:
            return reason('clock-writer', f'{P.RUN_CLOCK} from a second writer (sender tag {c.tag:.0f}, not the '
                          f"run's {self.tag:.0f}): not this run's clock")
        if c.t < self.t:
            return reason('clock-past', f'{P.RUN_CLOCK} t={c.t:.3f} is before this clock t={self.t:.3f}: '
                          'the clock never goes back')
        most = self.t0 + self.rtf * (wall - self.wall0 + self.ahead)
        if c.t > most:
            return reason('clock-jump', f'{P.RUN_CLOCK} t={c.t:.3f} is ahead of what the run can do (at most '
                          f't={most:.3f} at rtf {self.rtf:g}): a jump')
        return None

    def take(self, c, wall: float) -> float:
        """Take ``c`` (`check` said None); its sim time."""
        if self.tag is None:
            self.tag, self.rtf, self.t0, self.wall0 = c.tag, c.rtf, c.t, wall
        self.t = c.t
        return c.t


def qos_reader():
    """The readers' QoS: the newest value only, best effort (as rclpy's own /clock reader)."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    return QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


def follow_the_run_clock(node):
    """A lone realtime agent of a run (``node.run_id`` set, use_sim_time) follows its run's clock
    alone (`follow_run_clock`); else nothing changes (a container does this for its agents)."""
    if node.run_id and node.get_parameter('use_sim_time').value:
        follow_run_clock(node, node.run_id, node.reject)


def follow_run_clock(node, run_id: str, reject, clocks=None, time_source=None):
    """Make ``node`` (rclpy, with use_sim_time) set the ROS time of ``clocks`` (default: its own)
    from the run's clock (``/swarm/clock`` of ``run_id``) through a `ClockGuard`, and drop its
    /clock reader (that of ``time_source``, default the node's own TimeSource).  Returns the
    guard.  A message of another run, or one the guard refuses, is counted and logged with
    ``reject`` (a `msg_checks.RejectLog`)."""
    from rclpy.time import Time
    from std_msgs.msg import Float64MultiArray
    (time_source if time_source is not None else node._time_source).detach_node()     # no /clock reader
    clocks = [node.get_clock()] if clocks is None else list(clocks)
    guard = ClockGuard()

    def on_clock(raw):
        c = decoded(RunClock, raw, run_id, reject, 'clock')
        wall = time.monotonic()
        if c is None or refused(reject, guard.check(c, wall)):
            return
        now = Time(nanoseconds=int(round(guard.take(c, wall) * 1e9)))
        for clock in clocks:
            clock.set_ros_time_override(now)
    node.create_subscription(Float64MultiArray, P.RUN_CLOCK, on_clock, qos_reader(), raw=True)
    return guard
