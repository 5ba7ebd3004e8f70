"""``swarm run --robots``: which agents drive a robot, and the robot parameters of their nodes
(pure: no ROS, nothing started).

``--robots KIND`` puts every agent on a robot of that kind, ``--robots KIND:SELECTION`` only
the agents named (``agent_0-agent_2``: a range in roster order, ``agent_0,agent_4``: a list,
both mixed); the option may be given more than once for different agents.  KIND is one of
`swarm_core.robot_units.ROBOT_KINDS` other than ``none``: ``external`` (the agents drive
whatever publishes their ``odom`` and reads their ``cmd_vel``; nothing else starts) or
``mujoco`` (the agents drive robots of the MuJoCo world; on the agent's side the same as
external).  The scale comes from the scenario's ``robots:`` section, which such a run needs.

The agents put on ``mujoco`` robots drive robots of one MuJoCo world, the node
``robots`` (`swarm_robots.mujoco_world_node`), which the run starts as one more process (or
node, ``--in-process``).  At the end it leaves its summary (contacts, time at the limits) in
the output directory; metrics.json carries it as ``summary.robots`` (docs/robots.md).
"""
from __future__ import annotations

import json
from pathlib import Path

from swarm_core.robot_units import ROBOT_KINDS
from swarm_robots.world_setup import SUMMARY_FILE

#: the kinds ``--robots`` takes
KINDS = tuple(k for k in ROBOT_KINDS if k != 'none')


def _select(sel: str, names: list, where: str) -> list:
    """Agent names of a selection ``agent_0-agent_2,agent_5`` in roster order."""
    row = {nm: i for i, nm in enumerate(names)}
    out = set()
    for part in [p.strip() for p in sel.split(',')]:
        lo, sep, hi = part.partition('-')
        for end in (lo, hi) if sep else (lo,):
            if end not in row:
                raise ValueError(f'{where}: {end!r} is not an agent of the scenario '
                                 f'({names[0]} ... {names[-1]})' if end else f'{where}: an empty agent name')
        a, b = row[lo], row[hi] if sep else row[lo]
        if a > b:
            raise ValueError(f'{where}: {part!r} is an empty range ({hi} comes before {lo})')
        out.update(range(a, b + 1))
    return [names[i] for i in sorted(out)]


def parse_robots(options, names) -> dict:
    """{agent name: kind} of the agents on robots from the ``--robots`` options (a list of
    ``KIND`` or ``KIND:SELECTION``; None or [] = no robots).  ValueError names the bad part."""
    names = list(names)
    out = {}
    for text in options or []:
        kind, sep, sel = text.partition(':')
        kind = kind.strip()
        where = f'--robots {text}'
        if kind not in KINDS:
            raise ValueError(f'{where}: the kind must be one of {", ".join(KINDS)}')
        chosen = _select(sel, names, where) if sep else names
        twice = [nm for nm in chosen if nm in out]
        if twice:
            raise ValueError(f'{where}: {twice[0]} is already on a robot ({out[twice[0]]})')
        out.update({nm: kind for nm in chosen})
    return out


def robot_parameters(spec, kind: str, mode: str) -> dict:
    """An agent node's parameters for a robot of ``kind`` with the scenario's ``robots:``
    section ``spec`` (`swarm_core.robot_spec.RobotsSpec`) in ``mode``: an external robot in
    realtime lives in wall time (its controller stamps and times out on the system clock)."""
    clock = 'wall' if kind == 'external' and mode == 'realtime' else 'sim'
    return dict(robot=kind, robot_clock=clock,
                length_scale=float(spec.length_scale), cruise_speed=float(spec.cruise_speed),
                max_angular=float(spec.max_angular), odom_timeout=float(spec.odom_timeout),
                neighbour_timeout=float(spec.neighbour_timeout), max_jump=float(spec.max_jump),
                robot_frame=spec.frame, cmd_type=spec.cmd_type)


def robot_steps(scn, robots: dict) -> str | None:
    """Whether the robots of ``robots`` ({name: kind}) can follow the steps of ``scn``
    (`swarm_core.robot_spec.RobotsSpec.step_check`): ValueError naming the scale if a step
    lasts longer than `swarm_core.robot_units.MAX_ROBOT_STEP` robot s; the one warning line if
    the robots brake in every step; None (also without robots, or without a ``robots:`` section,
    which `apply_robots` refuses).  The scenario loader has checked the robot description."""
    if not robots or scn.spec.robots is None:
        return None
    return scn.spec.robots.step_check(scn.dt)


def apply_robots(params: dict, scn, robots: dict, mode: str) -> str | None:
    """Set the robot parameters of the agents in ``robots`` ({name: kind}) in ``params`` (every
    node's parameters); the line that says the scale (None without robots).  Realtime with
    external robots: the world's clock runs at v0/L model s per wall s, since a robot lives in
    wall time (``swarm join``: the run's world does that).  ValueError when the scenario has no
    ``robots:`` section or a step is too long for the robots (`robot_steps`)."""
    if not robots:
        return None
    spec = scn.spec.robots
    if spec is None:
        raise ValueError(f'--robots: the scenario {scn.name!r} has no robots: section '
                         '(length_scale, cruise_speed; see docs/robots.md)')
    robot_steps(scn, robots)
    for nm, kind in robots.items():
        params[f'/{nm}/agent'].update(robot_parameters(spec, kind, mode))
    units = spec.units()
    head = f'{len(robots)} of {len(scn.names)} agents on robots ({", ".join(sorted(set(robots.values())))})'
    if mode == 'realtime' and 'external' in robots.values() and '/world' in params:     # not on swarm join
        params['/world']['rtf'] = units.model_time(1.0)
        head += f', sim clock at {units.model_time(1.0):.3g} model s per wall s'
    return head + '; ' + units.describe(scn.law.cutoff_radius, getattr(scn.law, 'r0', None))


# ------------------------------------------------------------------ the MuJoCo robot world
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
