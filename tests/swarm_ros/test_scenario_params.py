"""How the world and the commander get their scenario (swarm_ros.scenario_params), without
ROS: the launcher writes a reference and the run's values, the node loads it again and gets
the scenario the launcher loaded (and so the agents' values came from)."""
from __future__ import annotations

import argparse

import numpy as np
import pytest

from swarm_core.scenario.loader import ScenarioError, load
from swarm_ros.scenario_params import SCENARIO_PARAMETERS, reload_scenario, scenario_parameters
from swarm_tools.run.params import load_scenario, node_parameters

SCENARIO = """\
name: small
seed: 4
dt: 0.2
duration: 30
agents: {count: 5, positions: {rule: disc, radius: 3}}
lambda: {kind: constant, value: 0.5}
faults: [{at: 2, kill: agent_3}]
"""


def _same(a, b):
    assert (a.names, a.seed, a.dt, a.duration, a.steps) == (b.names, b.seed, b.dt, b.duration, b.steps)
    assert np.array_equal(a.pos0, b.pos0) and np.array_equal(a.theta0, b.theta0)
    assert a.spec == b.spec


def test_a_node_reloads_the_scenario_the_launcher_loaded_from_another_directory(tmp_path, monkeypatch):
    (tmp_path / 'small.yaml').write_text(SCENARIO)
    monkeypatch.chdir(tmp_path)
    opts = argparse.Namespace(scenario='small.yaml', seed=11, duration=7.0, dt=0.1)
    scn, ref = load_scenario('swarm run', opts)
    monkeypatch.chdir('/')                     # a node may start elsewhere: the reference is absolute
    params = node_parameters(scn, ref, 'lockstep', duration=scn.duration)
    for node in ('/world', '/commander'):
        mine = {k: params[node][k] for k in SCENARIO_PARAMETERS}
        assert mine == scenario_parameters(scn, ref, scn.duration) and mine['seed'] == 11
        _same(reload_scenario(**mine), scn)
    assert params['/world']['duration'] == params['/commander']['duration'] == 7.0


def test_the_written_values_are_the_declared_parameters_with_their_types():
    scn = load('homotopy_global')
    values = scenario_parameters(scn, 'homotopy_global')
    assert list(values) == list(SCENARIO_PARAMETERS)
    for nm, (default, _text, _lim) in SCENARIO_PARAMETERS.items():
        assert type(values[nm]) is type(default), nm          # ROS refuses a double for an integer
    assert values['duration'] == scn.duration


def test_defaults_mean_the_scenarios_own_values():
    own = load('homotopy_global')
    _same(reload_scenario('homotopy_global'), own)
    _same(reload_scenario(*(d for d, _t, _l in SCENARIO_PARAMETERS.values())), own)
    other = reload_scenario('homotopy_global', seed=3, duration=5.0, dt=0.05)
    assert (other.seed, other.duration, other.dt, other.steps) == (3, 5.0, 0.05, 100)


def test_a_bad_reference_is_a_scenario_error():
    with pytest.raises(ScenarioError, match='no_such_scenario'):
        reload_scenario('no_such_scenario')
