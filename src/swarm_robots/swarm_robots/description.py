"""A differential-drive robot's description (no ROS): geometry, mass, the limits of its
``diff_drive_controller`` and its wheel motors.

The defaults are a TurtleBot3 Burger: wheel radius 0.033 m, wheel separation 0.160 m, footprint
radius 0.105 m, about 1 kg, 0.22 m/s and 2.84 rad/s (ROBOTIS' published specification); the
caster and centre-of-mass offsets and the wheel mass are those of ``turtlebot3_burger.urdf``
(``caster_back_joint`` at x = -0.081 m, ``base_link`` inertial origin x = -0.032 m, wheel links
0.0285 kg).

The acceleration limits are ours (the Burger's published specification gives none): one budget
of 1.0 m/s² at the wheel rim for both axes, so ``max_angular_accel`` = 1.0 / (0.160 / 2) =
12.5 rad/s².  The robot reaches full speed in 0.22 s and full turn rate in 0.23 s, and the rim
acceleration stays far below what the tyres grip (μ·g ≈ 7.8 m/s² at μ = 0.8), so a robot on a
normal floor does not slip unless a description asks for it.  ``wheel_torque`` (1.4 N·m) is of
the order of the stall torque of the Burger's Dynamixel wheel motors.  ``max_wheel_speed``
(7.0 rad/s, a rim speed of 0.231 m/s) is the motors' top speed: enough for the published
0.22 m/s straight on or 2.84 rad/s on the spot (6.9 rad/s at each wheel), not for both at
once, as on the real robot, whose top speeds are its wheels'.  ``diff_drive_controller`` does
not know this limit; the motors clip each wheel's target, and the robot turns less or drives
slower than it was told.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import yaml


class DescriptionError(ValueError):
    """A robot description that cannot be used; the text names the field."""


@dataclass(frozen=True)
class RobotDescription:
    """A differential-drive robot; every length in m, mass in kg, time in s."""
    wheel_radius: float = 0.033
    wheel_separation: float = 0.160
    radius: float = 0.105               # footprint (robot-robot contact) radius
    mass: float = 1.0                   # the whole robot, wheels included
    max_linear: float = 0.22            # m/s, the controller's linear.x.max_velocity
    max_angular: float = 2.84           # rad/s, angular.z.max_velocity
    max_linear_accel: float = 1.0       # m/s², linear.x.max_acceleration
    max_angular_accel: float = 12.5     # rad/s², angular.z.max_acceleration
    wheel_torque: float = 1.4           # N·m, each wheel motor's torque limit
    max_wheel_speed: float = 7.0        # rad/s, each wheel motor's speed limit
    friction: float = 0.8               # wheel-ground sliding friction coefficient
    cmd_vel_timeout: float = 0.5        # s, the controller's cmd_vel_timeout (0 disables it)
    wheel_mass: float = 0.0285          # kg, each wheel (part of `mass`)
    caster_x: float = -0.081            # m, the ball caster behind the wheel axle
    com_x: float = -0.032               # m, the chassis' centre of mass from the wheel axle

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise DescriptionError(f'{f.name}: must be a number (got {value!r})')
            if not math.isfinite(value):
                raise DescriptionError(f'{f.name}: must be finite (got {value!r})')
            if f.name in _SIGNED:
                continue
            if value < 0 or (value == 0 and f.name not in _MAY_BE_ZERO):
                need = '>= 0' if f.name in _MAY_BE_ZERO else '> 0'
                raise DescriptionError(f'{f.name}: must be {need} (got {value!r})')
        if 2 * self.wheel_mass >= self.mass:
            raise DescriptionError(f'wheel_mass: two wheels ({2 * self.wheel_mass} kg) must weigh '
                                   f'less than the robot (mass {self.mass} kg)')
        if self.wheel_separation / 2 >= self.radius:
            raise DescriptionError(f'wheel_separation: the wheels ({self.wheel_separation} m apart) '
                                   f'must fit inside the footprint (radius {self.radius} m)')
        for name in ('caster_x', 'com_x'):
            if abs(getattr(self, name)) >= self.radius:
                raise DescriptionError(f'{name}: must lie inside the footprint '
                                       f'(|{name}| < radius {self.radius} m)')

    @classmethod
    def from_yaml(cls, path) -> 'RobotDescription':
        """A description from a YAML mapping of field: value; fields left out keep the
        TurtleBot3 Burger's values.  Raises `DescriptionError` naming the bad field."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text())
        except OSError as e:
            raise DescriptionError(f'{path}: cannot read ({e.strerror or e})') from None
        except yaml.YAMLError as e:
            raise DescriptionError(f'{path}: not YAML ({e})') from None
        return cls.from_mapping({} if data is None else data, source=str(path))

    @classmethod
    def from_mapping(cls, data, source: str = 'description') -> 'RobotDescription':
        """A description from a mapping (see `from_yaml`)."""
        if not isinstance(data, dict):
            raise DescriptionError(f'{source}: must be a mapping of field: value '
                                   f'(got {type(data).__name__})')
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(str(k) for k in data if k not in known)
        if unknown:
            raise DescriptionError(f'{source}: {unknown[0]}: unknown field '
                                   f'(known: {", ".join(sorted(known))})')
        try:
            return cls(**data)
        except DescriptionError as e:
            raise DescriptionError(f'{source}: {e}') from None


#: fields that are positions (any sign) and fields where 0 means "none"
_SIGNED = frozenset({'caster_x', 'com_x'})
_MAY_BE_ZERO = frozenset({'cmd_vel_timeout'})

TURTLEBOT3_BURGER = RobotDescription()
