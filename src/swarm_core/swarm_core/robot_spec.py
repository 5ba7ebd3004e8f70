"""The scenario's ``robots:`` section (`RobotsSpec`, pydantic; no ROS), with the limits of
`swarm_core.robot_units` (`ROBOTS_BOUNDS`, `MAX_ROBOT_STEP`, `DESCRIPTION_FIELDS`).  Apart from
robot_units so that an agent process, which needs the units and the guard, loads no schema."""
from __future__ import annotations

from typing import Literal, Optional

from pydantic import PrivateAttr

from swarm_core.checks import InputError
from swarm_core.robot_units import (
    DESCRIPTION_FIELDS,
    MAX_ROBOT_STEP,
    ROBOTS_BOUNDS,
    ROBOTS_DEFAULTS,
    RobotUnits,
    description_values,
)
from swarm_core.schema import Strict, checked

D = ROBOTS_DEFAULTS


class RobotsSpec(Strict):
    """The scenario's ``robots:`` section (see docs/robots.md), each number in its range
    (`ROBOTS_BOUNDS`)."""
    length_scale: checked(ROBOTS_BOUNDS['length_scale'])                  # L, metres per model unit
    cruise_speed: checked(ROBOTS_BOUNDS['cruise_speed'])                  # v0, m/s
    max_angular: checked(ROBOTS_BOUNDS['max_angular']) = D['max_angular']           # ω_max, rad/s
    odom_timeout: checked(ROBOTS_BOUNDS['odom_timeout']) = D['odom_timeout']        # robot s: older odometry stops it
    neighbour_timeout: checked(ROBOTS_BOUNDS['neighbour_timeout']) = D['neighbour_timeout']  # no neighbour in range
    max_jump: checked(ROBOTS_BOUNDS['max_jump']) = D['max_jump']                    # m beyond v·Δt
    frame: Literal['odom', 'world'] = D['frame']
    cmd_type: Literal['TwistStamped', 'Twist'] = D['cmd_type']
    description: Optional[str] = None             # robot description YAML (default TurtleBot3 Burger)
    _robot: Optional[dict] = PrivateAttr(default=None)        # the description's values, once read

    def units(self) -> 'RobotUnits':
        return RobotUnits(self.length_scale, self.cruise_speed, self.max_angular)

    def take_description(self, data, source: str) -> None:
        """Check the mapping ``data`` read from the description file ``source``
        (`description_values`: InputError naming the field) and keep its values (`robot`)."""
        self._robot = description_values(data, source)

    def robot(self) -> dict:
        """The values of the robot description: the file's once read (`take_description`, as
        the scenario loader does), the Burger's when the section names none; ValueError for a
        file named but not read."""
        if self._robot is not None:
            return self._robot
        if self.description:
            raise ValueError(f'robots.description {self.description}: not read (load the scenario with '
                             'swarm_core.scenario.loader, which reads it)')
        return {name: f.default for name, f in DESCRIPTION_FIELDS.items()}

    def step_check(self, dt: float) -> str | None:
        """A run of these robots at a step of ``dt`` model s: InputError if one step lasts
        longer than `MAX_ROBOT_STEP` robot s; the warning line if it lasts longer than the
        controller's ``cmd_vel_timeout`` (the robots brake in every step: one command per step),
        else None."""
        units = self.units()
        step = units.robot_time(dt)
        scale = (f'robots: a step of dt = {dt:g} model s lasts {step:.3g} robot s (L/v0 = {self.length_scale:g} m '
                 f'/ {self.cruise_speed:g} m/s = {units.seconds_per_model_unit:.3g} s per model unit)')
        if step > MAX_ROBOT_STEP:
            raise InputError(f'{scale}: at most {MAX_ROBOT_STEP:g} robot s (raise cruise_speed, lower length_scale '
                             'or dt)')
        timeout = self.robot()['cmd_vel_timeout']
        if timeout and step > timeout:
            return (f'{scale}, longer than the controller\'s cmd_vel_timeout '
                    f'{timeout:g} s: the robots brake in every step (lower dt, or give the robot description '
                    'a longer cmd_vel_timeout)')
        return None
