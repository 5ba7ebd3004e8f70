"""The scenario of the world and the commander: given by reference in their ROS parameters
(``scenario``: a shipped name or a YAML path; ``seed``, ``duration``, ``dt``: the run's values)
and loaded by the node itself, the same way for both (`declare_scenario`).

Agents are given values instead (their initial state, the law, dt, seed, the roster: the
launcher's ``swarm_tools.run.params``).  The world and the commander run what the scenario
nests (the λ schedule, leader rule and steering programs, faults, comms events, reunions),
which flat ROS parameters do not hold, and every process of a run parses the whole parameters
file: a reference keeps that file small however large the scenario.  See docs/ros-graph.md."""
from __future__ import annotations

from swarm_core.checks import DT_BOUND, DURATION_BOUND
from swarm_core.scenario.loader import ScenarioError, load
from swarm_ros.rosutil import ParameterError, declare

#: name -> (default, description, limits); 0 / -1: the scenario's own value
SCENARIO_PARAMETERS = {
    'scenario': ('homotopy_global', 'scenario name or YAML path; the node loads it (λ schedule, leaders, '
                 'faults, comms, target, barrier)', {}),
    'seed': (-1, "seed (-1: the scenario's)", dict(lo=-1, hi=2**31 - 1)),
    'duration': (0.0, "run length in sim s (0: the scenario's)", dict(lo=0.0, hi=DURATION_BOUND.hi)),
    'dt': (0.0, "step (0: the scenario's)", dict(lo=0.0, hi=DT_BOUND.hi)),
}


def scenario_parameters(scn, ref: str, duration: float = 0.0) -> dict:
    """The values of `SCENARIO_PARAMETERS` that make a node load ``scn`` again: its
    reference ``ref`` and its seed, ``duration`` (0: the scenario's) and dt."""
    return dict(scenario=str(ref), seed=int(scn.seed), duration=float(duration or scn.duration), dt=float(scn.dt))


def reload_scenario(scenario: str, seed: int = -1, duration: float = 0.0, dt: float = 0.0):
    """The scenario the values of `SCENARIO_PARAMETERS` name (swarm_core.scenario.loader.load;
    raises its ScenarioError)."""
    return load(scenario, seed=None if seed < 0 else seed, duration=duration or None, dt=dt or None)


def declare_scenario(node):
    """Declare `SCENARIO_PARAMETERS` on ``node`` (with descriptions and ranges) and load the
    scenario they name; a bad one raises ``ParameterError('parameter scenario: ...')``."""
    # read once, at the start: read-only (`ros2 param set /world dt 0.0` is refused)
    values = {nm: declare(node, nm, default, text, read_only=True, **lim)
              for nm, (default, text, lim) in SCENARIO_PARAMETERS.items()}
    try:
        return reload_scenario(**values)
    except ScenarioError as err:
        raise ParameterError(f'parameter scenario: {err}') from None
