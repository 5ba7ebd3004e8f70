"""Every number of a scenario's ``robots:`` section and of the robot description it names has a
range that makes physical sense, and the description file is read with a scenario file's limits,
relative to the scenario, when the scenario is loaded: one line naming the field, the value and
the range, before anything runs (no ROS)."""
from __future__ import annotations

import os
import re
import time

import pytest
import yaml

from swarm_core import study as st
from swarm_core.robot_spec import RobotsSpec
from swarm_core.robot_units import DESCRIPTION_FIELDS, MAX_ROBOT_STEP, ROBOTS_BOUNDS
from swarm_core.scenario import loader as scenario
from swarm_core.scenario.loader import ScenarioError, load, parse

ROBOTS = dict(length_scale=0.3, cruise_speed=0.15)
BASE = dict(name='r', dt=0.1, duration=1.0, agents=dict(count=3), robots=ROBOTS)


def _outside(bound):
    """A value below the range (a tiny one where the range starts above 0) and one above it."""
    return [bound.lo / 10 if bound.lo > 0 else bound.lo - 1, bound.hi * 10]


def _range(bound) -> str:
    return f'[{bound.lo:g}, {bound.hi:g}]'


@pytest.mark.parametrize('name, value', [(b.name, v) for b in ROBOTS_BOUNDS.values() for v in _outside(b)])
def test_each_robots_number_outside_its_range_is_one_line(name, value):
    """length_scale 1e-4 (robots that never move), cruise_speed 1000 m/s (which every agent
    refused, after the start) and the like passed the check."""
    bound = ROBOTS_BOUNDS[name]
    with pytest.raises(ScenarioError) as e:
        parse(dict(BASE, robots=dict(ROBOTS, **{name: value})), 'x.yaml')
    line = str(e.value)
    assert '\n' not in line and f'robots.{name}' in line and f'{name}={value!r}' in line and _range(bound) in line
    for edge in (bound.lo, bound.hi):                 # the range itself is allowed
        parse(dict(BASE, robots=dict(ROBOTS, **{name: edge})), 'x.yaml')


@pytest.mark.parametrize('name, value', [(n, v) for n, f in DESCRIPTION_FIELDS.items() for v in _outside(f.bound)])
def test_each_number_of_a_robot_description_outside_its_range_is_one_line(tmp_path, name, value):
    """Accelerations of 1e-300 (a robot that never moves) and the like, in the description file a
    scenario names: refused when the scenario is loaded."""
    (tmp_path / 'robot.yaml').write_text(yaml.safe_dump({name: value}))
    path = tmp_path / 'scn.yaml'
    path.write_text(yaml.safe_dump(dict(BASE, robots=dict(ROBOTS, description='robot.yaml'))))
    with pytest.raises(ScenarioError) as e:
        load(str(path))
    line = str(e.value)
    assert '\n' not in line and 'robots.description' in line and str(tmp_path / 'robot.yaml') in line
    assert f'{name}={value!r}' in line and _range(DESCRIPTION_FIELDS[name].bound) in line


def test_a_step_longer_than_the_robots_can_follow_is_refused_and_braking_is_warned():
    """A tiny cruise speed ended in "every agent is lost" without naming the scale; --dt 1.0
    with robots that brake in every step passed without a word."""
    spec = RobotsSpec.model_validate(dict(length_scale=0.3, cruise_speed=0.15))
    assert spec.step_check(0.1) is None                        # 0.2 robot s, inside the 0.5 s timeout
    line = spec.step_check(1.0)                                # 2 robot s: the controller brakes each step
    assert '\n' not in line and 'dt = 1 model s lasts 2 robot s' in line and 'cmd_vel_timeout 0.5 s' in line
    slow = RobotsSpec.model_validate(dict(length_scale=0.3, cruise_speed=0.001))
    with pytest.raises(ValueError) as e:
        slow.step_check(0.1)                                   # 30 robot s per step
    assert 'L/v0 = 0.3 m / 0.001 m/s' in str(e.value) and f'at most {MAX_ROBOT_STEP:g} robot s' in str(e.value)


def _scenario_naming(tmp_path, description) -> str:
    path = tmp_path / 'scn.yaml'
    path.write_text(yaml.safe_dump(dict(BASE, robots=dict(ROBOTS, description=str(description)))))
    return str(path)


def _refused(path, said):
    t0 = time.monotonic()
    with pytest.raises(ScenarioError, match=said) as e:
        load(path)
    assert time.monotonic() - t0 < 10 and '\n' not in str(e.value) and 'robots.description' in str(e.value)


def test_a_description_alias_bomb_is_refused(tmp_path):
    lines = ['a0: &a0 [x, x, x, x, x, x, x, x, x]']
    lines += [f'a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']' for i in range(1, 12)]
    (tmp_path / 'bomb.yaml').write_text('\n'.join(lines) + '\n')
    _refused(_scenario_naming(tmp_path, 'bomb.yaml'), 'aliases')


def test_a_description_that_is_a_device_is_refused(tmp_path):
    _refused(_scenario_naming(tmp_path, '/dev/zero'), 'a device, not a regular file')


def test_a_description_that_is_a_fifo_is_refused_without_waiting(tmp_path):
    os.mkfifo(tmp_path / 'robot.yaml')
    _refused(_scenario_naming(tmp_path, 'robot.yaml'), 'a FIFO, not a regular file')


def test_a_description_that_is_a_directory_is_refused(tmp_path):
    (tmp_path / 'robot.yaml').mkdir()
    _refused(_scenario_naming(tmp_path, 'robot.yaml'), 'a directory, not a regular file')


def test_a_description_larger_than_a_scenario_file_may_be_is_refused(tmp_path):
    with open(tmp_path / 'robot.yaml', 'w') as fh:
        fh.write('mass: 1.0\n' + '#' * scenario.MAX_FILE_BYTES + '\n')
    _refused(_scenario_naming(tmp_path, 'robot.yaml'), re.escape(f'a robot description is at most '
                                                                  f'{scenario.MAX_FILE_BYTES} bytes'))


def test_a_description_nested_too_deep_is_refused(tmp_path):
    (tmp_path / 'robot.yaml').write_text('mass: ' + '[' * (scenario.MAX_YAML_DEPTH + 5) +
                                         ']' * (scenario.MAX_YAML_DEPTH + 5) + '\n')
    _refused(_scenario_naming(tmp_path, 'robot.yaml'), 'nested deeper')


def test_a_missing_description_is_one_line(tmp_path):
    _refused(_scenario_naming(tmp_path, 'nowhere.yaml'), 'no such robot description')


def test_a_relative_description_is_the_scenario_directorys(tmp_path, monkeypatch):
    """A relative path was read from the working directory of whichever process loaded it."""
    here = tmp_path / 'scenarios'
    here.mkdir()
    (here / 'robot.yaml').write_text('wheel_radius: 0.05\nmax_linear: 0.5\n')
    path = here / 'scn.yaml'
    path.write_text(yaml.safe_dump(dict(BASE, robots=dict(ROBOTS, description='robot.yaml'))))
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    robot = load(str(path)).spec.robots.robot()
    assert (robot['wheel_radius'], robot['max_linear'], robot['mass']) == (0.05, 0.5, 1.0)
    path.write_text(yaml.safe_dump(dict(BASE, robots=dict(ROBOTS, description=str(here / 'robot.yaml')))))
    assert load(str(path)).spec.robots.robot()['wheel_radius'] == 0.05        # an absolute one as it is
    assert load(str(path)).content_hash == load(str(path)).content_hash


def test_a_study_with_a_bad_robot_description_is_refused_before_any_run(tmp_path):
    """A robot description error in a study was a traceback from a worker, after the start."""
    (tmp_path / 'robot.yaml').write_text('max_linear_accel: 1.0e-300\n')
    path = _scenario_naming(tmp_path, 'robot.yaml')
    study = st.make_study(path, [('robot_set', ['none', 'all'])], seeds=2)
    with pytest.raises(st.StudyError) as e:
        st.validate(study)
    assert '\n' not in str(e.value) and 'robots.description' in str(e.value) and 'max_linear_accel' in str(e.value)
    # a study file's own robots.description is relative to the study file
    (tmp_path / 'studies').mkdir()
    (tmp_path / 'studies' / 'good.yaml').write_text('wheel_radius: 0.05\n')
    (tmp_path / 'studies' / 's.yaml').write_text(yaml.safe_dump(dict(
        scenario='../scn.yaml', seeds=1, grid={'robot_set': ['all']}, set={'robots.description': 'good.yaml'})))
    study = st.load_study(tmp_path / 'studies' / 's.yaml')
    st.validate(study)
    assert study.fixed['robots.description'] == str(tmp_path / 'studies' / 'good.yaml')


def test_a_study_says_once_that_its_robots_brake_in_every_step():
    said = []
    study = st.make_study('homotopy_global', [('robot_set', ['none', 'half', 'all'])], seeds=2, fixed={'dt': 1.0})
    st.validate(study, warn=said.append)
    assert len(said) == 1 and 'brake in every step' in said[0]
    study = st.make_study('homotopy_global', [('robot_set', ['all'])], seeds=2,
                          fixed={'robots.cruise_speed': 0.001})
    with pytest.raises(st.StudyError, match=re.escape(f'at most {MAX_ROBOT_STEP:g} robot s')):
        st.validate(study)
