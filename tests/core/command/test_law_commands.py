"""An agent's live law change as a command (`swarm_core.command.plan`): its event in a run's
events.jsonl read back (`read_commands`), checked (`check_command`), applied to a law
(`law_with`: only the law's own parameters but its kind, in their ranges) and laid out per
agent and step (`law_timeline`), as `swarm simulate --replay` does."""
import json

import pytest

from swarm_core.command.plan import check_command, law_timeline, law_with, read_commands
from swarm_core.laws import Blend, flat_parameters, make_law
from tests.core.laws import paper_law

NAMES = ['a', 'b', 'c']


def test_law_events_are_read_back_as_commands_of_agent_indices():
    lines = [json.dumps(dict(t=1.0, kind='command', command='law', agent='b', parameters={'alpha': 0.5}, step=20,
                             node='agent')),
             json.dumps(dict(t=1.0, kind='command', command='lambda', value=1.0, ramp=0.0, step=20)),
             json.dumps(dict(t=0.5, kind='leaders_chosen', leaders=['a']))]
    cmds = read_commands(lines, NAMES)
    assert cmds == {20: [dict(command='law', agent=1, parameters={'alpha': 0.5}),
                         dict(command='lambda', value=1.0, ramp=0.0, shape='smoothstep')]}
    bad = json.dumps(dict(kind='command', command='law', agent='zz', parameters={'alpha': 0.5}, step=3))
    with pytest.raises(ValueError, match='line 1: law command for unknown agent'):
        read_commands([bad], NAMES)


@pytest.mark.parametrize('cmd', [dict(command='law', agent=1), dict(command='law', agent=1, parameters={}),
                                 dict(command='law', agent=1, parameters={'alpha': [1]}),
                                 dict(command='law', agent=5, parameters={'alpha': 0.5}),
                                 dict(command='law', agent=True, parameters={'alpha': 0.5})])
def test_malformed_law_commands_are_named(cmd):
    with pytest.raises(ValueError, match='law'):
        check_command(cmd, 3)


def test_law_with_changes_only_the_laws_own_parameters_in_their_ranges():
    law = paper_law(kind='homotopy')
    new = law_with(law, {'alpha': 0.5, 'mu': 1, 'barrier_mode': 'literal', 'target_normalised': True})
    assert (new.alpha, new.mu, new.barrier_mode, new.target_normalised) == (0.5, 1.0, 'literal', True)
    assert type(new.mu) is float and new.kind == 'homotopy' and law.alpha == paper_law().alpha
    for change, why in [({'law': 'global'}, 'may change'), ({'speed': 1.0}, 'may change'),
                        ({'alpha': -1.0}, 'outside'), ({'q0': 2.0}, 'outside'), ({'alpha': float('nan')}, 'finite'),
                        ({'alpha': True}, 'finite'), ({'barrier_mode': 'sideways'}, 'one of'),
                        ({'target_normalised': 1}, 'bool')]:
        with pytest.raises(ValueError, match=why):
            law_with(law, change)


def test_law_with_reaches_a_blends_two_laws_and_a_shipped_law():
    blend = make_law({'kind': 'blend', 'from': {'kind': 'global'}, 'to': {'kind': 'spl_circular'}})
    assert isinstance(blend, Blend)
    flat = flat_parameters(blend)
    name = next(k for k in flat if k.startswith('to.') and not k.endswith('law') and isinstance(flat[k], float))
    new = law_with(blend, {'from.alpha': 0.3, name: flat[name] / 2})
    assert flat_parameters(new)['from.alpha'] == 0.3 and flat_parameters(new)[name] == flat[name] / 2
    with pytest.raises(ValueError, match='may change'):
        law_with(blend, {'to.law': 'global'})


def test_law_timeline_applies_each_agents_changes_in_step_order():
    law = paper_law(kind='global')
    cmds = {30: [dict(command='law', agent=2, parameters={'eta': 0.1})],
            10: [dict(command='law', agent=2, parameters={'alpha': 0.2}),
                 dict(command='lambda', value=1.0, ramp=0.0, shape='step')]}
    tl = law_timeline(cmds, law, 3)
    assert sorted(tl) == [10, 30]
    (k, l10, p10), = tl[10]
    (k2, l30, p30), = tl[30]
    assert (k, k2, p10, p30) == (2, 2, {'alpha': 0.2}, {'eta': 0.1})
    assert (l30.alpha, l30.eta) == (0.2, 0.1)          # the second change keeps the first
    with pytest.raises(ValueError, match='law command at step 30'):
        law_timeline({30: [dict(command='law', agent=0, parameters={'alpha': -1.0})]}, law, 3)


LAW_FILE = '''import numpy as np
from swarm_core.laws import Law, param

class Turn(Law):
    gain = param(0.1, lo=0.0, hi=10.0)

    def control(self, view):
        return np.full(view.receivers.size, {turn} * self.gain)
'''


def _u(law):
    return float(law.evaluate([[0.0, 0.0]], [1.0], [0.0], [0])[0])


@pytest.mark.parametrize('blend', [False, True], ids=['alone', 'in a blend'])
def test_law_with_keeps_the_law_file_the_run_imported(tmp_path, blend):
    """A run imports a law file once: a live set rebuilds the law from its own class, so an
    edited file is not imported again (its new code would run from the set on)."""
    path = tmp_path / 'turn.py'
    path.write_text(LAW_FILE.format(turn=1.0))
    user = {'kind': f'{path}:Turn', 'gain': 0.5}
    law = make_law({'kind': 'blend', 'from': user, 'to': {'kind': 'global'}} if blend else user)
    path.write_text(LAW_FILE.format(turn=100.0))             # edited during the run (size and mtime change)
    new = law_with(law, {'from.gain' if blend else 'gain': 0.25})
    inner = new.from_law if blend else new
    was = law.from_law if blend else law
    assert type(inner) is type(was)
    assert _u(inner) == 0.25 and _u(was) == 0.5
    assert make_law(user).evaluate([[0.0, 0.0]], [1.0], [0.0], [0])[0] == 50.0    # a new load reads the edit
