"""What a run's robot world is made of (pure: no ROS import): which agents have robots, where
the robots start, and the scale between model and robot time."""
from __future__ import annotations

import numpy as np

#: the file the robot world writes into the run's output directory at the end (metrics.json
#: carries it as ``summary.robots``)
SUMMARY_FILE = 'robots.json'


def robots_section(scn):
    """The scenario's ``robots`` section (length scale, cruise speed, ...); ValueError if it has
    none: without the scale a model cannot drive a robot."""
    sec = getattr(scn.spec, 'robots', None)
    if sec is None:
        raise ValueError(f'scenario {scn.name!r} has no robots section (length_scale, cruise_speed): '
                         'robots need the scale between the model and metres')
    return sec


def robot_per_model(sec) -> float:
    """Robot seconds per model second: L / v0 (one model unit at v0 m/s takes L / v0 s)."""
    return float(sec.length_scale) / float(sec.cruise_speed)


def chosen_rows(names, chosen) -> list:
    """Roster rows of the agents ``chosen`` (names; empty: every agent), in roster order;
    ValueError naming an agent the roster does not have."""
    row = {nm: i for i, nm in enumerate(names)}
    unknown = [nm for nm in chosen if nm not in row]
    if unknown:
        raise ValueError(f'no agent {", ".join(unknown)} in the scenario (agents {names[0]} .. {names[-1]})')
    return sorted({row[nm] for nm in chosen}) if chosen else list(range(len(names)))


def start_poses(scn, rows, length_scale: float) -> np.ndarray:
    """(K, 3) x, y (m), yaw (rad) in the world frame of the robots at ``rows``: the scenario's
    initial conditions scaled by L."""
    rows = np.asarray(rows, dtype=int)
    return np.column_stack([scn.pos0[rows] * float(length_scale), scn.theta0[rows]])
