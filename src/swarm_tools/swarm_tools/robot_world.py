"""``swarm run --robots mujoco``: the run's MuJoCo robot world (pure: the launcher's plan;
nothing is started here).

The agents `robot_plan` puts on ``mujoco`` robots drive robots of one MuJoCo world, the node
``robots`` (`swarm_robots.mujoco_world_node`), which the run starts as one more process (or
node, ``--in-process``).  At the end it leaves its summary (contacts, time at the limits) in
the output directory; metrics.json carries it as ``summary.robots`` (docs/robots.md)."""
from __future__ import annotations

import json
from pathlib import Path

from swarm_robots.run_setup import SUMMARY_FILE

#: the robot world's node in a run's parameters
ROBOTS_NODE = '/robots'
#: the robot kind the robot world drives
MUJOCO = 'mujoco'
#: the world's parameters the robot world shares (the scenario it loads, the mode, the run)
SHARED = ('scenario', 'seed', 'duration', 'dt', 'mode', 'run_id', 'output_dir')


def add_robot_world(params: dict, robots: dict) -> None:
    """The robot world node `ROBOTS_NODE` in ``params`` (every node's parameters) for the agents
    ``robots`` ({name: kind}) puts on ``mujoco`` robots; none if there are none."""
    chosen = [nm for nm, kind in robots.items() if kind == MUJOCO]
    if chosen:
        world = params['/world']
        params[ROBOTS_NODE] = dict({k: world[k] for k in SHARED}, robots=','.join(chosen), use_sim_time=True,
                                   hold_timeout=world['missing_timeout'] / 2)
        if world['mode'] == 'lockstep':     # their poses come from the robot world's reports
            world['robot_poses'] = ','.join(chosen)


def read_summary(out_dir) -> dict | None:
    """The robot world's summary (contacts, time at the limits) it wrote into ``out_dir``; None
    if there is none."""
    try:
        return json.loads((Path(out_dir) / SUMMARY_FILE).read_text())
    except (OSError, ValueError):
        return None
