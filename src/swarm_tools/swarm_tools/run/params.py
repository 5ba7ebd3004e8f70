"""The parameters of a run's nodes: one function turns a scenario into every node's ROS
parameters (`node_parameters`), and one parameters file holds them all (`write_params_file`)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import yaml

from swarm_core.laws import flat_parameters
from swarm_core.laws.paper.compiled_sums import run_sums
from swarm_core.scenario.loader import ScenarioError, load
from swarm_ros.scenario_params import scenario_parameters


class _QuotedStrings(yaml.SafeDumper):
    """Strings that ROS's parameter-file parser could read as a number or a boolean are quoted:
    it reads a plain ``7710e017`` (a run id) as the double 7.71e+20, where PyYAML would not."""


def _str(dumper, value):
    looks = value[:1] in tuple('0123456789+-.') or value.lower() in (
        '', 'true', 'false', 'yes', 'no', 'on', 'off', 'null', '~', 'y', 'n', 'nan', 'inf')
    return dumper.represent_scalar('tag:yaml.org,2002:str', value, style="'" if looks else None)


_QuotedStrings.add_representer(str, _str)


def load_scenario(prog: str, a):
    """(scenario, the reference the nodes load it by) from a command's ``scenario``, ``seed``,
    ``duration`` and ``dt`` options; a bad scenario prints one line ``PROG: ...`` and gives
    (None, None).  The reference is the resolved path of a YAML file (the nodes may start in
    another directory), else the shipped name."""
    try:
        scn = load(a.scenario, seed=a.seed, duration=a.duration, dt=a.dt)
    except ScenarioError as err:
        print(f'{prog}: {err}', file=sys.stderr)
        return None, None
    why = not_yet_3d(scn, a)
    if why:
        print(f'{prog}: {scn.source}: a 3D scenario (dim: 3) {why}', file=sys.stderr)
        return None, None
    ref = a.scenario
    if Path(a.scenario).suffix in ('.yaml', '.yml') or Path(a.scenario).exists():
        ref = str(Path(a.scenario).resolve())
    return scn, ref


def not_yet_3d(scn, a) -> str | None:
    """What a 3D scenario cannot do on ROS yet with options ``a`` (the rest of a line), or None:
    robots are refused."""
    if scn.dim != 3:
        return None
    if getattr(a, 'robots', None):
        return 'cannot drive robots: robots are planar for now'
    return None


def agent_parameters(scn, i: int, mode: str, pair_sums: str = 'numpy') -> dict:
    noise = scn.spec.noise
    if scn.dim == 3:             # r and the initial frame [x y z] (9 numbers: x, y, z)
        pose = dict(x=float(scn.pos0[i, 0]), y=float(scn.pos0[i, 1]), z=float(scn.pos0[i, 2]), theta=0.0, dim=3,
                    frame=[float(v) for f in scn.frames0 for v in f[i]],
                    ground='' if scn.ground is None else repr(float(scn.ground)))
    else:
        pose = dict(x=float(scn.pos0[i, 0]), y=float(scn.pos0[i, 1]), theta=float(scn.theta0[i]))
    return dict(agent_name=scn.names[i], agent_index=i, agent_names=list(scn.names), leader=False, pair_sums=pair_sums,
                **pose, **flat_parameters(scn.law), dt=scn.dt, mode=mode,
                noise_position=float(noise.position), noise_heading=float(noise.heading),
                seed=int(scn.seed), use_sim_time=True,
                comms=json.dumps(scn.comms_config()) if scn.comms_config() is not None else '')


def node_parameters(scn, scenario_ref: str, mode: str, rtf: float = 1.0, output_dir: str = '',
                    duration: float = 0.0, extra_world=None, compiled: str = 'auto') -> dict:
    """{fully qualified node name: parameters} for every node of a run: the world and the
    commander load the scenario themselves (by reference: swarm_ros.scenario_params), the
    agents get values (`agent_parameters`), with the run's pair sums (``compiled``: auto, on,
    off; `compiled_sums.run_sums` of the run's agents and steps, as `swarm simulate` chooses)."""
    pair_sums = run_sums(len(scn.names), scn.steps, compiled, lockstep=mode == 'lockstep')
    common = dict(scenario_parameters(scn, scenario_ref, duration), mode=mode)
    world = dict(common, rtf=float(rtf), output_dir=str(output_dir), use_sim_time=False, **(extra_world or {}))
    out = {'/world': world, '/commander': dict(common, use_sim_time=True)}
    for i, nm in enumerate(scn.names):
        out[f'/{nm}/agent'] = agent_parameters(scn, i, mode, pair_sums)
    return out


#: the parameters-file section every agent node reads (ROS wildcard: any namespace)
AGENTS_SECTION = '/**/agent'


def write_params_file(params: dict, path: Path) -> Path:
    """One parameters file for every node.  What all agents share (the roster, the law, dt, ...)
    goes once into the wildcard section `AGENTS_SECTION`; each agent's own section keeps only
    what differs (name, index, initial state), so the file grows as N, not N² (the roster in
    every agent's section)."""
    agents = {fqn: p for fqn, p in params.items() if fqn.endswith('/agent')}
    doc = {fqn: {'ros__parameters': p} for fqn, p in params.items() if fqn not in agents}
    if agents:
        first = next(iter(agents.values()))
        shared = {k: v for k, v in first.items() if all(k in p and p[k] == v for p in agents.values())}
        if len(agents) > 1:
            doc[AGENTS_SECTION] = {'ros__parameters': shared}
        else:
            shared = {}
        for fqn, p in agents.items():
            doc[fqn] = {'ros__parameters': {k: v for k, v in p.items() if k not in shared}}
    path.write_text(yaml.dump(doc, Dumper=_QuotedStrings, sort_keys=False))
    return path
