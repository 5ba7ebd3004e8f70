"""From the model's units to a robot's, and the robot agent's safety guard (no ROS).

The model is dimensionless: every agent flies at unit speed with curvature u (eq. 1).  A length
scale L (metres per model unit) and a cruise speed v0 (m/s) map it to a differential-drive
robot (`RobotUnits`):

- ``linear.x = v0``, ``angular.z = clip(v0·u/L, −ω_max, ω_max)``; a clipped command is counted
  (`RobotUnits.command`), never hidden;
- robot time s = model time τ · L / v0 (one lockstep step of dt model units is dt·L/v0 robot s);
- a robot pose (metres, yaw) is x/L, y/L, yaw in model units, after the start-pose transform
  when each robot's odometry starts at (0, 0, 0) in its own ``odom`` frame (`RobotUnits.to_model`).

`swarm_core.robot_spec.RobotsSpec` is the scenario's ``robots:`` section, `DESCRIPTION_FIELDS`
the fields of the robot description it may name (`swarm_robots.description`): the limits of both
are here, in one place
(`ROBOTS_BOUNDS`, `MAX_ROBOT_STEP`, `DESCRIPTION_FIELDS`; docs/robots.md, "Limits").
`SafetyGuard` decides when a robot agent stops its robot (stale odometry, no neighbour in radio
range) and resumes it, and which odometry it rejects (not finite, or a jump physics does not
allow), with rate-limited reasons.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from swarm_core.checks import Bound, InputError

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


# ------------------------------------------------------------------ the limits (one place)

@dataclass(frozen=True)
class DescriptionField:
    """One number of a robot description: the TurtleBot3 Burger's value and its limits."""
    default: float
    bound: Bound
    off: bool = False            # 0 is allowed too, and means "none" (cmd_vel_timeout 0 disables it)

    def check(self, value) -> None:
        """InputError (the bound's one text) unless ``value`` is allowed."""
        if self.off and isinstance(value, (int, float)) and not isinstance(value, bool) and value == 0:
            return
        if not self.bound.ok(value):
            raise InputError(self.bound.error(value) + (' (or 0: none)' if self.off else ''))


def _field(name, default, lo, hi, off=False):
    return name, DescriptionField(default, Bound(name, lo, hi), off)


#: a robot description's numbers (`swarm_robots.description.RobotDescription`; lengths in m,
#: masses in kg, times in s): the TurtleBot3 Burger's value, which a description file leaves
#: out, and the range that makes physical sense (a robot from a few millimetres to a few metres,
#: from a gram to ten tonnes; limits that let it move at all: no acceleration, torque, wheel
#: speed or grip of 1e-300)
DESCRIPTION_FIELDS = dict([
    _field('wheel_radius', 0.033, 1e-3, 1.0),
    _field('wheel_separation', 0.160, 1e-3, 10.0),
    _field('radius', 0.105, 1e-3, 10.0),                 # footprint (robot-robot contact)
    _field('mass', 1.0, 1e-3, 1e4),                      # the whole robot, wheels included
    _field('max_linear', 0.22, 1e-3, 100.0),             # m/s, linear.x.max_velocity
    _field('max_angular', 2.84, 1e-3, 100.0),            # rad/s, angular.z.max_velocity
    _field('max_linear_accel', 1.0, 1e-2, 1e3),          # m/s², linear.x.max_acceleration
    _field('max_angular_accel', 12.5, 1e-2, 1e4),        # rad/s², angular.z.max_acceleration
    _field('wheel_torque', 1.4, 1e-3, 1e4),              # N·m, each wheel motor's torque limit
    _field('max_wheel_speed', 7.0, 1e-2, 1e4),           # rad/s, each wheel motor's speed limit
    _field('friction', 0.8, 1e-2, 10.0),                 # wheel-ground sliding friction coefficient
    _field('cmd_vel_timeout', 0.5, 0.02, 3600.0, off=True),   # longer than two controller periods
    _field('wheel_mass', 0.0285, 1e-4, 1e3),             # each wheel (part of `mass`)
    _field('caster_x', -0.081, -10.0, 10.0),             # the ball caster behind the wheel axle
    _field('com_x', -0.032, -10.0, 10.0),                # the chassis' centre of mass from the axle
])
#: TurtleBot3 Burger's largest turn rate (rad/s), the default ω_max
DEFAULT_MAX_ANGULAR = DESCRIPTION_FIELDS['max_angular'].default

#: the numbers of the scenario's ``robots:`` section and the range of each that makes physical
#: sense
ROBOTS_BOUNDS = {b.name: b for b in (
    Bound('length_scale', 1e-3, 1e3),          # L, m per model unit: a millimetre to a kilometre
    Bound('cruise_speed', 1e-3, 100.0),        # v0, m/s: a millimetre per second to 100 m/s
    Bound('max_angular', 1e-3, 100.0),         # ω_max, rad/s
    Bound('odom_timeout', 1e-2, 3600.0),       # robot s: a controller period to an hour
    Bound('neighbour_timeout', 1e-2, 3600.0),  # robot s
    Bound('max_jump', 0.0, 1e3),               # m
)}
#: the defaults of the ``robots:`` fields that have one (`swarm_core.robot_spec.RobotsSpec`, and
#: the robot agent's parameters): ω_max rad/s, the timeouts robot s, the jump m
ROBOTS_DEFAULTS = dict(max_angular=DEFAULT_MAX_ANGULAR, odom_timeout=0.5, neighbour_timeout=2.0, max_jump=0.5,
                       frame='odom', cmd_type='TwistStamped')
#: most robot seconds one step of the model may last (dt·L/v0): a robot gets one command per
#: step, and the MuJoCo world runs this much physics for each step while the world waits
MAX_ROBOT_STEP = 10.0


def check_description(values: dict) -> None:
    """InputError naming the field unless ``values`` (every field of `DESCRIPTION_FIELDS`) is a
    robot that can be built: each number in its range, the wheels inside the footprint and
    lighter than the robot, the caster and the centre of mass inside the footprint."""
    for name, f in DESCRIPTION_FIELDS.items():
        f.check(values[name])
    v = values
    if 2 * v['wheel_mass'] >= v['mass']:
        raise InputError(f'wheel_mass: two wheels ({2 * v["wheel_mass"]} kg) must weigh less than the robot '
                         f'(mass {v["mass"]} kg)')
    if v['wheel_separation'] / 2 >= v['radius']:
        raise InputError(f'wheel_separation: the wheels ({v["wheel_separation"]} m apart) must fit inside the '
                         f'footprint (radius {v["radius"]} m)')
    for name in ('caster_x', 'com_x'):
        if abs(v[name]) >= v['radius']:
            raise InputError(f'{name}: must lie inside the footprint (|{name}| < radius {v["radius"]} m)')


def description_values(data, source: str = 'description') -> dict:
    """Every field of a robot description: those of ``data`` (the mapping of field: value a
    description file holds) over the Burger's, checked (`check_description`); InputError
    naming ``source`` and the field.  An empty file (None) is the Burger."""
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise InputError(f'{source}: must be a mapping of field: value (got {type(data).__name__})')
    unknown = sorted(str(k) for k in data if k not in DESCRIPTION_FIELDS)
    if unknown:
        raise InputError(f'{source}: {unknown[0]}: unknown field (known: {", ".join(sorted(DESCRIPTION_FIELDS))})')
    values = {name: f.default for name, f in DESCRIPTION_FIELDS.items()} | data
    try:
        check_description(values)
    except InputError as err:
        raise InputError(f'{source}: {err}') from None
    return values


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


#: robot s over which the odometry guard bounds a walk (`SafetyGuard.odometry`): readings each
#: within ``max_jump`` of the one before add up to at most ``max_jump`` beyond v·Δt in this long
ODOM_WINDOW = 1.0


@dataclass
class Odom:
    """One accepted odometry reading: robot time it arrived, pose (m, yaw) as given."""
    t: float
    x: float
    y: float
    yaw: float


class SafetyGuard:
    """When a robot agent stops its robot and when it lets it go again (times in robot s).

    - `odometry` checks a reading: not finite, or farther than ``max_speed``·Δt + ``max_jump``
      (m) from the last accepted one, or from the one accepted up to `ODOM_WINDOW` before (so
      small jumps cannot add up: per second a walk gains at most ``max_jump`` on the speed
      bound), and it is rejected (a reason; never fed to the law);
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
        self.anchor: Odom | None = None    # an accepted reading up to ODOM_WINDOW old
        self.heard = float(start)          # when a neighbour in range was last heard (start: grace)
        self.stopped: str | None = None    # the reason the robot is stopped, None while it drives
        self.started = False               # `decide` was called
        self.rejected = 0

    def odometry(self, t: float, x: float, y: float, yaw: float) -> str | None:
        """Accept a reading at robot time t (None) or say why it is rejected."""
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            why = f'odometry not finite: x={x!r}, y={y!r}, yaw={yaw!r}'
        else:
            why = self._jump(self.last, t, x, y) or self._jump(self.anchor, t, x, y)
        if why is not None:
            self.rejected += 1
            return why
        self.last = Odom(t, x, y, yaw)
        if self.anchor is None or t - self.anchor.t >= ODOM_WINDOW:
            self.anchor = self.last
        return None

    def _jump(self, since: Odom | None, t: float, x: float, y: float) -> str | None:
        """Why (x, y) at t is farther from the reading ``since`` than ``max_speed``·Δt + ``max_jump``."""
        if since is None:
            return None
        jump = math.hypot(x - since.x, y - since.y)
        allowed = self.max_speed * max(0.0, t - since.t) + self.max_jump
        return (f'odometry jumped {jump:.3g} m in {t - since.t:.3g} s (at most {allowed:.3g} m)'
                if jump > allowed else None)

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
