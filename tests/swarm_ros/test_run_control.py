"""Control paths belong to the run (`swarm_ros.run_control`, pure): events act only with the
run's id, a robot's commands only with the run's id and their first sender tag, and
/lockstep/robot_states is bound to its first sender."""
import json

import numpy as np
import pytest

from swarm_ros.layouts import RobotStates
from swarm_ros.run_control import (
    CommandSenders,
    EventRefused,
    FirstSender,
    command_frame,
    command_sender,
    event_text,
    run_event,
)

KILL = {'t': 1.0, 'kind': 'kill', 'agent': 'agent_0', 'node': 'world'}


def test_an_event_acts_only_with_the_run_id():
    assert run_event(event_text(KILL, 'ab12'), 'ab12') == KILL        # read back without its run id
    for text in (json.dumps(KILL), event_text(KILL, 'other'), event_text(KILL, ''),
                 json.dumps(dict(KILL, run_id=['ab12']))):
        with pytest.raises(EventRefused, match="not this run 'ab12'") as err:
            run_event(text, 'ab12')
        assert err.value.kind == 'other-run'
    assert run_event(json.dumps(KILL), '') == KILL                      # a node without a run id takes any
    assert run_event(event_text(KILL, 'other'), '') == KILL


@pytest.mark.parametrize('text', ['not json', '[1, 2]', '"kill"', '{"t": NaN}', '[' * 10000, 'x' * 70000])
def test_an_event_that_is_not_a_json_object_is_refused_in_one_line(text):
    with pytest.raises(EventRefused) as err:
        run_event(text, 'ab12')
    assert err.value.kind == 'event-json' and len(str(err.value)) < 300


def test_a_robots_commands_come_from_its_run_and_its_first_sender():
    assert command_frame('agent_1', 'ab12', 77.0) == 'agent_1/base_link run=ab12 tag=77'
    assert command_sender(command_frame('agent_1', 'ab12', 77.0)) == ('ab12', 77)
    for frame in ('', 'agent_1/base_link', 'a run=', 'a tag=x run', 'a tag=-5', 'a tag=' + '9' * 40):
        assert command_sender(frame)[1] == 0, frame
    senders = CommandSenders('ab12', ['/agent_0/cmd_vel', '/agent_1/cmd_vel'])
    for frame in ('agent_1/base_link', command_frame('agent_1', 'zz', 77)):      # a peer's, another run's
        assert senders.check(1, frame).kind == 'other-run'
    assert senders.check(1, command_frame('agent_1', 'ab12', 77)) is None          # binds robot 1 to 77
    assert senders.check(1, command_frame('agent_1', 'ab12', 77)) is None
    assert senders.check(1, command_frame('agent_1', 'ab12', 78)).kind == 'second-publisher'
    assert senders.check(0, command_frame('agent_0', 'ab12', 78)) is None          # each robot its own
    loose = CommandSenders('', ['/agent_0/cmd_vel'])          # a robot world without a run id
    assert loose.check(0, 'agent_0/base_link') is None and loose.check(0, 'x run=a tag=5').kind == 'second-publisher'


def test_robot_states_carry_the_robot_worlds_tag_and_bind_to_the_first():
    pose = np.array([[1.0], [2.0], [0.0], [1.0]])
    m = RobotStates.from_cdr(RobotStates(3, 41.0, [2], pose).to_cdr('ab12'), 'ab12')
    assert (m.n, m.tag, m.index.tolist(), m.pose.tolist()) == (3, 41.0, [2], pose.tolist())
    first = FirstSender('/lockstep/robot_states')
    assert first.check(41.0) is None and first.check(41.0) is None
    why = first.check(42.0)
    assert why.kind == 'second-publisher' and 'bound to 41' in why
