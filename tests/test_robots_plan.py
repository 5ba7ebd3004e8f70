"""`swarm run --robots`: the plan (pure): which agents drive robots, the robot world's node and
its parameters, and what metrics.json gets from it."""
import json

import pytest

from swarm_core.scenario import load
from swarm_robots.run_setup import SUMMARY_FILE
from swarm_tools import launch, robots_option
from swarm_tools.robots_option import parse_robots, read_summary

NAMES = [f'agent_{i}' for i in range(6)]


def test_parse_robots_kinds_names_and_ranges():
    assert parse_robots('mujoco', NAMES) == ('mujoco', NAMES)
    assert parse_robots('mujoco:agent_0-agent_2', NAMES) == ('mujoco', NAMES[:3])
    assert parse_robots('mujoco:agent_5,agent_1-agent_2', NAMES) == ('mujoco', ['agent_1', 'agent_2', 'agent_5'])
    for bad, why in (('gazebo', 'kind must be one of'), ('mujoco:agent_9', "'agent_9' is neither"),
                     ('mujoco:agent_3-agent_1', "'agent_3-agent_1' is neither"), ('mujoco:', "'' is neither")):
        with pytest.raises(ValueError, match=why):
            parse_robots(bad, NAMES)


@pytest.fixture
def six(tmp_path, monkeypatch):
    """Six agents; the scenario's robots section stood in (its schema is swarm_core's)."""
    path = tmp_path / 'six.yaml'
    path.write_text('name: six\nagents: {count: 6}\nduration: 5\n')
    monkeypatch.setattr(robots_option, 'robots_section', lambda scn: object())
    return load(str(path)), str(path)


def plan(scn_ref, *args):
    scn, ref = scn_ref
    a = launch._parser().parse_args([ref, *args])
    return launch.plan(a, scn, ref, run_id='r1')


def test_plan_puts_the_chosen_agents_on_mujoco_robots(six):
    run = plan(six, '--robots', 'mujoco:agent_1-agent_3', '--mode', 'realtime')
    assert run.robots == ('mujoco', ['agent_1', 'agent_2', 'agent_3'])
    robot = {fqn.split('/')[1]: p.get('robot') for fqn, p in run.params.items() if fqn.endswith('/agent')}
    assert robot == {'agent_0': None, 'agent_1': 'mujoco', 'agent_2': 'mujoco', 'agent_3': 'mujoco',
                     'agent_4': None, 'agent_5': None}
    node = run.params['/robots']
    assert node['robots'] == 'agent_1,agent_2,agent_3' and node['mode'] == 'realtime' and node['run_id'] == 'r1'
    assert node['output_dir'] == str(run.out) and node['use_sim_time'] is True
    assert node['scenario'] == six[1] and node['dt'] == six[0].dt
    assert run.processes == 6 + 3 and '3 on mujoco robots' in run.summary()
    plain = plan(six)
    assert plain.robots == ('', []) and '/robots' not in plain.params and plain.processes == 8
    assert 'robots' not in plain.summary()


def test_a_scenario_without_a_robots_section_is_refused(tmp_path):
    path = tmp_path / 'plain.yaml'
    path.write_text('name: plain\nagents: {count: 3}\nduration: 5\n')
    with pytest.raises(ValueError, match='--robots mujoco: .*no robots section'):
        plan((load(str(path)), str(path)), '--robots', 'mujoco')


def test_the_robot_summary_goes_into_the_run_outputs(tmp_path):
    assert read_summary(tmp_path) is None
    (tmp_path / SUMMARY_FILE).write_text(json.dumps({'contacts': 2}))
    assert read_summary(tmp_path) == {'contacts': 2}
