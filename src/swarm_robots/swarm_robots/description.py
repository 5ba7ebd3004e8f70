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
from dataclasses import dataclass

from swarm_core.checks import InputError
from swarm_core.robot_units import DESCRIPTION_FIELDS, check_description, description_values
from swarm_core.scenario.loader import ScenarioError, read_yaml_file

#: each field's default, the Burger's (its limits: `swarm_core.robot_units.DESCRIPTION_FIELDS`)
_BURGER = {name: f.default for name, f in DESCRIPTION_FIELDS.items()}


class DescriptionError(ValueError):
    """A robot description that cannot be used; the text names the field."""


@dataclass(frozen=True)
class RobotDescription:
    """A differential-drive robot; every length in m, mass in kg, time in s."""
    wheel_radius: float = _BURGER['wheel_radius']
    wheel_separation: float = _BURGER['wheel_separation']
    radius: float = _BURGER['radius']                   # footprint (robot-robot contact) radius
    mass: float = _BURGER['mass']                       # the whole robot, wheels included
    max_linear: float = _BURGER['max_linear']           # m/s, the controller's linear.x.max_velocity
    max_angular: float = _BURGER['max_angular']         # rad/s, angular.z.max_velocity
    max_linear_accel: float = _BURGER['max_linear_accel']       # m/s², linear.x.max_acceleration
    max_angular_accel: float = _BURGER['max_angular_accel']     # rad/s², angular.z.max_acceleration
    wheel_torque: float = _BURGER['wheel_torque']       # N·m, each wheel motor's torque limit
    max_wheel_speed: float = _BURGER['max_wheel_speed']         # rad/s, each wheel motor's speed limit
    friction: float = _BURGER['friction']               # wheel-ground sliding friction coefficient
    cmd_vel_timeout: float = _BURGER['cmd_vel_timeout']         # s, the controller's (0 disables it)
    wheel_mass: float = _BURGER['wheel_mass']           # kg, each wheel (part of `mass`)
    caster_x: float = _BURGER['caster_x']               # m, the ball caster behind the wheel axle
    com_x: float = _BURGER['com_x']                     # m, the chassis' centre of mass from the wheel axle

    def __post_init__(self):
        try:                        # each field in its range, the parts inside the footprint
            check_description(dataclasses.asdict(self))
        except InputError as e:
            raise DescriptionError(str(e)) from None

    @classmethod
    def from_yaml(cls, path) -> 'RobotDescription':
        """A description from a YAML mapping of field: value, read with the limits of a
        scenario file (size, no aliases, depth; a regular file); fields left out keep the
        TurtleBot3 Burger's values.  Raises `DescriptionError` naming the file and the field."""
        try:
            data = read_yaml_file(path, 'robot description')
        except ScenarioError as e:
            raise DescriptionError(str(e)) from None
        return cls.from_mapping({} if data is None else data, source=str(path))

    @classmethod
    def from_mapping(cls, data, source: str = 'description') -> 'RobotDescription':
        """A description from a mapping (see `from_yaml`)."""
        try:
            return cls(**description_values(data, source))
        except InputError as e:
            raise DescriptionError(str(e)) from None


TURTLEBOT3_BURGER = RobotDescription()
