"""A 3D scenario's faults, failover, reunion, comms and noise sections: what the loader takes
and the one line naming the key of what it refuses."""
import pytest

from swarm_core.scenario import ScenarioError, parse
from swarm_core.scenario.loader import NOT_YET_3D

SIX = [[-1, 1, 0], [0, 1, 0], [1, 1, 0], [-1, 0, 0], [0, 0, 0], [1, 0, 0]]


def _scenario(**over):
    data = dict(name='s3', dim=3, dt=0.1, duration=20, agents=dict(positions=SIX, headings={'rule': 'cap'}))
    data.update(over)
    return data


def test_a_3d_scenario_takes_faults_failover_reunion_comms_and_noise():
    scn = parse(_scenario(faults=[{'at': 3, 'kill': 'leader:0'}, {'at': 1, 'freeze': 'agent_2', 'for': 2}],
                          failover={'timeout': 1.0}, reunion=[{'at': 5, 'for': 5, 'point': [1, 2, 3]}],
                          comms={'loss': 0.2, 'radio_range': 8, 'partition': [['agent_0', 'agent_1']]},
                          noise={'position': 0.01, 'heading': 0.01}), 's3.yaml')
    assert scn.spec.reunion[0].point == (1, 2, 3) and scn.comm_model() is not None
    assert NOT_YET_3D == ('robots',)


@pytest.mark.parametrize('over,text', [
    (dict(faults=[{'at': 1, 'kill': 'agent_9'}]), "s3.yaml: faults.0.kill: unknown agent 'agent_9'"),
    (dict(faults=[{'at': 1, 'kill': 'agent_0', 'freeze': 'agent_1'}]), 's3.yaml: faults.0: Value error, give '
                                                                         'exactly one of kill'),
    (dict(faults=[{'at': 1, 'freeze': 'agent_0'}]), 's3.yaml: faults.0: Value error, freeze needs for'),
    (dict(faults=[{'at': -1, 'kill': 'agent_0'}]), 's3.yaml: faults.0.at'),
    (dict(failover={'timeout': -1}), 's3.yaml: failover.timeout'),
    (dict(reunion=[{'at': 1, 'for': 2, 'point': [1, 2]}]),
     's3.yaml: reunion.0.point: the rendezvous point of a 3D scenario (dim: 3) has 3 coordinates'),
    (dict(reunion=[{'at': 1, 'for': 2}], target={'position': [1, 2, 3]}), 'reunion: a scenario with a target cannot'),
    (dict(comms={'loss': 2}), 's3.yaml: comms.loss'),
    (dict(comms={'partition': [['agent_0', 'ghost']]}), "s3.yaml: comms: partition: unknown agent 'ghost'"),
    (dict(comms={'links': [{'sender': 'ghost', 'loss': 0.5}]}), "s3.yaml: comms: links.0.sender: unknown agent"),
    (dict(comms={'loss': 0.1}, integrator='rk4'), 's3.yaml: comms: a communication model needs integrator zoh'),
    (dict(noise={'heading': -0.1}), 's3.yaml: noise.heading'),
    (dict(robots={'scale': 1.0}), 's3.yaml: robots: not in 3D scenarios yet'),
])
def test_a_bad_3d_fault_comms_or_noise_input_is_one_line_naming_the_key(over, text):
    with pytest.raises(ScenarioError) as err:
        parse(_scenario(**over), 's3.yaml')
    assert text in str(err.value) and '\n' not in str(err.value), str(err.value)


def test_a_3d_rendezvous_point_in_a_planar_scenario_is_refused():
    with pytest.raises(ScenarioError) as err:
        parse(dict(name='s2', agents=dict(count=4), reunion=[{'at': 1, 'for': 2, 'point': [1, 2, 3]}]), 's2.yaml')
    assert 's2.yaml: reunion.0.point' in str(err.value) and '\n' not in str(err.value)
