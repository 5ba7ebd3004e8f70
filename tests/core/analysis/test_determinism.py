"""metrics.json says when a lockstep ROS run is no longer the run its scenario and seed make
(`analysis.outputs.not_deterministic`): an agent lost to the wall clock, a robot's missed command."""
from swarm_core.analysis.outputs import not_deterministic

LOST = {'t': 5.2, 'kind': 'lost', 'agent': 'agent_0'}


def test_a_lost_agent_or_a_missed_robot_command_makes_a_lockstep_run_not_deterministic():
    meta = dict(source='ros', mode='lockstep', events=[{'t': 1.0, 'kind': 'kill', 'agent': 'agent_4'}, LOST],
                robots={'commands_missed': {'agent_1': [3, 4]}})
    assert not_deterministic(meta) == ['agent_0 lost at t = 5.2',
                                       "agent_1's robot went on without its command at 2 step(s) from step 3"]


def test_a_clean_run_a_scenario_fault_a_batch_or_a_realtime_run_say_nothing():
    kill = {'t': 1.0, 'kind': 'kill', 'agent': 'agent_4'}
    assert not_deterministic(dict(source='ros', mode='lockstep', events=[kill], robots={'commands_missed': {}})) == []
    assert not_deterministic(dict(source='ros', mode='realtime', events=[LOST])) == []
    assert not_deterministic(dict(events=[LOST])) == []
