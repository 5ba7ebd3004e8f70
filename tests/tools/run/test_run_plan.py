"""`swarm run` and `swarm join` plan what they start before anything runs (`launch.plan`,
`join.plan`): pure, no ROS, nothing written; bad options are named before any process starts."""
import sys

import pytest

from swarm_core.scenario.loader import load
from swarm_tools.run import join, launch


@pytest.fixture
def scenario_of(tmp_path):
    """A scenario of n agents (loaded, and the reference the nodes get)."""
    def make(n):
        path = tmp_path / f'swarm{n}.yaml'
        path.write_text(f'name: swarm{n}\nagents: {{count: {n}}}\nduration: 5\n')
        return load(str(path)), str(path)
    return make


def run_plan(scn_ref, *args, cores=1, run_id='r1'):
    scn, ref = scn_ref
    a = launch._parser().parse_args([ref, *args])
    launch.check_options(a)
    return launch.plan(a, scn, ref, cores=cores, run_id=run_id)


def agents(run):
    return {fqn: p for fqn, p in run.params.items() if fqn.endswith('/agent')}


def test_containers_for_agents_per_process(scenario_of):
    run = run_plan(scenario_of(10), '--agents-per-process', '4')
    assert run.groups == [[f'agent_{i}' for i in range(4)], [f'agent_{i}' for i in range(4, 8)],
                          ['agent_8', 'agent_9']]
    assert run.per == 4 and run.processes == 3 + 2 and run.services
    assert run.params['/world']['step_readers'] == 3     # one step relay reader per agent process
    assert '(4 agents per process)' in run.summary() and '5 processes' in run.summary()
    one = run_plan(scenario_of(10))
    assert one.groups == [[f'agent_{i}'] for i in range(10)] and one.processes == 12
    assert 'step_readers' not in one.params['/world'] and 'per process' not in one.summary()
    # auto: one process per agent for a small swarm, one container per core for a large one
    assert run_plan(scenario_of(10), '--agents-per-process', 'auto', cores=4).per == 1
    big = run_plan(scenario_of(200), '--agents-per-process', 'auto', cores=4)
    assert big.per == 50 and len(big.groups) == 4 and not big.services
    assert 'agent nodes without services' in big.summary()


def test_the_agents_sum_pairs_as_the_run_chooses(scenario_of):
    """``--compiled``: every agent gets the run's `compiled_sums.run_sums` as its read-only
    ``pair_sums`` (auto: numpy for this short run of ten; on, off), and `swarm join` the same."""
    for args, want in (((), 'numpy'), (('--compiled', 'on'), 'compiled'), (('--compiled', 'off'), 'numpy')):
        assert {p['pair_sums'] for p in agents(run_plan(scenario_of(10), *args)).values()} == {want}
    scn, ref = scenario_of(10)
    a = join._parser().parse_args([ref, '--agents', '1', '--server', '127.0.0.1:11811', '--compiled', 'on'])
    assert join.plan(a, scn, ref).params['/agent_1/agent']['pair_sums'] == 'compiled'


def test_in_process_plans_one_process_and_ignores_process_options(scenario_of):
    run = run_plan(scenario_of(6), '--in-process', '--record', 'x.mcap', '--foxglove', '--agents-per-process', '3')
    assert run.in_process and run.record is None and run.foxglove is None and not run.use_server
    assert 'one process' in run.summary() and 'per process' not in run.summary()
    assert [ln.split()[0] for ln in run.ignored] == ['--record', '--foxglove']
    assert 'events_file' not in run.params['/world'] and 'step_readers' not in run.params['/world']
    assert run_plan(scenario_of(6), '--in-process').ignored == []


def test_record_makes_every_node_wait_for_the_recorder(scenario_of):
    run = run_plan(scenario_of(6), '--record', 'x.mcap', '--state-readers', '2')
    assert run.record == 'x.mcap' and run.processes == 6 + 2 + 1
    assert {p['state_subscribers'] for p in agents(run).values()} == {3}      # 2 outside + our recorder
    assert run.params['/world']['wait_for_recorder'] and run.params['/commander']['wait_for_recorder']
    plain = run_plan(scenario_of(6))
    assert plain.record is None and plain.processes == 8
    assert all('state_subscribers' not in p for p in agents(plain).values())
    assert 'wait_for_recorder' not in plain.params['/world'] | plain.params['/commander']
    realtime = run_plan(scenario_of(6), '--record', 'x.mcap', '--mode', 'realtime')   # lockstep only
    assert all('state_subscribers' not in p for p in agents(realtime).values())
    assert 'wait_for_recorder' not in realtime.params['/world']


def test_every_node_gets_the_run_id_and_outputs(scenario_of, tmp_path):
    run = run_plan(scenario_of(3), '--out', str(tmp_path / 'o'), '--foxglove', '0', run_id='abc123')
    assert {p['run_id'] for p in run.params.values()} == {'abc123'} and len(run.params) == 5
    assert run.out == (tmp_path / 'o').resolve() and run.traj_file == run.out / 'trajectory.npz'
    assert run.params['/world']['events_file'] == str(run.out / 'events.jsonl')
    assert run.foxglove == 0 and run.processes == 3 + 2 + 1
    assert not (tmp_path / 'o').exists()          # planning writes nothing
    assert run.summary().startswith('swarm run: run abc123: swarm3 seed ')


def test_remote_agents_and_the_discovery_server(scenario_of):
    run = run_plan(scenario_of(8), '--remote-agents', '2,5-7', '--agents-per-process', '2', '--seed', '3',
                   '--record', 'b.mcap')
    assert run.remote == [2, 5, 6, 7] and run.local == ['agent_0', 'agent_1', 'agent_3', 'agent_4']
    assert run.groups == [['agent_0', 'agent_1'], ['agent_3', 'agent_4']] and run.use_server
    assert run.params['/world']['step_readers'] == 2 + 4     # the remote agents each read the relay
    head, tail = run.join
    assert head.endswith('--agents 2,5-7') and tail == ' --interface ADDR --seed 3 --recorded'
    assert not run_plan(scenario_of(8)).use_server
    assert run_plan(scenario_of(8), '--discovery', 'server').use_server


@pytest.mark.parametrize('args, word', [
    (('--agents-per-process', '0'), '--agents-per-process 0: must be a whole number ≥ 1 or auto'),
    (('--agents-per-process', 'many'), '--agents-per-process many'),
    (('--remote-agents', '1', '--in-process'), '--remote-agents needs --processes'),
    (('--remote-agents', '1', '--discovery', 'simple'), '--remote-agents needs a discovery server'),
    (('--remote-agents', '9'), "'9' is outside 0..5"),
    (('--server-port', '70000'), '--server-port 70000'),
])
def test_plan_names_the_bad_option(scenario_of, args, word):
    with pytest.raises(ValueError, match=word):
        run_plan(scenario_of(6), *args)


@pytest.mark.parametrize('args, word', [
    (('--missing-timeout', '0'), '--missing-timeout 0.0: must be in'), (('--start-timeout', 'nan'), '--start-timeout'),
    (('--clock-every', '0'), '--clock-every 0'), (('--foxglove', '70000'), '--foxglove 70000'),
    (('--state-readers', '-1'), '--state-readers -1'), (('--rtf', '0'), '--rtf 0.0'),
])
def test_options_out_of_range_are_named(scenario_of, args, word):
    with pytest.raises(ValueError, match=word):
        run_plan(scenario_of(3), *args)


def test_too_many_agents_for_one_run(scenario_of):
    with pytest.raises(ValueError, match=f'{launch.MAX_RUN_AGENTS + 1} agents: at most {launch.MAX_RUN_AGENTS}'):
        run_plan(scenario_of(launch.MAX_RUN_AGENTS + 1))


def test_prepare_outputs_refuses_a_bad_bag_and_clears_old_outputs(scenario_of, tmp_path):
    run = run_plan(scenario_of(3), '--out', str(tmp_path / 'o'), '--record', str(tmp_path / 'x.bag'))
    with pytest.raises(ValueError, match='must name a .mcap file'):
        launch.prepare_outputs(run)
    run = run_plan(scenario_of(3), '--out', str(tmp_path / 'o'), '--record', str(tmp_path / 'bags' / 'x.mcap'))
    run.traj_file.write_text('old')
    launch.prepare_outputs(run)
    assert (tmp_path / 'bags').is_dir() and not run.traj_file.exists()


def test_join_plans_the_agents_it_starts(scenario_of):
    scn, ref = scenario_of(6)
    a = join._parser().parse_args([ref, '--agents', '1,4-5', '--server', '127.0.0.1:11811', '--recorded'])
    plan = join.plan(a, scn, ref)
    assert plan.names == ['agent_1', 'agent_4', 'agent_5'] and plan.server == '127.0.0.1:11811'
    assert list(plan.params) == ['/agent_1/agent', '/agent_4/agent', '/agent_5/agent']
    assert {p['state_subscribers'] for p in plan.params.values()} == {1}
    # the same parameters as the run's own agents (one planning for both)
    run = run_plan((scn, ref), '--record', 'x.mcap')
    assert all(dict(p, run_id='r1') == run.params[fqn] for fqn, p in plan.params.items())
    a = join._parser().parse_args([ref, '--agents', '1', '--server', '127.0.0.1:11811', '--wait', '0'])
    with pytest.raises(ValueError, match='--wait 0.0: must be > 0'):
        join.plan(a, scn, ref)


def test_join_starts_the_robot_agents_the_run_announces(tmp_path):
    """``swarm run --remote-agents 3-5 --robots mujoco:agent_4``: the world announces agent_4's
    robot; ``swarm join`` starts it as a robot agent with the run's own parameters for it (the
    robot world, on the run's host, drives its robot), the others kinematic."""
    from swarm_ros.runinfo import parse_robots_text, parse_run, run_json
    path = tmp_path / 'robots6.yaml'
    path.write_text('name: robots6\nagents: {count: 6}\nduration: 5\n'
                    'robots: {length_scale: 0.3, cruise_speed: 0.15}\n')
    scn, ref = load(str(path)), str(path)
    run = run_plan((scn, ref), '--remote-agents', '3-5', '--robots', 'mujoco:agent_1,agent_4')
    world = run.params['/world']
    assert world['remote_robots'] == 'agent_4=mujoco'
    assert run.params['/robots']['robots'] == 'agent_1,agent_4'       # the robot world is the run's
    robots = parse_robots_text(world['remote_robots'], world['remote_agents'].split(','), ('external', 'mujoco'))
    said = parse_run(run_json('r1', scn.name, 'lockstep', scn.names, 1.0, scn.content_hash,
                              world['remote_agents'].split(','), robots))
    a = join._parser().parse_args([ref, '--agents', '3-5', '--server', '127.0.0.1:11811'])
    plan = join.plan(a, scn, ref)
    assert 'robot' not in plan.params['/agent_4/agent']          # known only once the run is heard
    assert '1 of 6 agents on robots (mujoco)' in plan.for_run(said)
    assert all(p == run.params[fqn] for fqn, p in plan.params.items())
    assert plan.params['/agent_4/agent']['robot'] == 'mujoco' and 'robot' not in plan.params['/agent_3/agent']
    with pytest.raises(ValueError, match='NAME a remote agent'):
        parse_robots_text('agent_1=mujoco', ['agent_4'], ('external', 'mujoco'))


def test_plan_module_has_no_ros_import():
    import subprocess
    code = ('import sys; from swarm_core.scenario.loader import load; from swarm_tools.run import launch; '
            "a = launch._parser().parse_args(['global_alignment', '--agents-per-process', '2']); "
            "launch.plan(a, load('global_alignment'), 'global_alignment'); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rosidl_runtime_py')))")
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == '[]', r.stderr


def test_robots_external_sets_the_robot_agents_and_shares_containers(tmp_path):
    path = tmp_path / 'robots.yaml'
    path.write_text('name: robots\nagents: {count: 6}\nduration: 5\n'
                    'robots: {length_scale: 0.3, cruise_speed: 0.15}\n')
    scn_ref = load(str(path)), str(path)
    run = run_plan(scn_ref, '--agents-per-process', '3', '--robots', 'external:agent_1-agent_2')
    assert run.robots == {'agent_1': 'external', 'agent_2': 'external'}
    assert run.groups == [['agent_0', 'agent_1', 'agent_2'], ['agent_3', 'agent_4', 'agent_5']]
    params = agents(run)
    assert params['/agent_1/agent']['robot'] == 'external' and params['/agent_1/agent']['robot_clock'] == 'sim'
    assert 'robot' not in params['/agent_0/agent']
    assert run.params['/world']['step_readers'] == 2
    assert 'r0 = 0.45 m, w = 1.2 m' in run.robots_line
    rt = run_plan(scn_ref, '--mode', 'realtime', '--robots', 'external')
    assert rt.params['/world']['rtf'] == pytest.approx(0.5) and agents(rt)['/agent_0/agent']['robot_clock'] == 'wall'
    for bad, why in ((['--robots', 'external:agent_7'], "'agent_7' is not an agent"),
                     (['--robots', 'mars'], 'mars')):
        with pytest.raises(ValueError, match=why):
            run_plan(scn_ref, *bad)
    assert run_plan(scn_ref).robots == {} and run_plan(scn_ref).robots_line is None
