"""The hash of a user's law file is recorded with the run (no ROS): the scenario keeps it as
it was loaded (`Scenario.law_hash`), metrics.json carries it in its summary, the batch engine's
replayed ``law`` commands carry it, and ``swarm simulate --replay`` says in one line when the
law file changed since the run it replays (it runs today's file)."""
from __future__ import annotations

import json

import pytest
import yaml

from swarm_core.command import plan
from swarm_core.laws.registry import law_code_hash
from swarm_core.scenario.loader import load
from swarm_tools.simulate import simulate_main

LAW = '''import numpy as np
from swarm_core.laws import Law, param

class Turn(Law):
    gain = param(0.1, lo=0.0, hi=10.0)

    def control(self, view):
        return np.full(view.receivers.size, {turn} * self.gain)
'''


def user_law_scenario(where, turn=0.02):
    (where / 'turn.py').write_text(LAW.format(turn=turn))
    path = where / 'turn.yaml'
    path.write_text(yaml.safe_dump({'name': 'turn', 'seed': 0, 'dt': 0.1, 'duration': 3.0, 'agents': {'count': 3},
                                    'law': {'kind': 'turn.py:Turn', 'gain': 0.5}}))
    return path


def test_a_user_laws_hash_is_kept_with_the_scenario_and_written_to_metrics(tmp_path):
    path = user_law_scenario(tmp_path)
    scn = load(str(path))
    assert scn.law_hash == law_code_hash({'kind': 'turn.py:Turn'}, tmp_path) != ''
    (tmp_path / 'turn.py').write_text(LAW.format(turn=0.5))     # edited after the load: the run's hash stays
    assert scn.law_hash != law_code_hash({'kind': 'turn.py:Turn'}, tmp_path)
    out = tmp_path / 'run'
    assert simulate_main([str(path), '--out', str(out), '--no-figure', '--quiet']) == 0
    summary = json.loads((out / 'metrics.json').read_text())['summary']
    assert summary['law_hash'] == law_code_hash({'kind': 'turn.py:Turn'}, tmp_path)
    shipped = tmp_path / 'shipped'
    assert simulate_main(['homotopy_global', '--duration', '1', '--out', str(shipped), '--no-figure', '--quiet']) == 0
    assert load('homotopy_global').law_hash == ''
    assert 'law_hash' not in json.loads((shipped / 'metrics.json').read_text())['summary']


def test_the_recorded_hashes_are_read_back_from_events():
    lines = [json.dumps(dict(t=0.0, kind='law', law='/x/turn.py:Turn', law_hash='aaaa')),
             json.dumps(dict(t=1.0, kind='command', command='law', agent='a', parameters={'gain': 1.0}, step=10,
                             law_hash='aaaa')),
             '', 'not json', json.dumps(dict(t=2.0, kind='command', command='law', agent='a',
                                             parameters={'gain': 2.0}, step=20, law_hash='bbbb')),
             json.dumps(dict(t=3.0, kind='kill', agent='a'))]
    assert plan.recorded_law_hashes(lines) == ['aaaa', 'bbbb']
    assert plan.recorded_law_hashes([json.dumps(dict(t=0.0, kind='lost', agent='a'))]) == []


@pytest.mark.parametrize('edited', [False, True], ids=['same file', 'edited file'])
def test_replay_says_when_the_law_file_changed_since_the_run(tmp_path, capsys, edited):
    path = user_law_scenario(tmp_path)
    ran = load(str(path)).law_hash
    events = tmp_path / 'events.jsonl'
    events.write_text('\n'.join(json.dumps(e) for e in [
        dict(t=0.0, kind='law', law=f'{tmp_path / "turn.py"}:Turn', law_hash=ran),
        dict(t=1.0, kind='command', command='law', agent='agent_1', parameters={'gain': 1.0}, step=10,
             law_hash=ran, node='agent')]) + '\n')
    if edited:
        (tmp_path / 'turn.py').write_text(LAW.format(turn=0.03))
    out = tmp_path / 'replayed'
    assert simulate_main([str(path), '--replay', str(events), '--out', str(out), '--no-figure', '--quiet']) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if 'law file changed' in ln]
    if edited:
        now = load(str(path)).law_hash
        assert said == [f'swarm simulate: --replay {events}: the law file changed since the run (the run\'s hash '
                        f'{ran}, now {now}): the replay runs today\'s file'], said
    else:
        assert said == []
    events_out = json.loads((out / 'metrics.json').read_text())['summary']['events']
    law = [e for e in events_out if e.get('command') == 'law']
    assert [e['law_hash'] for e in law] == [load(str(path)).law_hash]      # the replay's law command: its file
