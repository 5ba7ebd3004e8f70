"""``swarm run --robots``: which agents drive robots, and the MuJoCo robot world of a run (pure:
the launcher's plan; nothing is started here).

``--robots mujoco`` puts every agent on a robot of the run's MuJoCo world (the node ``robots``,
`swarm_robots.mujoco_world_node`); ``--robots mujoco:agent_0-agent_2`` only those (a range of
the roster, or names separated by commas); the others stay kinematic.  Each chosen agent gets
the parameter ``robot`` = the kind: it commands its robot on ``/<agent>/cmd_vel`` and reads its
pose from ``/<agent>/odom`` (docs/robots.md)."""
from __future__ import annotations

import json
from pathlib import Path

from swarm_robots.run_setup import SUMMARY_FILE, robots_section

#: the kinds of robot an agent can drive (``--robots KIND[:AGENTS]``)
MUJOCO = 'mujoco'
KINDS = (MUJOCO,)
#: the robot world's node in a run's parameters
ROBOTS_NODE = '/robots'


def parse_robots(text: str, names) -> tuple[str, list]:
    """``KIND`` or ``KIND:AGENTS`` -> (kind, the chosen agents in roster order); AGENTS is a
    comma-separated list of names or ranges of the roster (``agent_0-agent_2``).  ValueError
    naming the bad part."""
    kind, colon, which = text.partition(':')
    if kind not in KINDS:
        raise ValueError(f'--robots {text}: the kind must be one of {", ".join(KINDS)}')
    if not colon:
        return kind, list(names)
    row = {nm: i for i, nm in enumerate(names)}
    rows = set()
    for part in [p.strip() for p in which.split(',')]:
        if part in row:
            rows.add(row[part])
            continue
        lo, sep, hi = part.partition('-')
        if not sep or lo not in row or hi not in row or row[lo] > row[hi]:
            raise ValueError(f'--robots {text}: {part!r} is neither an agent of the scenario nor a range '
                             f'like {names[0]}-{names[-1]}')
        rows.update(range(row[lo], row[hi] + 1))
    return kind, [names[i] for i in sorted(rows)]


def add_robots(params: dict, text: str, scn, common: dict) -> tuple[str, list]:
    """Put the agents ``text`` (``--robots``) chooses on robots in ``params`` (the run's node
    parameters): each gets ``robot`` = the kind, and the MuJoCo world node `ROBOTS_NODE` is
    added with ``common`` (the scenario reference, mode, run id, output_dir).  ValueError for a
    bad option or a scenario without the robots section."""
    kind, chosen = parse_robots(text, list(scn.names))
    try:
        robots_section(scn)
    except ValueError as err:
        raise ValueError(f'--robots {text}: {err}') from None
    for nm in chosen:
        params[f'/{nm}/agent']['robot'] = kind
    if kind == MUJOCO:
        params[ROBOTS_NODE] = dict(common, robots=','.join(chosen), use_sim_time=True)
    return kind, chosen


def read_summary(out_dir) -> dict | None:
    """The robot world's summary (contacts, time at the limits) it wrote into ``out_dir``; None
    if there is none."""
    try:
        return json.loads((Path(out_dir) / SUMMARY_FILE).read_text())
    except (OSError, ValueError):
        return None
