"""What a run's robot world is made of (pure: no ROS import): which agents have robots, where
the robots start, and the scale between model and robot (`swarm_core.robot_units`)."""
from __future__ import annotations

import numpy as np

from swarm_core.model.frenet import quaternion_from_heading
from swarm_core.robot_units import odometry_quaternion, wrap_near, yaw_of_quaternion
from swarm_core.scenario.loader import read_description
from swarm_robots.description import TURTLEBOT3_BURGER, RobotDescription
from swarm_robots.timing import TurnLimitClock

#: the file the robot world writes into the run's output directory at the end (metrics.json
#: carries it as ``summary.robots``)
SUMMARY_FILE = 'robots.json'


def robots_section(scn):
    """The scenario's ``robots:`` section (`swarm_core.robot_spec.RobotsSpec`); ValueError if
    it has none: without the scale a model cannot drive a robot."""
    if scn.spec.robots is None:
        raise ValueError(f'scenario {scn.name!r} has no robots: section (length_scale, cruise_speed): '
                         'robots need the scale between the model and metres')
    return scn.spec.robots


def chosen_rows(names, chosen) -> list:
    """Roster rows of the agents ``chosen`` (names; empty: every agent), in roster order;
    ValueError naming an agent the roster does not have."""
    row = {nm: i for i, nm in enumerate(names)}
    unknown = [nm for nm in chosen if nm not in row]
    if unknown:
        raise ValueError(f'no agent {", ".join(unknown)} in the scenario (agents {names[0]} .. {names[-1]})')
    return sorted({row[nm] for nm in chosen}) if chosen else list(range(len(names)))


def start_poses(scn, rows, units) -> np.ndarray:
    """(K, 3) x, y (m), yaw (rad) in the world frame of the robots at ``rows``: the scenario's
    initial conditions in metres (``units``: `swarm_core.robot_units.RobotUnits`)."""
    return np.array([units.start_pose(float(scn.pos0[i, 0]), float(scn.pos0[i, 1]), float(scn.theta0[i]))
                     for i in rows], dtype=float).reshape(-1, 3)


class OdometryPoses:
    """Each robot's pose in model units as its agent reads its odometry (`swarm_agent.robot_driver`):
    the orientation through the message's quaternion, its own odom frame turned into the common
    one from its start pose (``frame: odom``; ``world``: ground truth), metres into model units,
    the yaw unwrapped near the robot's heading before (first near its θ0, from the odometry of
    t = 0).  The robot engine and the robot world's lockstep reports (``/lockstep/robot_states``)
    both read their robots through it.  ``world``: a `physics.RobotWorld`."""

    def __init__(self, world, scn, rows, units, frame: str):
        self.units = units
        self.odom = world.odometry_pose if frame == 'odom' else world.ground_truth
        starts = start_poses(scn, rows, units).tolist()
        self.starts = starts if frame == 'odom' else [None] * len(starts)
        self.heading = [float(scn.theta0[i]) for i in rows]
        self.first = self._table(*scn.pos0[rows].T, scn.theta0[rows])   # t_0: the scenario's, as the agents have it
        self.read()

    def read(self) -> list:
        """[(x, y, θ)] of the robots now, in model units; θ unwrapped (and kept as the heading)."""
        out = []
        for k, (x, y, yaw) in enumerate(self.odom()[:, :3].tolist()):
            yaw = yaw_of_quaternion(0.0, 0.0, *odometry_quaternion(yaw))
            x, y, yaw = self.units.to_model(x, y, yaw, self.starts[k])
            self.heading[k] = wrap_near(yaw, self.heading[k])
            out.append((x, y, self.heading[k]))
        return out

    def table(self) -> np.ndarray:
        """(4, K) x, y, qz, qw of the robots now, as their agents would publish them (``first``:
        those of t_0, the scenario's initial conditions)."""
        return self._table(*np.array(self.read(), dtype=float).reshape(-1, 3).T)

    @staticmethod
    def _table(x, y, theta) -> np.ndarray:
        return np.stack([x, y, *quaternion_from_heading(theta)])


def robot_description(sec) -> RobotDescription:
    """The robot description ``sec`` (the ``robots:`` section) names, default a TurtleBot3
    Burger.  The scenario loader has read its file, relative to the scenario, with the limits of
    a scenario file, and checked it (`swarm_core.scenario.loader.read_description`): this
    builds the robot of those values.  A section not loaded with a scenario reads its file
    here, relative to the working directory.  ValueError (`ScenarioError`, `DescriptionError`)
    naming the file and the field."""
    if not sec.description:
        return TURTLEBOT3_BURGER
    try:
        values = sec.robot()
    except ValueError:                  # a section made without the loader: read it now
        read_description(sec)
        values = sec.robot()
    return RobotDescription(**values)


def turn_limit_clock(world, sec, description):
    """``world`` (a `physics.RobotWorld`) counting the time each robot is commanded at the
    turn-rate limit: the smaller of the scenario's and the description's."""
    return TurnLimitClock(world, min(sec.max_angular, description.max_angular), description.cmd_vel_timeout)
