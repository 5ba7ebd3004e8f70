"""Hostile inputs, one test (or a few) per class, all without a ROS graph: finite but absurd
values, study files and caches, the size of a run, replay files and the hosts' records.  The
peers on the domain are in tests/swarm_ros/test_msg_checks.py (runinfo is pure)."""
from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from swarm_core import checks as inputs
from swarm_core import study as st
from swarm_core.command import plan as command_plan
from swarm_core.command import schedules
from swarm_core.faults.agents import Fault, FaultTimeline
from swarm_core.scenario import loader as scenario
from swarm_tools import simulate as simulate_cli

NAMES = ['agent_0', 'agent_1', 'agent_2']


# ---------------------------------------------------------------- finite but absurd values

@pytest.mark.parametrize('bound, good, bad', [
    (inputs.STEERING_BOUND, (0.01, -1e6), (1e308, 1e9, math.nan, True, '0.1')),
    (inputs.PAUSE_BOUND, (1.5, 1e7), (0.0, 1e308, math.inf, -1.0)),
    (inputs.RAMP_BOUND, (0.0, 20.0), (1e308, -1.0, [1])),
    (inputs.DT_BOUND, (0.05, 10.0), (0.0, 1e-12, 11.0)),
    (inputs.DURATION_BOUND, (1.0, 1e7), (0.0, 1e9)),
])
def test_each_value_has_one_bound(bound, good, bad):
    for v in good:
        assert bound.check(v) == float(v)
    for v in bad:
        with pytest.raises(inputs.InputError, match=f'^{bound.name}='):
            bound.check(v)


def test_the_schema_takes_its_bounds_from_the_same_objects():
    base = dict(name='x', agents={'count': 3})
    for change, where in [(dict(dt=0.0), 'dt'), (dict(dt=1e-12), 'dt'), (dict(duration=1e9), 'duration'),
                          (dict(leaders={'fixed': {'agent_0': {'kind': 'constant', 'curvature': 1e9}}}), 'curvature'),
                          (dict(faults=[{'at': 1, 'freeze': 'agent_1', 'for': 1e308}]), 'for'),
                          (dict(faults=[{'at': 1e308, 'kill': 'agent_1'}]), 'at'),
                          (dict(leaders={'fixed': {'agent_0': {'kind': 'sinusoid', 'period': 1e-310}}}), 'period'),
                          (dict(leaders={'fixed': {'agent_0': {'kind': 'sinusoid', 'amplitude': 1e6,
                                                               'offset': 1e6}}}), 'steering bound'),
                          (dict(**{'lambda': {'kind': 'ramps', 'ramps': [{'at': 1, 'to': 1, 'duration': 1e308}]}}),
                           'duration')]:
        with pytest.raises(scenario.ScenarioError, match=where):
            scenario.parse({**base, **change})


def test_the_world_survives_any_fault_request_a_peer_can_send():
    """Every request is either refused (ValueError, KeyError, TypeError: one log line in the
    world) or applied; `swarm pause agent_1 1e308` was accepted and crashed the world with
    OverflowError in the freeze schedule."""
    from swarm_world.parsing import fault_request
    requests = ['{"kind": "freeze", "agent": "agent_1", "for": 1e308}',
                '{"kind": "freeze", "agent": "agent_1", "for": 1e999}',
                '{"kind": "freeze", "agent": "agent_1", "for": "5"}',
                '{"kind": "freeze", "agent": "agent_1", "for": [1]}',
                '{"kind": "kill", "agent": ["agent_1"]}',
                '{"kind": "kill", "agent": "leader:x"}',
                '{"kind": "kill", "agent": "leader:99999999999999999999999"}',
                '[' * 100000, '{"kind": "freeze", "agent": "agent_1", "for": 2.5}']
    tl = FaultTimeline([], NAMES, 0.05)
    applied = 0
    for text in requests:
        try:
            tl.add(fault_request(text))
            applied += 1
        except (ValueError, KeyError, TypeError):
            continue
    for k in range(200):
        tl.apply(k, {0: 0})
    assert applied == 1 and not tl.dead.any()
    with pytest.raises(inputs.InputError):
        Fault(0.0, 'freeze', 'agent_1', 1e308)


def test_commands_and_decisions_take_the_same_bounds():
    """A steering of 1e308 made an agent NaN once λ = 1: refused by the commander's check,
    the world's check of a decision and the Foxglove view alike."""
    from swarm_tools.live.view import client_bound
    from swarm_world.realtime import decision_valid
    for cmd in [dict(command='steer', agent=0, value=1e308), dict(command='lambda', value=1.0, ramp=1e308),
                dict(command='lambda', value=1.0, ramp=[1]), dict(command='lambda', value=1.0, shape=['x'])]:
        with pytest.raises(ValueError):
            command_plan.check_command(cmd, 3)
    assert command_plan.check_command(dict(command='steer', agent=0, value=1e6), 3)['value'] == 1e6
    assert not decision_valid(0.5, np.zeros(3, bool), np.array([0.0, 1e308, 0.0]), 3)
    assert decision_valid(0.5, np.zeros(3, bool), np.array([0.0, 0.01, 0.0]), 3)
    assert client_bound('/agent_0/steering') is inputs.STEERING_BOUND
    assert client_bound('/swarm/lambda') is inputs.LAMBDA_BOUND


# ---------------------------------------------------------------- sizes

@pytest.mark.parametrize('over, said', [(dict(duration=1e9), 'duration'), (dict(dt=1e-12), 'dt'),
                                        (dict(duration=1e7, dt=1e-3), 'steps'),
                                        (dict(duration=1e6, dt=0.1), 'recorded values')])
def test_the_size_of_a_run_is_bounded_before_it_starts(over, said, tmp_path, capsys):
    """`simulate --duration 1e9` or `--dt 1e-12` ended in ArrayMemoryError: one line, exit 2."""
    t0 = time.monotonic()
    with pytest.raises(SystemExit) as ex:
        simulate_cli.simulate_main(['homotopy_global', '--out', str(tmp_path / 'o'), '--quiet', '--no-figure',
                                    *sum(([f'--{k}', str(v)] for k, v in over.items()), [])])
    err = capsys.readouterr().err
    assert ex.value.code == 2 and said in err and len(err.strip().splitlines()) == 1
    assert time.monotonic() - t0 < 10


# ---------------------------------------------------------------- replay files

def _replay(tmp_path, capsys, text_or_path, duration=5):
    path = text_or_path
    if not str(text_or_path).startswith('/dev/'):
        path = tmp_path / 'events.jsonl'
        path.write_text(text_or_path)
    with pytest.raises(SystemExit) as ex:
        simulate_cli.simulate_main(['homotopy_global', '--duration', str(duration), '--out', str(tmp_path / 'o'),
                                    '--quiet', '--no-figure', '--replay', str(path)])
    return ex.value.code, capsys.readouterr().err


@pytest.mark.parametrize('text, said', [
    (json.dumps(dict(kind='command', step=3, command='lambda', value=0.5, ramp=[1])), 'ramp=[1]'),
    (json.dumps(dict(kind='command', step=3, command='steer', agent=['agent_0'], value=0.1)), 'unknown agent'),
    (json.dumps(dict(kind='command', step=3, command='steer', agent='agent_0', value=1e308)), 'steering=1e+308'),
    ('[' * 100000, 'characters'),
    ('[' * 5000 + ']' * 5000, 'nested deeper'),
    ('/dev/zero', 'more than'),
])
def test_a_bad_replay_file_is_one_line(tmp_path, capsys, text, said):
    """`"ramp": [1]` was a TypeError, 100k nested [ a RecursionError, /dev/zero read until
    MemoryError."""
    code, err = _replay(tmp_path, capsys, text)
    assert code == 2 and said in err and len(err.strip().splitlines()) == 1, err


def _naive(initial, ramps, t):
    """RampSchedule.value as it was: a walk over every ramp (the reference)."""
    level = initial
    for i, r in enumerate(ramps):
        if t < r.start:
            break
        nxt = ramps[i + 1].start if i + 1 < len(ramps) else math.inf
        x = 1.0 if r.duration <= 0 else (min(t, nxt) - r.start) / r.duration
        level = level + (r.to - level) * float(schedules.ramp_shape(x, r.shape))
    return level


def test_many_live_set_points_run_in_linear_time_with_the_same_values(monkeypatch):
    """200k replayed commands ran O(n²) (every step walked every ramp): now each step walks
    only the ramps not yet over, with the same sums in the same order, bit for bit."""
    rng = np.random.default_rng(1)
    s = schedules.RampSchedule(initial=0.2)
    starts = np.sort(rng.uniform(0, 100, 300))
    for k, t0 in enumerate(starts):
        s.then(float(t0), float(rng.uniform()), float(rng.choice([0.0, 0.5, 3.0])), ['smoothstep', 'linear'][k % 2])
        if k % 7 == 0:
            s.then(float(rng.uniform(0, t0)), 0.3, 1.0)           # out of order: folded again
    for t in np.concatenate([np.linspace(0, 110, 500), rng.uniform(0, 110, 100)]):
        assert s.value(float(t)) == _naive(0.2, s.ramps, float(t))
    calls = []
    real = schedules.ramp_shape
    monkeypatch.setattr(schedules, 'ramp_shape', lambda x, shape: calls.append(1) or real(x, shape))
    live, n = schedules.RampSchedule(), 5000
    for k in range(n):
        live.then(k * 0.05, (k % 7) / 7, 1.0)
        live.value(k * 0.05)
    assert len(calls) < 4 * n          # a walk over every ramp at every step: n²/2 calls


# ---------------------------------------------------------------- study files and caches

def test_study_files_go_through_the_scenario_yaml_limits(tmp_path):
    bomb = tmp_path / 'bomb.yaml'
    bomb.write_text('a: &a ["x","x","x","x","x","x","x","x","x"]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]\n'
                    'c: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]\nscenario: homotopy_global\ngrid: {seed: [1]}\n')
    deep = tmp_path / 'deep.yaml'
    deep.write_text('scenario: homotopy_global\ngrid: ' + '[' * 100 + ']' * 100 + '\n')
    big = tmp_path / 'big.yaml'
    big.write_text('scenario: homotopy_global\n' + '#' * (scenario.MAX_FILE_BYTES + 1))
    for path, said in [(bomb, 'aliases'), (deep, 'nested deeper'), (big, 'bytes')]:
        with pytest.raises(st.StudyError, match=said):
            st.load_study(path)


@pytest.mark.parametrize('sets, said', [
    (['law.leader_gain=0:0.05:100000000'], '100000000 values'),
    (['law.leader_gain=1:2:1000', 'law.alpha=0.01:0.02:1000'], '1000000 cells'),
])
def test_grids_have_a_cell_limit_checked_before_any_allocation(sets, said):
    t0 = time.monotonic()
    with pytest.raises(st.StudyError, match=said):
        st.make_study('homotopy_global', sets, seeds=1)
    with pytest.raises(st.StudyError, match='runs'):
        st.make_study('homotopy_global', ['law.leader_gain=1:2:100'], seeds=10**9)
    assert time.monotonic() - t0 < 5


@pytest.mark.parametrize('edit', [
    lambda d: d['result'].update(final_clusters=99),
    lambda d: d['result'].update(ok='yes'),
    lambda d: d['result'].update(min_distance='1e999'),
    lambda d: '{"result": {"min_distance": 1e999}}',
    lambda d: [],
    lambda d: d.update(seed=d['seed'] + 1),
    lambda d: 'not json',
])
def test_a_cached_row_that_is_not_one_is_run_again_with_one_warning(tmp_path, edit):
    s = st.make_study('homotopy_global', ['law.leader_gain=10'], seeds=1, fixed={'duration': 2.0})
    rows, counts = st.run_study(s, tmp_path)
    assert counts['ran'] == 1
    (path,) = tmp_path.glob('*.json')
    doc = json.loads(path.read_text())
    new = edit(doc)
    path.write_text(new if isinstance(new, str) else json.dumps(doc if new is None else new))
    with pytest.warns(UserWarning, match='running it again') as warned:
        again, counts = st.run_study(s, tmp_path)
    assert len(warned) == 1 and counts == {'total': 1, 'cached': 0, 'ran': 1}
    assert again == rows
    _, counts = st.run_study(s, tmp_path)             # the good row is back: taken as it is
    assert counts['cached'] == 1


# ---------------------------------------------------------------- hosts

def test_a_rebuild_never_replaces_a_longer_record(tmp_path, capsys):
    """The launcher rebuilt the world's 85-sample trajectory from the bag as 84 samples (the
    discovery server was SIGKILLed, the run ended with an error): the longer one stays."""
    from swarm_core.engine.trajectory import Trajectory
    from swarm_tools.run import outputs
    from tests.helpers import write_run_bag
    run_dir = tmp_path / 'run'
    assert simulate_cli.simulate_main(['homotopy_global', '--duration', '4', '--out', str(run_dir),
                                       '--quiet', '--no-figure']) == 0
    saved = (run_dir / 'trajectory.npz').read_bytes()
    traj = Trajectory.load(run_dir / 'trajectory.npz')
    short = Trajectory(names=traj.names, t=traj.t[:-1], r=traj.r[:-1], theta=traj.theta[:-1], u=traj.u[:-1],
                       lam=traj.lam[:-1], leader=traj.leader[:-1], meta=dict(traj.meta))
    scn = scenario.load('homotopy_global', duration=4)
    bag = write_run_bag(short, tmp_path / 'run.mcap', metrics_cutoff=scn.law.cutoff_radius)
    assert not outputs.salvage(scn, run_dir, bag, 'lockstep', 0.0, figure=False)
    assert (run_dir / 'trajectory.npz').read_bytes() == saved
    assert f'kept the trajectory the world saved ({len(traj.t)} samples); the bag holds {len(traj.t) - 1}' \
        in capsys.readouterr().err
    (run_dir / 'trajectory.npz').unlink()                # nothing saved: the rebuild is written
    assert outputs.salvage(scn, run_dir, bag, 'lockstep', 0.0, figure=False)
    assert outputs.saved_samples(run_dir / 'trajectory.npz') == len(traj.t) - 1


def test_the_world_and_join_agree_on_the_scenario_hash():
    """The world loads the scenario from its parameters, `swarm join` from its options: the
    same run gives the same hash (announced on /swarm/run), another seed or duration another."""
    from swarm_ros.scenario_params import reload_scenario, scenario_parameters
    for over in ({}, dict(duration=30.0), dict(seed=3)):
        mine = scenario.load('homotopy_global', **over)
        world = reload_scenario(**scenario_parameters(mine, 'homotopy_global', duration=over.get('duration', 0.0)))
        assert world.content_hash == mine.content_hash
    assert len({scenario.load('homotopy_global', **o).content_hash for o in ({}, dict(seed=3), dict(dt=0.025))}) == 3
