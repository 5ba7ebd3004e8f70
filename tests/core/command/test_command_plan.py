"""Live commands in the pure plan (no ROS): validation, the leader rule on a rising λ, replay."""
import json

import numpy as np
import pytest

from swarm_core.command.plan import CHOOSE_RISE, check_command, read_commands
from swarm_core.engine.reference import simulate
from swarm_core.scenario.loader import load


def test_check_command_names_the_bad_field():
    assert check_command(dict(command='lambda', value=1, ramp=0), 3)['shape'] == 'smoothstep'
    for bad, word in [(dict(command='lambda', value=1.5), 'λ'), (dict(command='lambda', value=float('nan')), 'finite'),
                      (dict(command='lambda', value=0.5, ramp=-1), 'ramp'),
                      (dict(command='steer', agent=3, value=0.1), 'agent'), (dict(command='fly', value=1), 'command')]:
        with pytest.raises(ValueError, match=word):
            check_command(bad, 3)


def test_raising_lambda_fires_the_leader_rule_and_replay_is_exact():
    """homotopy_global with the clock rule out of reach: a λ set-point at step 50 (ramp 20 s)
    chooses the leaders once λ has risen by CHOOSE_RISE; the same commands give the same run."""
    scn = load('homotopy_global', duration=60.0)
    scn.spec.leaders.at = 1e6
    scn.spec.lambda_.rise_at, scn.spec.lambda_.fall_at = 1e6, 2e6
    lines = [json.dumps(dict(t=5.0, step=50, kind='command', command='lambda', value=1.0, ramp=20.0)),
             json.dumps(dict(t=30.0, step=300, kind='command', command='steer', agent='agent_3', value=0.02)),
             json.dumps(dict(t=1.0, kind='kill', agent='agent_1'))]      # not a command: ignored
    commands = read_commands(lines, scn.names)
    assert sorted(commands) == [50, 300] and commands[300][0]['agent'] == 3
    a = simulate(scn, commands=commands)
    chosen = [e for e in a.meta['events'] if e['kind'] == 'leaders_chosen']
    k = int(round(chosen[0]['t'] / scn.dt))
    assert a.lam[k] - a.lam[:k + 1].min() >= CHOOSE_RISE > a.lam[k - 1] - a.lam[:k].min()
    assert 5.0 < chosen[0]['t'] < 8.0 and a.leader[-1, 3] and a.lam[-1] == 1.0
    b = simulate(scn, commands=read_commands(lines, scn.names))
    assert np.array_equal(a.r, b.r)
    assert [e['step'] for e in a.meta['events'] if e['kind'] == 'command'] == [50, 300]
    without = simulate(scn)
    assert not without.leader.any() and without.lam.max() < CHOOSE_RISE


def test_read_commands_rejects_a_command_without_a_step_or_agent():
    names = ['agent_0', 'agent_1']
    with pytest.raises(ValueError, match='line 1: command without a step'):
        read_commands([json.dumps(dict(kind='command', command='lambda', value=1.0))], names)
    with pytest.raises(ValueError, match="unknown agent 'agent_9'"):
        read_commands([json.dumps(dict(kind='command', step=1, command='steer', agent='agent_9', value=1.0))], names)


def test_swarm_simulate_replay_cli(tmp_path, swarm_cmd):
    """``swarm simulate --replay events.jsonl`` applies the commands (the printed events show
    the command and the leaders it chose); a bad file is one line and exit 2."""
    import subprocess
    ev = tmp_path / 'events.jsonl'
    ev.write_text(json.dumps(dict(t=2.0, step=20, kind='command', command='lambda', value=1.0, ramp=5.0)) + '\n')
    r = subprocess.run([swarm_cmd, 'simulate', 'homotopy_global', '--duration', '10', '--replay', ev, '--quiet',
                        '--no-figure', '--out', tmp_path / 'out'], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert 'event t=2: command' in r.stdout and 'leaders_chosen' in r.stdout
    ev.write_text('{"kind": "command", "command": "lambda", "value": 1.0}\n')
    r = subprocess.run([swarm_cmd, 'simulate', 'homotopy_global', '--duration', '10', '--replay', ev, '--quiet',
                        '--no-figure', '--out', tmp_path / 'out'], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.strip().count('\n') == 0 and 'line 1' in r.stderr, r.stderr
