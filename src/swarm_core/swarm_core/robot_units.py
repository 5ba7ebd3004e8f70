"""From the model's units to a robot's, and the robot agent's safety guard (no ROS).

The model is dimensionless: every agent flies at unit speed with curvature u (eq. 1).  A length
scale L (metres per model unit) and a cruise speed v0 (m/s) map it to a differential-drive
robot (`RobotUnits`):

- ``linear.x = v0``, ``angular.z = clip(v0·u/L, −ω_max, ω_max)``; a clipped command is counted
  (`RobotUnits.command`), never hidden;
- robot time s = model time τ · L / v0 (one lockstep step of dt model units is dt·L/v0 robot s);
- a robot pose (metres, yaw) is x/L, y/L, yaw in model units, after the start-pose transform
  when each robot's odometry starts at (0, 0, 0) in its own ``odom`` frame (`RobotUnits.to_model`).

`RobotsSpec` is the scenario's ``robots:`` section.  `SafetyGuard` decides when a robot agent
stops its robot (stale odometry, no neighbour in radio range) and resumes it, and which
odometry it rejects (not finite, or a jump physics does not allow), with rate-limited reasons.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, Optional

import numpy as np

from swarm_core.schema import Length, NonNeg, Positive, Strict

#: TurtleBot3 Burger's largest turn rate (rad/s), the default ω_max
DEFAULT_MAX_ANGULAR = 2.84
#: what an agent's ``robot`` parameter may be: its own kinematic point, or a robot behind
#: ``/<agent>/cmd_vel`` and ``/<agent>/odom`` (``mujoco``: the same on the agent's side)
ROBOT_KINDS = ('none', 'external', 'mujoco')
#: which agents a study's run puts on robots (a study's ``robot_set``; `swarm_robots.engine`):
#: none, the first half of the roster (rounded up), or all
ROBOT_SETS = ('none', 'half', 'all')
#: where the odometry's pose is: each robot's own ``odom`` frame from (0, 0, 0), or one common frame
ROBOT_FRAMES = ('odom', 'world')
#: the command message: Jazzy's diff_drive_controller takes TwistStamped, some drivers Twist
CMD_TYPES = ('TwistStamped', 'Twist')


class RobotsSpec(Strict):
    """The scenario's ``robots:`` section (see docs/robots.md)."""
    length_scale: Length                          # L, metres per model unit
    cruise_speed: Positive                        # v0, m/s
    max_angular: Positive = DEFAULT_MAX_ANGULAR   # ω_max, rad/s
    odom_timeout: Positive = 0.5                  # robot s: older odometry stops the robot
    neighbour_timeout: Positive = 2.0             # robot s without a neighbour in radio range stops it
    max_jump: NonNeg = 0.5                        # m a pose may move beyond v·Δt
    frame: Literal['odom', 'world'] = 'odom'
    cmd_type: Literal['TwistStamped', 'Twist'] = 'TwistStamped'
    description: Optional[str] = None             # robot description YAML (default TurtleBot3 Burger)

    def units(self) -> 'RobotUnits':
        return RobotUnits(self.length_scale, self.cruise_speed, self.max_angular)


@dataclass
class RobotUnits:
    """The map between model units and a robot's (module docstring); counts clipped commands."""
    length_scale: float           # L (m per model unit)
    cruise_speed: float           # v0 (m/s)
    max_angular: float = DEFAULT_MAX_ANGULAR   # ω_max (rad/s)
    commands: int = 0             # commands made (`command`)
    saturated: int = 0            # of those, clipped at ±ω_max

    def __post_init__(self):
        for name in ('length_scale', 'cruise_speed', 'max_angular'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f'{name} must be a finite number > 0, got {v!r}')

    # -- time
    @property
    def seconds_per_model_unit(self) -> float:
        """Robot seconds per model time unit: L / v0."""
        return self.length_scale / self.cruise_speed

    def robot_time(self, tau):
        """Robot seconds of model time τ: τ·L/v0."""
        return tau * self.seconds_per_model_unit

    def model_time(self, s):
        """Model time of robot seconds s: s·v0/L."""
        return s / self.seconds_per_model_unit

    # -- commands
    def omega(self, u) -> np.ndarray:
        """Unclipped turn rate v0·u/L (rad/s) of curvature u (model units)."""
        return self.cruise_speed * np.asarray(u, float) / self.length_scale

    def saturates(self, u) -> np.ndarray:
        """Whether curvature u needs more than ω_max."""
        return np.abs(self.omega(u)) > self.max_angular

    def command(self, u: float) -> tuple[float, float, bool]:
        """(linear.x, angular.z, clipped) for curvature u; counted in `commands`/`saturated`.
        A non-finite u commands straight on (ω = 0) and is not counted as clipped."""
        u = float(u)
        if not math.isfinite(u):
            u = 0.0
        w = float(self.omega(u))
        m = self.max_angular
        clipped = abs(w) > m
        self.commands += 1
        self.saturated += int(clipped)
        return self.cruise_speed, float(min(max(w, -m), m)), clipped

    @property
    def saturated_fraction(self) -> float:
        return self.saturated / self.commands if self.commands else 0.0

    # -- poses
    def start_pose(self, x: float, y: float, theta: float) -> tuple[float, float, float]:
        """The robot's start pose in metres (the scenario's initial condition, model units, × L)."""
        return x * self.length_scale, y * self.length_scale, theta

    def to_model(self, x: float, y: float, yaw: float, start=None) -> tuple[float, float, float]:
        """A robot pose (metres, yaw) in model units.  ``start`` (x0, y0, θ0 in metres, common
        frame): the pose is in the robot's own odom frame, which starts at (0, 0, 0) there."""
        if start is not None:
            x0, y0, th0 = start
            c, s = math.cos(th0), math.sin(th0)
            x, y, yaw = x0 + c * x - s * y, y0 + s * x + c * y, th0 + yaw
        return x / self.length_scale, y / self.length_scale, yaw

    def describe(self, cutoff_radius: float, r0: float | None = None) -> str:
        """One line: the scale and the model's lengths in metres (printed at start)."""
        L = self.length_scale
        r = '' if r0 is None else f'r0 = {r0 * L:.3g} m, '
        u_max = self.max_angular * L / self.cruise_speed
        return (f'robots: L = {L:g} m per unit, v0 = {self.cruise_speed:g} m/s: {r}w = {cutoff_radius * L:.3g} m, '
                f'1 model s = {self.seconds_per_model_unit:.3g} robot s, ω_max = {self.max_angular:g} rad/s '
                f'(|u| ≤ {u_max:.3g} before it clips)')


def odometry_quaternion(yaw: float) -> tuple[float, float]:
    """(z, w) of a ``nav_msgs/Odometry`` pose's orientation at planar yaw (x = y = 0), as the
    robot world writes it."""
    return math.sin(yaw / 2), math.cos(yaw / 2)


def yaw_of_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Yaw of a quaternion (x, y, z, w), as a robot agent reads its odometry (NaN in, NaN out)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def wrap_near(yaw: float, theta: float) -> float:
    """The angle equal to ``yaw`` (mod 2π) nearest the unwrapped heading ``theta``."""
    return theta + math.remainder(yaw - theta, 2 * math.pi)


def reported_heading(qz: float, qw: float, theta: float) -> float:
    """Lockstep on a MuJoCo robot: an agent's heading from its row of the step's table (the
    robot world's report, planar quaternion ``qz``, ``qw``), unwrapped near its heading
    ``theta`` before; only a radio model's law reads it (the table's quaternion is the frame)."""
    return wrap_near(2.0 * math.atan2(qz, qw), theta)


# ------------------------------------------------------------------ safety guard

@dataclass
class RateLimit:
    """At most one line per key every ``every`` seconds (the guard's reasons, rejected odometry)."""
    every: float = 5.0
    last: dict = field(default_factory=dict)
    held: dict = field(default_factory=dict)     # key -> lines left out since the last one said

    def __call__(self, key: str, now: float) -> int | None:
        """None: stay quiet; else how many lines of this key were left out before this one."""
        t = self.last.get(key)
        if t is not None and now - t < self.every:
            self.held[key] = self.held.get(key, 0) + 1
            return None
        self.last[key] = now
        return self.held.pop(key, 0)


@dataclass
class Odom:
    """One accepted odometry reading: robot time it arrived, pose (m, yaw) as given."""
    t: float
    x: float
    y: float
    yaw: float


class SafetyGuard:
    """When a robot agent stops its robot and when it lets it go again (times in robot s).

    - `odometry` checks a reading: not finite, or farther from the last accepted one than
      ``max_speed``·Δt + ``max_jump`` (m), and it is rejected (a reason; never fed to the law);
    - `neighbour` notes that a neighbour's state within radio range arrived;
    - `decide` gives ('stop', reason) when the newest accepted odometry is older than
      ``odom_timeout`` (or none came yet) or no neighbour was in range for ``neighbour_timeout``
      (``needs_neighbours``: a lone agent has none), ('resume', '') when both are fresh again,
      or None when nothing changes.  ``paused``: the agent is paused (fault), a stop of its own."""

    def __init__(self, max_speed: float, odom_timeout: float = 0.5, neighbour_timeout: float = 2.0,
                 max_jump: float = 0.5, needs_neighbours: bool = True, start: float = 0.0):
        self.max_speed = float(max_speed)
        self.odom_timeout = float(odom_timeout)
        self.neighbour_timeout = float(neighbour_timeout)
        self.max_jump = float(max_jump)
        self.needs_neighbours = needs_neighbours
        self.last: Odom | None = None
        self.heard = float(start)          # when a neighbour in range was last heard (start: grace)
        self.stopped: str | None = None    # the reason the robot is stopped, None while it drives
        self.started = False               # `decide` was called
        self.rejected = 0

    def odometry(self, t: float, x: float, y: float, yaw: float) -> str | None:
        """Accept a reading at robot time t (None) or say why it is rejected."""
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            why = f'odometry not finite: x={x!r}, y={y!r}, yaw={yaw!r}'
        elif self.last is not None:
            jump = math.hypot(x - self.last.x, y - self.last.y)
            allowed = self.max_speed * max(0.0, t - self.last.t) + self.max_jump
            why = (f'odometry jumped {jump:.3g} m in {t - self.last.t:.3g} s (at most {allowed:.3g} m)'
                   if jump > allowed else None)
        else:
            why = None
        if why is not None:
            self.rejected += 1
            return why
        self.last = Odom(t, x, y, yaw)
        return None

    def neighbour(self, t: float) -> None:
        self.heard = max(self.heard, t)

    def reason(self, t: float, paused: bool = False, watch: bool = True) -> str | None:
        """Why the robot must stand still at robot time t, None if it may drive (``watch``
        False: only a pause counts; lockstep time waits for every robot's odometry)."""
        if paused:
            return 'paused'
        if not watch:
            return None
        if self.last is None:
            return 'no odometry yet'
        age = t - self.last.t
        if age > self.odom_timeout:
            return f'odometry {age:.3g} s old (timeout {self.odom_timeout:g} s)'
        quiet = t - self.heard
        if self.needs_neighbours and quiet > self.neighbour_timeout:
            return f'no neighbour in radio range for {quiet:.3g} s (timeout {self.neighbour_timeout:g} s)'
        return None

    def decide(self, t: float, paused: bool = False, watch: bool = True) -> tuple[str, str] | None:
        """('stop', reason) / ('resume', '') when the robot's state changes at robot time t;
        the first call always says one (the robot stands until then)."""
        why = self.reason(t, paused, watch)
        if not self.started:
            self.started = True
            self.stopped = why
            return ('stop', why) if why is not None else ('resume', '')
        if why is not None and self.stopped is None:
            self.stopped = why
            return 'stop', why
        if why is None and self.stopped is not None:
            self.stopped = None
            return 'resume', ''
        return None
