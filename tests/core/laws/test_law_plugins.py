"""Laws as plug-ins (no ROS): the paper's laws through the interface equal the code before it
bit for bit, a user's law from a file runs, what a law reads (its view, t) and how each way a
law can fail is said: one line naming the law and the problem, before the run where it can be
seen then, else the run stops with the steps done saved (``swarm simulate``, ``swarm sweep``)."""
from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.laws import (
    Blend,
    Law,
    LawError,
    LawFailed,
    View,
    flat_parameters,
    from_flat_parameters,
    law_mapping,
    make_law,
    param,
    parameter_specs,
    swarm_control,
)
from swarm_core.scenario.loader import ScenarioError, load, parse
from swarm_tools.simulate import simulate_main, sweep_main
from tests.core.laws import law_references as refs
from tests.core.laws import paper_law
from tests.helpers import ROOT, faulty_law_scenario

REFERENCE = json.loads((refs.DATA / f'paper_laws_{refs.REVISION}.json').read_text())['cases']


# ------------------------------------------------------------------ the paper's laws, bit for bit

@pytest.mark.parametrize('case', sorted(REFERENCE))
def test_paper_laws_equal_the_code_before_the_interface(case):
    """Every shipped scenario of the paper and every paper kind at λ = 0 and 1: t, r, θ, u, λ and
    the leader flags hash to what revision 1f236c6 gave (law_references.py made them)."""
    data = refs.cases()[case]
    got = refs.digests(refs.arrays(refs.run(data, case)))
    want = REFERENCE[case]
    assert {k: got[k] == want[k] for k in got} == dict.fromkeys(got, True), _first_difference(case, data)


def _first_difference(case, data) -> str:
    """Where a case first differs from the stored samples (every 200th step)."""
    samples = np.load(refs.DATA / f'paper_laws_{refs.REVISION}.npz')
    arr = refs.arrays(refs.run(data, case))
    for k, v in arr.items():
        old = samples[f'{case}/{k}']
        new = v[::refs.SAMPLE_EVERY]
        if old.shape != new.shape or not np.array_equal(old, new, equal_nan=True):
            return f'{case}: {k} differs (sampled every {refs.SAMPLE_EVERY} steps)'
    return f'{case}: differs between the sampled steps'


@pytest.mark.parametrize('lam', [0.0, 1.0])
@pytest.mark.parametrize('kind', refs.PAPER_KINDS)
def test_a_paper_law_in_a_blend_equals_it_alone(kind, lam):
    """blend(kind, spl_parallel) at λ = 0 and blend(spl_parallel, kind) at λ = 1 give the
    stored run of the paper's law alone, bit for bit (with its target and barrier terms, which
    the scenario's sections set in the blend's paper law too)."""
    data = refs.kind_case(kind, lam)
    paper = dict(data['law'])
    other = {'kind': 'spl_parallel', 'omega0': 0.05, 'phase_gain': -0.3}
    data['law'] = {'kind': 'blend', 'from': paper, 'to': other} if lam == 0.0 else \
        {'kind': 'blend', 'from': other, 'to': paper}
    scn = parse(data, 'blend')
    assert isinstance(scn.law, Blend)
    got = refs.digests(refs.arrays(simulate(scn)))
    want = REFERENCE[data['name']]
    assert {k: got[k] == want[k] for k in got} == dict.fromkeys(got, True)


# ------------------------------------------------------------------ a user's law

def test_the_example_user_law_runs_and_is_recorded(tmp_path):
    """examples/alignment.yaml: the law from examples/laws/alignment.py (relative to the
    scenario file) aligns the headings; metrics.json records its kind and parameters."""
    scn = load(str(ROOT / 'examples' / 'alignment.yaml'))
    assert scn.law.kind == f'{ROOT / "examples" / "laws" / "alignment.py"}:Alignment'
    assert scn.law.parameters() == {'cutoff_radius': 6.0, 'gain': 0.3}
    out = tmp_path / 'run'
    assert simulate_main([str(ROOT / 'examples' / 'alignment.yaml'), '--out', str(out), '--no-figure',
                          '--quiet', '--duration', '20']) == 0
    doc = json.loads((out / 'metrics.json').read_text())
    assert doc['parameters']['law'] == {'kind': scn.law.kind, 'cutoff_radius': 6.0, 'gain': 0.3}
    traj = Trajectory.load(out / 'trajectory.npz')
    p = np.abs(np.exp(1j * traj.theta).mean(axis=1))
    assert p[-1] > 0.99 > p[0]                      # the headings aligned


def test_a_user_law_becomes_ros_parameters_with_ranges_and_descriptions():
    law = load(str(ROOT / 'examples' / 'alignment.yaml')).law
    flat = flat_parameters(law)
    assert flat == {'law': law.kind, 'cutoff_radius': 6.0, 'gain': 0.3}
    assert from_flat_parameters(flat) == law
    specs = parameter_specs(law)
    assert specs['gain'] == (0.1, 'coupling K', (0.0, 10.0))
    assert specs['cutoff_radius'][2] == (1e-9, 1e6)
    assert law_mapping(law) == {'kind': law.kind, **law.parameters()}


class Clock(Law):
    """Records what it was asked (a test's law, by module: tests.core.laws.test_law_plugins:Clock)."""
    seen: list = []
    gain = param(0.0, lo=-1.0, hi=1.0, doc='turn rate')

    def control(self, view: View):
        Clock.seen.append((view.t, len(view.pos), view.receivers.size, view.lam))
        return np.full(view.receivers.size, self.gain)


CLOCK = {'name': 'clock', 'seed': 0, 'dt': 0.25, 'duration': 2.0, 'agents': {'count': 4},
         'law': {'kind': 'tests.core.laws.test_law_plugins:Clock', 'gain': 0.1},
         'lambda': {'kind': 'constant', 'value': 0.25}}


@pytest.mark.parametrize('integrator', ['zoh', 'rk4'])
def test_a_law_reads_the_sim_time_and_lambda_of_the_step(integrator):
    scn = parse(dict(CLOCK, integrator=integrator))
    Clock.seen.clear()
    simulate(scn)
    ts = [t for t, *_ in Clock.seen]
    steps = [n * scn.dt for n in range(scn.steps + 1)]
    if integrator == 'zoh':
        assert ts == steps
    else:                                       # the stage times t, t + dt/2 (twice), t + dt
        assert set(steps) <= set(ts) and min(ts) == 0.0 and max(ts) == scn.duration
        assert any(abs(t / scn.dt - round(t / scn.dt)) == 0.5 for t in ts)
    assert all(lam == 0.25 and n == 4 and k == 4 for _, n, k, lam in Clock.seen)


def test_with_a_radio_each_receiver_reads_a_view_of_its_own():
    """A radio model: each agent's u from what it believes, so the law gets one receiver at a
    time, its own row first and then the agents it heard (a lossy link hears fewer)."""
    data = dict(CLOCK, comms={'loss': 0.5})
    scn = parse(data)
    Clock.seen.clear()
    simulate(scn)
    assert Clock.seen and all(k == 1 for _, _, k, _ in Clock.seen)
    rows = [n for _, n, _, _ in Clock.seen]
    assert max(rows) <= 4 and min(rows) < 4
    ts = sorted({t for t, *_ in Clock.seen})
    assert ts == [n * scn.dt for n in range(scn.steps + 1)]


def test_a_paper_law_in_a_blend_keeps_the_target_and_barrier_of_the_scenario():
    data = copy.deepcopy(refs.kind_case('target', 0.0))
    data['law'] = {'kind': 'blend', 'from': data['law'], 'to': {'kind': 'spl_parallel'}}
    law = parse(data).law
    assert law.from_law.target_gain == 0.05 and law.from_law.barrier_gain == 5.0
    assert isinstance(law.to_law, Law)


# ------------------------------------------------------------------ a law that cannot be used

@pytest.mark.parametrize('kind, law, text', [
    ('broken.py:Alignment', {}, "law.kind 'broken.py:Alignment': broken.py does not import: SyntaxError"),
    ('missing.py:Alignment', {}, "law.kind 'missing.py:Alignment': no file "),
    ('faulty.py:Nobody', {}, "law.kind 'faulty.py:Nobody': faulty.py has no Nobody"),
    ('faulty.py:NotALaw', {}, "law.kind 'faulty.py:NotALaw': NotALaw is not a law (a subclass of swarm_core.laws.Law)"),
    ('no_such_module:Law', {}, "law.kind 'no_such_module:Law': module no_such_module does not import"),
    ('faulty.py:Raises', {'gain': 5}, 'faulty.py:Raises: parameter gain = 5 is outside [0, 1]'),
    ('faulty.py:Raises', {'gain': 'high'}, "faulty.py:Raises: parameter gain must be a number, got 'high'"),
    ('faulty.py:Raises', {'gian': 0.2}, "faulty.py:Raises: unknown parameter 'gian' (its parameters: cutoff_radius, "
                                        "gain)"),
    ('faulty.py:Raises', {'cutoff_radius': 0}, 'faulty.py:Raises: parameter cutoff_radius = 0 is outside'),
    ('spl_parallel', {'phase_gain': 1000}, 'law spl_parallel: parameter phase_gain = 1000 is outside [-100, 100]'),
    ('flocking', {}, "law.kind 'flocking': not a law kind (global, local"),
])
def test_a_law_that_cannot_be_used_is_one_line_before_the_run(tmp_path, capsys, kind, law, text):
    path = faulty_law_scenario(tmp_path, kind, **law)
    (tmp_path / 'broken.py').write_text('from swarm_core.laws import Law\nclass Alignment(Law)\n')
    with pytest.raises(ScenarioError) as err:
        load(str(path))
    msg = str(err.value)
    assert text in msg and '\n' not in msg, msg
    with pytest.raises(SystemExit) as stop:
        simulate_main([str(path), '--out', str(tmp_path / 'run'), '--quiet'])
    assert stop.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and text in lines[0], lines
    assert not (tmp_path / 'run').exists()                  # nothing ran


AT_START = {'Raises': 'raised RuntimeError: boom after t = 5',
            'WrongShape': 'returned shape (7,), want (6,): one u per receiver',
            'NotFinite': 'returned a non-finite u (nan)'}
#: every way a law can fail in a run (tests/helpers.FAULTY_LAWS) but leaving a thread (a
#: subprocess's test: tests/core/laws/test_law_misconduct.py)
FAILS = {**AT_START,
         'Exits': 'raised SystemExit: 3',
         'OwnInterrupt': 'raised KeyboardInterrupt (its own: no Ctrl-C came)',
         'ClosesGenerator': 'raised GeneratorExit: closed',
         'BadArray': 'returned Reads, which raised RuntimeError when read as numbers: cannot be read',
         'ComplexU': 'returned a complex u: a curvature is a real number'}


@pytest.mark.parametrize('cls', sorted(AT_START))
def test_a_law_that_fails_at_the_start_is_refused_with_the_scenario(tmp_path, cls):
    """Each scenario's law is tried once on the initial state at load: a law that fails at
    t = 0 is refused there, one line, before anything runs."""
    (tmp_path / 'at_start.py').write_text(
        'import numpy as np\nfrom swarm_core.laws import Law\n'
        'class Raises(Law):\n    def control(self, view):\n        raise RuntimeError("boom after t = 5")\n'
        'class WrongShape(Law):\n    def control(self, view):\n        return np.zeros(view.receivers.size + 1)\n'
        'class NotFinite(Law):\n    def control(self, view):\n        return np.full(view.receivers.size, np.nan)\n')
    path = faulty_law_scenario(tmp_path, f'at_start.py:{cls}')
    with pytest.raises(ScenarioError) as err:
        load(str(path))
    assert f'at_start.py:{cls} {AT_START[cls]} (at t = 0, on the initial state)' in str(err.value)


@pytest.mark.parametrize('cls', sorted(FAILS))
def test_a_law_that_fails_during_the_run_stops_it_with_the_steps_done(tmp_path, cls):
    scn = load(str(faulty_law_scenario(tmp_path, f'faulty.py:{cls}')))
    with pytest.raises(LawFailed) as err:
        simulate(scn)
    assert str(err.value) == f'law {tmp_path / "faulty.py"}:{cls} {FAILS[cls]} (at t = 5.1, step 51)'
    traj = err.value.trajectory
    assert len(traj.t) == 51 and traj.t[-1] == 5.0 and np.isfinite(traj.r).all()
    assert traj.meta['stopped'] == str(err.value)


@pytest.mark.parametrize('cls', sorted(FAILS))
def test_swarm_simulate_says_one_line_and_saves_the_steps_done(tmp_path, capsys, cls):
    path = faulty_law_scenario(tmp_path, f'faulty.py:{cls}')
    out = tmp_path / 'run'
    assert simulate_main([str(path), '--out', str(out), '--quiet', '--no-figure']) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f'swarm simulate: law {tmp_path / "faulty.py"}:{cls} {FAILS[cls]}')
    assert 'the steps done (t = 0..5)' in err[0]
    assert len(Trajectory.load(out / 'trajectory.npz').t) == 51
    summary = json.loads((out / 'metrics.json').read_text())['summary']
    assert FAILS[cls] in summary['stopped'] and summary['t_end'] == 5.0


@pytest.mark.parametrize('jobs', [1, 2])
@pytest.mark.parametrize('cls', sorted(FAILS))
def test_swarm_sweep_stops_with_one_line(tmp_path, capsys, cls, jobs):
    path = faulty_law_scenario(tmp_path, f'faulty.py:{cls}')
    assert sweep_main([str(path), '--seeds', '3', '--jobs', str(jobs)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (f'swarm sweep: {path} seed 0: law {tmp_path / "faulty.py"}:{cls} {FAILS[cls]} '
                       '(at t = 5.1, step 51); the sweep stops'), err
    assert not any('Traceback' in ln for ln in err)


@pytest.mark.parametrize('where', ['--jobs=1', '--jobs=2', '--scheduler=local:1'])
def test_a_study_stops_with_one_line_and_keeps_its_cache(tmp_path, capfd, where):
    path = faulty_law_scenario(tmp_path, 'faulty.py:Raises')
    out = tmp_path / 'study'
    assert sweep_main([str(path), '--set', 'law.gain=0.1,0.2', '--seeds', '2', where, '--out', str(out),
                       '--quiet', '--no-figure']) == 1
    err = capfd.readouterr().err
    line = [ln for ln in err.splitlines() if 'raised' in ln]
    assert len(line) == 1, err
    assert line[0].startswith(f'swarm sweep: law {tmp_path / "faulty.py"}:Raises raised RuntimeError: boom after '
                              't = 5 (at t = 5.1, step 51); the study stops')
    assert 'Traceback' not in err and (out / 'cache').is_dir()


def test_a_law_error_names_the_law_and_pickles_without_the_steps():
    import pickle
    err = LawFailed('law x.py:A raised RuntimeError: boom (at t = 1, step 10)', trajectory=object(), t=1.0)
    back = pickle.loads(pickle.dumps(err))
    assert isinstance(back, LawFailed) and str(back) == str(err) and back.t == 1.0 and back.trajectory is None
    assert isinstance(back, LawError) and isinstance(back, ValueError)


def test_swarm_control_checks_what_a_law_returns():
    class Ragged(Law):
        def control(self, view):
            return [[0.0]] * view.receivers.size
    pos = np.zeros((3, 2))
    with pytest.raises(LawError, match=r'returned shape \(3, 1\), want \(3,\)'):
        swarm_control(pos, np.ones(3), np.zeros(3), np.arange(3), Ragged())
    assert swarm_control(pos, np.ones(3), np.zeros(3), np.arange(3), paper_law(kind='global')).shape == (3,)
    assert make_law({'kind': 'global'}) == paper_law(kind='global')


def test_the_law_in_docs_is_the_example_file():
    """docs/laws.md shows examples/laws/alignment.py's law line for line (blank lines aside:
    the file keeps the lint's), so the documented law is the one the tests run."""
    import re
    doc = (ROOT / 'docs' / 'laws.md').read_text()
    shown = re.search(r'```python\n(.*?)```', doc, re.S).group(1)
    src = (ROOT / 'examples' / 'laws' / 'alignment.py').read_text()
    code = src[src.index('import numpy'):]
    assert [ln for ln in shown.splitlines() if ln.strip()] == [ln for ln in code.splitlines() if ln.strip()]
