"""`swarm run --robots mujoco`: the plan (pure): the robot world's node, its parameters and its
process, and what metrics.json gets from it (the agents' side of --robots: test_robot_units)."""
import json

import pytest

from swarm_core.scenario.loader import load
from swarm_robots.world_setup import SUMMARY_FILE
from swarm_tools.run import launch
from swarm_tools.run.robots import read_summary


@pytest.fixture
def six(tmp_path):
    path = tmp_path / 'six.yaml'
    path.write_text('name: six\nagents: {count: 6}\nduration: 5\nrobots: {length_scale: 0.3, cruise_speed: 0.15}\n')
    return load(str(path)), str(path)


def plan(scn_ref, *args):
    scn, ref = scn_ref
    a = launch._parser().parse_args([ref, *args])
    return launch.plan(a, scn, ref, run_id='r1')


def test_plan_starts_the_robot_world_for_the_mujoco_agents(six):
    run = plan(six, '--robots', 'mujoco:agent_1-agent_3', '--mode', 'realtime')
    robot = {fqn.split('/')[1]: p.get('robot') for fqn, p in run.params.items() if fqn.endswith('/agent')}
    assert robot == {'agent_0': None, 'agent_1': 'mujoco', 'agent_2': 'mujoco', 'agent_3': 'mujoco',
                     'agent_4': None, 'agent_5': None}
    node = run.params['/robots']
    assert node['robots'] == 'agent_1,agent_2,agent_3' and node['mode'] == 'realtime' and node['run_id'] == 'r1'
    assert node['output_dir'] == str(run.out) and node['use_sim_time'] is True
    assert node['hold_timeout'] == run.params['/world']['missing_timeout'] / 2
    assert node['scenario'] == six[1] and node['dt'] == six[0].dt
    # 3 kinematic agents, 3 robot agents (each a process of its own), world, commander, robots
    assert run.processes == 6 + 3
    assert 'robots' not in run.params['/world'] and run.params['/world']['rtf'] == 1.0
    assert 'robot_poses' not in run.params['/world']       # realtime: the agents read their odometry
    lock = plan(six, '--robots', 'mujoco:agent_1-agent_3', '--robots', 'external:agent_5')
    assert lock.params['/world']['robot_poses'] == 'agent_1,agent_2,agent_3'   # lockstep: the robot world reports
    for other in ([], ['--robots', 'external']):          # no MuJoCo robots: no robot world
        assert '/robots' not in plan(six, *other).params and plan(six, *other).processes == 8


def test_the_robot_summary_goes_into_the_run_outputs(tmp_path):
    assert read_summary(tmp_path) is None
    (tmp_path / SUMMARY_FILE).write_text(json.dumps({'contacts': 2}))
    assert read_summary(tmp_path) == {'contacts': 2}
