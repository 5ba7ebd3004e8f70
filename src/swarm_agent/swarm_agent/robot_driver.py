"""Robot agents: the agent's law drives a robot through ``cmd_vel`` and reads its pose from
odometry, instead of integrating its own frame (parameter ``robot``: external or mujoco).

The agent node (`agent_node.AgentNode`) is the same: same law code (`AgentCore`), same radio
model, same ``/swarm/states`` in model units.  What differs is the robot's link (`RobotLink`):
``/<agent>/odom`` (nav_msgs/Odometry, metres) in, ``/<agent>/cmd_vel`` (geometry_msgs/
TwistStamped as Jazzy's diff_drive_controller takes it, or Twist) out, the units of
`swarm_core.robot_units` between them, and its safety guard.

- `LockstepRobotDriver` (external robots): at step n it sends u_n as one cmd_vel stamped t_n,
  and answers the world (``/swarm/states``, ``/lockstep/agent_states``) only once odometry
  stamped t_(n+1) came: then its state of t_(n+1) is the robot's pose.  Lockstep time moves
  only when every robot answered, so odometry cannot go stale there (the world's stall watch
  sees a silent robot); rejected odometry is never fed to the law.
- `LockstepMujocoDriver` (robots of the MuJoCo world): the robot world reports each robot's
  pose of t_(n+1) to the world itself (``/lockstep/robot_states``), read from the odometry as
  the agent would read it, so the agent reads no odometry and waits for none: at step n it
  takes its pose of t_n from its row of the step's table, publishes that state on
  ``/swarm/states``, sends u_n as one cmd_vel stamped t_n and answers the world with u_n at
  once.  A step is then one hop shorter (docs/robots.md).
- `RealtimeRobotDriver`: at every control period it takes the newest accepted odometry as its
  pose, and sends u (or zero velocity while its guard holds the robot: odometry older than
  ``odom_timeout``, no neighbour in radio range for ``neighbour_timeout``, paused), with one
  ``robot_stopped`` / ``robot_resumed`` event on ``/swarm/events`` per change.

Faults: a kill or pause event for this agent on ``/swarm/events`` (a run in one process) makes
the driver send zero velocity from then on (until resume); a signalled agent process (SIGSTOP,
SIGKILL) sends nothing, and the robot's controller stops it after its ``cmd_vel_timeout``.
In an agent container (`container_node`) a robot agent keeps its own link (its cmd_vel, odom and
events on its own node); lockstep: the container's answer to the world waits for every robot
agent's odometry (`OdometryHold`); realtime: each robot agent ticks on its own timer (on the
container's clock) and sends its state in the container's batches.
"""
from __future__ import annotations

import math
import time

import numpy as np
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from swarm_agent.drivers import LockstepDriver, RealtimeDriver
from swarm_agent.process_io import AgentStatesWriter, step_message
from swarm_core.laws import LawError
from swarm_core.robot_units import (
    CMD_TYPES,
    ROBOT_FRAMES,
    ROBOTS_BOUNDS,
    ROBOTS_DEFAULTS,
    RateLimit,
    RobotUnits,
    SafetyGuard,
    wrap_near,
    yaw_of_quaternion,
)
from swarm_ros import protocol as P
from swarm_ros.msg_checks import new_sender_tag
from swarm_ros.rosutil import ParameterError, declare, fail, step_time
from swarm_ros.run_clock import follow_the_run_clock
from swarm_ros.run_control import command_frame, event_text

#: the robot's clock: the swarm's sim clock (a simulator on /clock, lockstep) or the system
#: clock (real robots; their controllers stamp and time out in wall time)
ROBOT_CLOCKS = ('sim', 'wall')
#: reliability of the odometry subscription (diff_drive_controller's publisher is reliable)
ODOM_RELIABILITY = ('reliable', 'best_effort')


def _default(name):
    return ROBOTS_DEFAULTS[name]          # one place, with the scenario schema's limits


def _range(name, unset=False):
    """The parameter range of a robots: field: the scenario's bounds (`ROBOTS_BOUNDS`, one
    place); ``unset``: 0.0 too, the value of a parameter not given."""
    b = ROBOTS_BOUNDS[name]
    return dict(lo=0.0 if unset else b.lo, hi=b.hi)


def declare_robot(node) -> dict:
    """A robot agent's parameters (declared only when ``robot`` is not none)."""
    d = lambda *a, **k: declare(node, *a, read_only=True, **k)  # read once at the start
    p = dict(
        length_scale=d('length_scale', 0.0, 'robot: L, metres per model unit (the scenario\'s robots: section)',
                       **_range('length_scale', unset=True)),
        cruise_speed=d('cruise_speed', 0.0, 'robot: v0, the forward speed (m/s)', **_range('cruise_speed', unset=True)),
        max_angular=d('max_angular', _default('max_angular'), 'robot: ω_max (rad/s); a larger turn is clipped '
                      'and counted', **_range('max_angular')),
        odom_timeout=d('odom_timeout', _default('odom_timeout'), 'robot: odometry older than this (robot s) '
                       'stops the robot', **_range('odom_timeout')),
        neighbour_timeout=d('neighbour_timeout', _default('neighbour_timeout'), 'robot: no neighbour in radio '
                            'range for this long (robot s) stops the robot', **_range('neighbour_timeout')),
        max_jump=d('max_jump', _default('max_jump'), 'robot: odometry moving farther than v0·Δt + this (m) '
                   'is rejected', **_range('max_jump')),
        robot_frame=d('robot_frame', _default('frame'), 'robot: odometry in its own odom frame from (0, 0, 0) '
                      'at the start pose (odom) or in a common frame (world)', choices=ROBOT_FRAMES),
        cmd_type=d('cmd_type', _default('cmd_type'), 'robot: cmd_vel message type', choices=CMD_TYPES),
        robot_clock=d('robot_clock', 'sim', 'robot: cmd_vel stamps and the guard in sim time (sim) or in '
                      'wall time (wall: real robots)', choices=ROBOT_CLOCKS),
        odom_reliability=d('odom_reliability', 'reliable', 'robot: QoS reliability of the odom subscription',
                           choices=ODOM_RELIABILITY))
    if not (p['length_scale'] > 0 and p['cruise_speed'] > 0):
        raise ParameterError('robot: parameters length_scale and cruise_speed must be > 0 '
                             "(the scenario's robots: section)")
    return p


class RobotLink:
    """The robot of one agent node: odometry in (checked by the guard, in model units),
    cmd_vel out (in the robot's units; its QoS `protocol.qos_cmd_vel` of ``lockstep``), the
    guard's events on ``/swarm/events``."""

    def __init__(self, node, lockstep, length_scale, cruise_speed, max_angular, odom_timeout, neighbour_timeout,
                 max_jump, robot_frame, cmd_type, robot_clock, odom_reliability, odometry=True):
        self.node = node
        self.units = RobotUnits(length_scale, cruise_speed, max_angular)
        x0, y0 = node.core.pos[0]
        self.start = self.units.start_pose(x0, y0, node.core.theta[0]) if robot_frame == 'odom' else None
        self.wall = robot_clock == 'wall'
        self.guard = SafetyGuard(cruise_speed, odom_timeout, neighbour_timeout, max_jump,
                                 needs_neighbours=node.n > 1, start=self.robot_now())
        self.say = RateLimit()
        self.stamped = cmd_type == 'TwistStamped'
        # a robot of the run's MuJoCo world takes commands of this run and this link only
        # (`run_control.CommandSenders`); an external robot's frame is its base_link
        frame = (command_frame(node.agent_name, node.run_id, new_sender_tag()) if node.robot == 'mujoco'
                 else f'{node.agent_name}/base_link')
        self.serialize_cmd = P.TwistWriter(frame, self.stamped)
        self.last_cmd = None       # the newest cmd_vel sent (serialized): `resend`
        self.pose = None           # newest accepted odometry: (stamp s, x, y, θ unwrapped), model units
        self.on_pose = None        # the driver's hook for a new pose
        self.cmd_pub = node.create_publisher(TwistStamped if self.stamped else Twist, 'cmd_vel',
                                             P.qos_cmd_vel(lockstep))
        self.events = node.create_publisher(String, P.EVENTS, P.qos_latched(100))
        ns = node.get_namespace().rstrip('/')
        if odometry:
            odom_qos = P.qos_reliable(10) if odom_reliability == 'reliable' else QoSProfile(
                history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
            node.create_subscription(Odometry, 'odom', self._on_odom, odom_qos, raw=True)
            pose = f'{ns}/odom ({robot_frame} frame, {robot_clock} clock)'
        else:
            pose = f'the robot world\'s reports ({P.LOCK_ROBOT_STATES})'
        r0 = getattr(node.law, 'r0', None)      # the paper's law's spacing, if any
        node.get_logger().info(f'robot on {ns}/cmd_vel ({cmd_type}), pose from {pose}; '
                               + self.units.describe(node.law.cutoff_radius, r0))

    # -- time
    def robot_now(self) -> float:
        """Robot seconds now: the system's steady clock (wall), else the sim clock × L/v0."""
        return time.monotonic() if self.wall else self.units.robot_time(self.node._now())

    def stamp_now(self) -> tuple:
        """A cmd_vel stamp (sec, nanosec) of now on the robot's clock."""
        ns = time.time_ns() if self.wall else self.node.sim_clock.now().nanoseconds
        return ns // 10**9, ns % 10**9

    # -- odometry in
    def _on_odom(self, raw):
        """One serialized odometry message (read raw: no message object per step); bytes that
        are not one (a writer of another type) are counted and dropped."""
        try:
            _, _, sec, nsec, (x, y, qx, qy, qz, qw), _, _, _ = P.cdr_to_odometry_full(raw)
        except Exception as err:          # struct.error, IndexError: too short, a bad length
            self.node.reject('odom-decode', f'{self.node.get_namespace()}/odom: not a serialized Odometry '
                             f'({len(raw)} bytes: {str(err)[:60]})')
            return
        yaw = yaw_of_quaternion(qx, qy, qz, qw)
        why = self.guard.odometry(self.robot_now(), x, y, yaw)
        if why is not None:
            self.log('odom', f'{self.node.agent_name}/odom rejected (not fed to the law): {why}')
            return
        x, y, yaw = self.units.to_model(x, y, yaw, self.start)
        near = self.pose[3] if self.pose is not None else float(self.node.core.theta[0])
        self.pose = (P.stamp_seconds(sec, nsec), x, y, wrap_near(yaw, near))
        if self.on_pose is not None:
            self.on_pose(self.pose)

    def neighbours_in_range(self, rows, own: int) -> bool:
        """Is an agent of the table (rows (m, ≥2) of x, y; own row ``own``) within radio range:
        the radio model's range, else w unless the law couples globally (then any agent)?"""
        node = self.node
        r = node.radio.radio_range
        if r is None:
            r = math.inf if node.law.couples_globally(node.lam) else node.law.cutoff_radius
        d2 = np.sum((rows[:, :2] - rows[own, :2]) ** 2, axis=1)
        d2[own] = math.inf
        return bool(np.any(d2 <= r * r))

    # -- commands out
    def publish_cmd(self, v: float, w: float, stamp):
        """One cmd_vel stamped ``stamp`` (sec, nanosec), pre-serialised (`protocol.TwistWriter`)."""
        self.last_cmd = self.serialize_cmd(*stamp, float(v), float(w))
        self.cmd_pub.publish(self.last_cmd)

    def resend(self):
        """Lockstep: the newest cmd_vel again, when the world repeats a stalled step (a reader's
        history may have lost it; the robot world takes the first of a step, a repeat changes
        nothing)."""
        if self.last_cmd is not None:
            self.cmd_pub.publish(self.last_cmd)

    def drive(self, u: float, stamp):
        """Command curvature u (model units) as v0 and a clipped ω (counted)."""
        v, w, clipped = self.units.command(u)
        if clipped:
            self.log('clip', f'{self.node.agent_name}: u = {u:.3g} needs ω = {float(self.units.omega(u)):.3g} '
                     f'rad/s, clipped at {self.units.max_angular:g}: {self.saturation()}', warn=False)
        self.publish_cmd(v, w, stamp)

    def saturation(self) -> str:
        u = self.units
        return f'{u.saturated} of {u.commands} commands clipped at ω_max ({100 * u.saturated_fraction:.1f} %)'

    # -- the guard
    def check(self, paused: bool, watch: bool = True) -> bool:
        """The guard's decision now (an event if it changed); True while the robot must stand
        (``watch`` False: only a pause stops it)."""
        change = self.guard.decide(self.robot_now() if watch else None, paused, watch)   # the time only if watched
        if change is not None:
            kind = 'robot_stopped' if change[0] == 'stop' else 'robot_resumed'
            ev = dict(t=self.node._now(), kind=kind, agent=self.node.agent_name, node='agent')
            if change[1]:
                ev['reason'] = change[1]
            self.events.publish(String(data=event_text(ev, self.node.run_id)))
            self.node.get_logger().warning(f'{kind}' + (f': {change[1]}' if change[1] else ''))
        return self.guard.stopped is not None

    def log(self, key: str, text: str, warn: bool = True):
        """One line per key every few seconds (how many were left out is said)."""
        held = self.say(key, time.monotonic())
        if held is None:
            return
        text += f' ({held} more like it not shown)' if held else ''
        (self.node.get_logger().warning if warn else self.node.get_logger().info)(text)


class OdometryHold:
    """The ``/lockstep/agent_states`` writer of a process with robot agents (alone, or in a
    container among kinematic ones): it holds the answers of a step while any of its robot
    agents waits for the odometry of its next state (`LockstepRobotDriver.pending`), then sends
    them all in one message, as a process always answers (the world's reader binds each agent to
    one process; the writer keeps one message).  ``batch``: the process's `AgentStatesWriter`."""

    def __init__(self, batch, agents):
        self.batch = batch
        self.robots = [a for a in agents if isinstance(a.driver, LockstepRobotDriver)]
        self.said = []

    def publish(self, agents):
        """The agents that answered (`process_io.step_message`; [] when a robot's odometry came)."""
        self.said += [a for a in agents if a not in self.said]
        if any(a.driver.pending is not None for a in self.robots):
            return
        said, self.said = self.said, []
        self.batch.publish(said)


class LockstepRobotDriver(LockstepDriver):
    """Lockstep with a robot (module docstring; the contract's steps 2-4)."""

    def __init__(self, node, state_subscribers, lockstep_clock, **robot):
        super().__init__(node, state_subscribers, lockstep_clock)
        self.link = RobotLink(node, True, **robot)
        self.link.on_pose = self.on_pose
        self.pending = None          # the step whose odometry the agent waits for
        self.hold = None             # its process's `OdometryHold` (alone: its own; contained: the container's)

    def start(self):
        super().start()
        if not self.node.contained:
            self.hold = OdometryHold(self.batch, [self.node])

    def on_input(self, raw):
        s = step_message(raw, self.lock, [self.node], self.node.reject, self.hold)
        if s is not None and self.lockstep_clock == 'step':
            step_time([self.node], s)

    def lockstep_outcome(self, kind, detail, s):
        node, link = self.node, self.link
        stamp = P.time_to_stamp(s.t)
        if kind == 'moved':          # u_n as one cmd_vel stamped t_n; the state when the robot moved
            node.lam = s.lam
            node.step = s.n
            node.applied(detail)
            if link.check(paused=node.halted is not None, watch=False):
                link.publish_cmd(0.0, 0.0, stamp)
            else:
                link.drive(detail, stamp)
            self.pending = s.n + 1
        elif kind == 'repeat':
            if self.pending is None:
                node.publish_state()
            else:                    # still waiting for the robot: its command again
                link.resend()
        else:
            if kind == 'silent':     # out of the table: the robot stands, and no answer is awaited
                link.publish_cmd(0.0, 0.0, stamp)
                self.pending = None
            super().lockstep_outcome(kind, detail, s)

    def on_pose(self, pose):
        """Odometry stamped t_(n+1) for the step awaited: the state of t_(n+1), to the world."""
        node = self.node
        if self.pending is None or P.step_of(pose[0], node.dt) != self.pending:
            return
        node.core.place(pose[1], pose[2], pose[3], node.core.u_last)
        node.step, self.pending = self.pending, None
        node.t = node.step * node.dt
        node.publish_state()
        self.hold.publish([])


class LockstepMujocoDriver(LockstepDriver):
    """Lockstep on a robot of the MuJoCo world, whose pose the robot world reports (module
    docstring).  Its answer to step n carries u_n (and its pose of t_n, which the world does not
    take: the robot world's report of t_(n+1) is its state)."""

    def __init__(self, node, state_subscribers, lockstep_clock, **robot):
        super().__init__(node, state_subscribers, lockstep_clock)
        self.link = RobotLink(node, True, odometry=False, **robot)
        node.core.reported = True
        self.hold = None             # a container's `OdometryHold` (set by it; never holds this agent)

    def lockstep_outcome(self, kind, detail, s):
        node, link = self.node, self.link
        stamp = P.time_to_stamp(s.t)
        if kind == 'moved':          # its state of t_n (the table's row), then u_n to the robot and the world
            node.lam = s.lam
            node.step, node.t = s.n, s.t
            node.applied(detail)
            if s.n > 0:              # the state of t_0 went out at the start
                node.publish_state(u=float(s.u[node.index]))
            if link.check(paused=node.halted is not None, watch=False):
                link.publish_cmd(0.0, 0.0, stamp)
            else:
                link.drive(detail, stamp)
            node.step = s.n + 1
            node.own = node.own[:6] + (float(detail),)
        elif kind == 'repeat':       # a repeat: the process sends the answer again, and the robot its command
            link.resend()
        else:
            if kind == 'silent':     # out of the table: the robot stands
                link.publish_cmd(0.0, 0.0, stamp)
            super().lockstep_outcome(kind, detail, s)


class RealtimeRobotDriver(RealtimeDriver):
    """Realtime with a robot (module docstring)."""

    live_parameters = ('stale_after', 'future_tolerance')     # no catch-up: the robot's pose each tick

    def __init__(self, node, stale_after, catch_up_limit, future_tolerance, **robot):
        super().__init__(node, stale_after, catch_up_limit, future_tolerance)
        self.link = RobotLink(node, False, **robot)

    def start(self):
        """Alone: its own timer (`on_tick`) and its own batch of one state per tick on
        /swarm/agent_states, as a lone agent.  Contained: the container gives it its table of
        states heard, its batch writer and a timer on the container's clock (`container_node`)."""
        node = self.node
        if not node.contained:
            follow_the_run_clock(node)
            self.batch = AgentStatesWriter(node, realtime=True)
            self.join(self.batch.tag, self.heard)
            self.timer = node.create_timer(node.dt, self.on_tick)
        node.publish_state()
        self._share_own_state()

    def _share_own_state(self):
        """Its newest state into its table and to the other processes."""
        node = self.node
        self.heard.hear(node.agent_name, (node.t, *node.own[2:]))
        if self.batch is not None:
            self.batch.publish([node])

    def on_tick(self):
        """One control period: the robot's pose, the guard, u (or zero velocity), the state."""
        node, link = self.node, self.link
        now = node._now()
        if link.pose is not None:
            node.core.place(*link.pose[1:], node.core.u_last)
        own, rows, flags = self.table(now)
        if link.neighbours_in_range(rows, own):
            link.guard.neighbour(link.robot_now())
        stamp = link.stamp_now()
        u = 0.0
        if link.check(paused=node.halted is not None):
            link.publish_cmd(0.0, 0.0, stamp)
        else:
            try:
                u = node.core.control(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], node.lam, flags,
                                      node.steering, node.target, node.barrier, row=own, t=now)
            except LawError as err:     # the law failed: the robot stops, the process with one line
                link.publish_cmd(0.0, 0.0, stamp)
                fail(err)
                return
            if not math.isfinite(u):
                node.reject('u-nan', f'non-finite control u={u}; holding u=0')
                u = 0.0
            link.drive(u, stamp)
        node.core.u_last = u
        node.applied(u)
        node.step = P.step_of(now, node.dt)
        node.t = now
        node.publish_state()
        self._share_own_state()


#: the drivers of a robot agent, by mode, or by (mode, robot kind) (`agent_node.driver_class`)
ROBOT_DRIVERS = {'lockstep': LockstepRobotDriver, 'realtime': RealtimeRobotDriver,
                 ('lockstep', 'mujoco'): LockstepMujocoDriver}
