"""What a run's robot world is made of (pure: no ROS import): which agents have robots, where
the robots start, and the scale between model and robot (`swarm_core.robot_units`)."""
from __future__ import annotations

import numpy as np

#: the file the robot world writes into the run's output directory at the end (metrics.json
#: carries it as ``summary.robots``)
SUMMARY_FILE = 'robots.json'


def robots_section(scn):
    """The scenario's ``robots:`` section (`swarm_core.robot_units.RobotsSpec`); ValueError if
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


def robot_description(sec):
    """The robot description ``sec`` (the ``robots:`` section) names, default a TurtleBot3
    Burger; OSError or ValueError if its file cannot be read."""
    from .description import TURTLEBOT3_BURGER, RobotDescription
    return RobotDescription.from_yaml(sec.description) if sec.description else TURTLEBOT3_BURGER


def turn_limit_clock(world, sec, description):
    """``world`` (a `physics.RobotWorld`) counting the time each robot is commanded at the
    turn-rate limit: the smaller of the scenario's and the description's."""
    from .timing import TurnLimitClock
    return TurnLimitClock(world, min(sec.max_angular, description.max_angular), description.cmd_vel_timeout)
