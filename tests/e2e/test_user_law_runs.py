"""Laws as plug-ins over ROS: a user's law from examples/laws/ in `swarm run` lockstep (a
process per agent, and agent containers) equals `swarm simulate`; a law reading the sim time
gets the batch engine's t; a blend split by `swarm lambda` live ends in the circular formation;
a law that fails stops the run with one line and the steps done saved, and one that cannot be
used stops `swarm run` before any process starts."""
import re
import subprocess
import time

import numpy as np
import pytest
import yaml

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from tests.helpers import ROOT, Lines, faulty_law_scenario

ALIGNMENT = ROOT / 'examples' / 'alignment.yaml'


def run_swarm(processes, swarm_cmd, path, out, *options, timeout=300):
    """`swarm run PATH --out OUT --no-figure OPTIONS`: (exit code, its lines, wall s)."""
    t0 = time.monotonic()
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', *options],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    code = lines.wait(p, timeout)
    return code, ''.join(lines.lines), time.monotonic() - t0


@pytest.mark.parametrize('per', [1, 3], ids=['processes', 'containers'])
def test_a_user_law_lockstep_equals_simulate(per, tmp_path, ros_domain, processes, swarm_cmd):
    out = tmp_path / 'run'
    code, text, _ = run_swarm(processes, swarm_cmd, ALIGNMENT, out, '--duration', '20',
                              '--agents-per-process', str(per))
    assert code == 0, text[-3000:]
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(load(str(ALIGNMENT), duration=20))
    assert got.r.shape == ref.r.shape == (201, 6, 2)
    assert np.abs(got.r - ref.r).max() <= 1e-9
    assert np.abs(got.u - ref.u).max() <= 1e-9
    assert np.abs(got.theta - ref.theta).max() <= 1e-9
    assert np.abs(ref.u).max() > 0.01                         # the law steered


TIME_LAW = '''\
import numpy as np

from swarm_core.laws import Law, param


class Sway(Law):
    """Every agent turns with sin(ω t): a law that reads the sim time of its view."""
    omega = param(0.7, lo=0.0, hi=10.0, doc='rad per sim s')

    def control(self, view):
        return np.full(view.receivers.size, 0.2 * np.sin(self.omega * view.t) + 0.01 * view.receivers)
'''


def test_a_law_reads_the_same_sim_time_in_ros_lockstep(tmp_path, ros_domain, processes, swarm_cmd):
    (tmp_path / 'sway.py').write_text(TIME_LAW)
    path = tmp_path / 'sway.yaml'
    path.write_text(yaml.safe_dump({'name': 'sway', 'seed': 0, 'dt': 0.1, 'duration': 8.0, 'agents': {'count': 4},
                                    'law': {'kind': 'sway.py:Sway', 'omega': 0.9}}))
    out = tmp_path / 'run'
    code, text, _ = run_swarm(processes, swarm_cmd, path, out, '--agents-per-process', '2')
    assert code == 0, text[-3000:]
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(load(str(path)))
    np.testing.assert_array_equal(got.u, ref.u)               # u = f(t): the same t, bit for bit
    assert np.abs(got.r - ref.r).max() <= 1e-9


FLOCK_TO_CIRCLE = 'flock_to_circle'


def centre_spread(r, theta, omega0):
    """Largest distance of an agent's circle centre c_k = r_k + i e^{iθ_k}/ω0 from their mean."""
    c = r[..., 0] + 1j * r[..., 1] + 1j * np.exp(1j * theta) / omega0
    return np.abs(c - c.mean(axis=-1, keepdims=True)).max(axis=-1)


def test_a_blend_split_by_swarm_lambda_ends_in_the_circle(tmp_path, ros_domain, processes, swarm_cmd):
    """flock_to_circle at λ = 0 throughout, λ raised live with `swarm lambda 1`: the flock of
    the paper's global law turns into the SPL circle (centres together, radius 1/ω0)."""
    from swarm_core.scenario.loader import read_yaml
    data, _ = read_yaml(FLOCK_TO_CIRCLE)
    data.pop('expect', None)
    data.update(duration=60.0, **{'lambda': {'kind': 'constant', 'value': 0.0}})
    path = tmp_path / 'flock_to_circle_live.yaml'
    path.write_text(yaml.safe_dump(data))
    omega0 = data['law']['to']['omega0']
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--in-process', '--mode', 'realtime',
                         '--rtf', '2', '--progress-every', '5'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    at_10 = re.compile(r'\[world\] t=\s*(\d+\.\d+)')
    assert lines.wait_for(lambda ln: (m := at_10.match(ln)) is not None and float(m.group(1)) >= 10, 120), \
        ''.join(lines.lines[-30:])
    cmd = subprocess.run([swarm_cmd, 'lambda', '1', '--ramp', '2'], capture_output=True, text=True, timeout=60)
    assert cmd.returncode == 0, cmd.stdout + cmd.stderr
    assert lines.wait(p, 120) == 0, ''.join(lines.lines[-30:])
    got = Trajectory.load(out / 'trajectory.npz')
    spread = centre_spread(got.r, got.theta, omega0)
    before = got.lam == 0.0
    assert before[:50].all() and got.lam[-1] == 1.0
    # one threshold tells a common circle from none: the flock at λ = 0 settles near a spread
    # of 1.3-1.7 (the batch engine over 60 s), the circle near 0.5 (0.2/ω0 = 1.0)
    assert spread[before].min() > 0.2 / omega0                # a flock: no common circle
    assert spread[-1] < 0.2 / omega0                          # one circle ...
    radius = np.abs(got.r[-1, :, 0] + 1j * got.r[-1, :, 1] - (got.r[-1, :, 0] + 1j * got.r[-1, :, 1]
                                                                + 1j * np.exp(1j * got.theta[-1]) / omega0).mean())
    assert np.all(np.abs(radius * omega0 - 1.0) < 0.2)        # ... of radius 1/ω0


PROBLEM = {'Raises': 'raised RuntimeError: boom after t = 5',
           'WrongShape': 'returned shape (2,), want (1,): one u per receiver',
           'NotFinite': 'returned a non-finite u (nan)',
           'Exits': 'raised SystemExit: 3',
           'OwnInterrupt': 'raised KeyboardInterrupt (its own: no Ctrl-C came)',
           'LeavesThread': 'left a thread running (never-ends): a law may not start threads that outlive its call'}


@pytest.mark.parametrize('cls, options', [
    ('Raises', ()),
    ('Raises', ('--agents-per-process', '3')),
    ('Raises', ('--mode', 'realtime')),
    ('WrongShape', ('--in-process',)),
    ('NotFinite', ('--mode', 'realtime', '--in-process')),
    ('OwnInterrupt', ()),
    ('Exits', ('--mode', 'realtime')),
    ('LeavesThread', ('--agents-per-process', '3')),
], ids=['raises-processes', 'raises-containers', 'raises-realtime', 'shape-in-process', 'nan-realtime-in-process',
        'interrupt-processes', 'exit-realtime', 'thread-containers'])
def test_a_law_that_fails_stops_the_run_with_one_line(cls, options, tmp_path, ros_domain, processes, swarm_cmd):
    path = faulty_law_scenario(tmp_path, f'faulty.py:{cls}', duration=30.0)
    out = tmp_path / 'run'
    code, text, wall = run_swarm(processes, swarm_cmd, path, out, *options, timeout=180)
    assert code == 1, text[-3000:]
    problem = PROBLEM[cls] if '--agents-per-process' not in options else PROBLEM[cls].replace('(2,), want (1,)',
                                                                                           '(4,), want (3,)')
    said = [ln for ln in text.splitlines() if 'faulty.py' in ln]
    assert len(said) == 1, text[-3000:]
    assert said[0].startswith(f'swarm run: law {tmp_path / "faulty.py"}:{cls} {problem} (at t = 5'), said
    assert said[0].endswith('; stopping the run')
    assert 'Traceback' not in text and 'Exception in' not in text, text[-3000:]
    got = Trajectory.load(out / 'trajectory.npz')
    assert 4.9 <= got.t[-1] <= 6.0 and np.isfinite(got.r).all()      # the steps done, not the 30 s
    summary = yaml.safe_load((out / 'metrics.json').read_text())['summary']
    assert problem in summary['stopped'] and summary['interrupted']
    assert wall < 90, wall


@pytest.mark.parametrize('kind, law, text', [
    ('faulty.py:NotALaw', {}, 'NotALaw is not a law'),
    ('broken.py:Sway', {}, 'broken.py does not import: NameError'),
    ('faulty.py:Raises', {'gain': 2.0}, 'parameter gain = 2.0 is outside [0, 1]'),
    ('start.py:Raises', {}, 'raised ZeroDivisionError: division by zero (at t = 0, on the initial state)'),
])
def test_a_law_that_cannot_be_used_stops_swarm_run_before_it_starts(kind, law, text, tmp_path, ros_domain,
                                                                     processes, swarm_cmd):
    path = faulty_law_scenario(tmp_path, kind, **law)
    (tmp_path / 'broken.py').write_text('oops\n')
    (tmp_path / 'start.py').write_text('from swarm_core.laws import Law\n\nclass Raises(Law):\n'
                                       '    def control(self, view):\n        return 1 / 0\n')
    out = tmp_path / 'run'
    code, said, wall = run_swarm(processes, swarm_cmd, path, out, timeout=60)
    lines = said.strip().splitlines()
    assert code == 2 and len(lines) == 1, said
    assert lines[0].startswith(f'swarm run: {path}: law') and text in lines[0], lines
    assert not (out / 'trajectory.npz').exists() and wall < 30     # nothing started


def test_a_law_an_installed_package_registers_runs_by_name(tmp_path, ros_domain, processes, swarm_cmd):
    """A package on the path whose metadata declares a ``swarm_core.laws`` entry point: `swarm run`
    names its law ``law: {kind: spin}``, every agent process finds it (PYTHONPATH), and lockstep
    equals `swarm simulate` bit for bit."""
    import os

    from tests.core.laws.test_law_registry import installed_package
    site = tmp_path / 'site'
    site.mkdir()
    installed_package(site, {'spin': 'spinlaws:Spin'})
    path = tmp_path / 'spin.yaml'
    path.write_text(yaml.safe_dump({'name': 'spin', 'seed': 0, 'dt': 0.1, 'duration': 4.0, 'agents': {'count': 4},
                                    'law': {'kind': 'spin', 'rate': 0.15}}))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), os.environ.get('PYTHONPATH', '')]))
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--agents-per-process', '2'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    got = Trajectory.load(out / 'trajectory.npz')
    sim = subprocess.run([swarm_cmd, 'simulate', path, '--out', tmp_path / 'sim', '--no-figure'],
                         capture_output=True, text=True, env=env, timeout=300)
    assert sim.returncode == 0, sim.stdout + sim.stderr
    ref = Trajectory.load(tmp_path / 'sim' / 'trajectory.npz')
    assert got.r.shape == ref.r.shape == (41, 4, 2)
    np.testing.assert_array_equal(got.u, ref.u)
    np.testing.assert_array_equal(got.r, ref.r)
    assert np.all(got.u == 0.15)


def test_an_agent_whose_law_calls_os_exit_stops_the_run_as_vanished(tmp_path, ros_domain, processes, swarm_cmd):
    """os._exit in a law ends the agent's process with no word (nothing can catch it): the
    launcher says it vanished and stops the run, non-zero, with the steps done; an agent
    process stopped by a signal is not taken for one (its note), as the fault runs test."""
    (tmp_path / 'vanish.py').write_text(
        'import os\nimport numpy as np\nfrom swarm_core.laws import Law\n\n\nclass Vanish(Law):\n'
        '    def control(self, view):\n        if view.t > 5:\n            os._exit(0)\n'
        '        return np.zeros(view.receivers.size)\n')
    path = faulty_law_scenario(tmp_path, 'vanish.py:Vanish', duration=30.0)
    out = tmp_path / 'run'
    code, text, wall = run_swarm(processes, swarm_cmd, path, out, timeout=180)
    assert code == 1, text[-3000:]
    said = [ln for ln in text.splitlines() if 'vanished' in ln]
    assert said and said[0].startswith('swarm run: agent_') and 'exited with code 0 without a word' in said[0]
    got = Trajectory.load(out / 'trajectory.npz')
    assert 4.9 <= got.t[-1] <= 6.0 and 'vanished' in yaml.safe_load((out / 'metrics.json').read_text())['summary'][
        'stopped']
