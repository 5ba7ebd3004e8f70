"""End-to-end: the real ``ros2 launch`` (ros2cli + ros2launch + launch + launch_ros, Jazzy) runs
swarm_tools' launch file and starts the graph ``swarm run`` starts: the same processes (command
lines and DDS environment, read from /proc while they run), a lockstep trajectory equal to
``swarm simulate``'s, and the outputs ``swarm run`` writes.

The tools are not on PyPI, so CI does not have them and these tests skip there.  Locally:
``scripts/install_ros2_tools.sh`` (into /work/ros2tools), then run pytest with
``PYTHONPATH=/work/ros2tools``.  ``ros2`` is ros2cli's console script ``ros2 = ros2cli.cli:main``,
run here with this interpreter.

Two ways to name the launch file: by path (``ros2 launch src/swarm_tools/launch/swarm.launch.py``:
the pip/editable install of the project has no ament index entry for swarm_tools, so
``ros2 launch swarm_tools ...`` cannot find it there), and by package after ``colcon build``
(``install/swarm_tools/share/swarm_tools/launch/swarm.launch.py``, from setup.py's data_files).
"""
import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from tests.helpers import ROOT, Lines

TOOLS = ('launch', 'launch_ros', 'ros2launch', 'ros2cli')
MISSING = [m for m in TOOLS if importlib.util.find_spec(m) is None]
pytestmark = pytest.mark.skipif(bool(MISSING), reason=(
    f'the real ROS 2 launch tools are not importable ({", ".join(MISSING)}): they are not on PyPI, so CI has '
    'none; for a local run install them with scripts/install_ros2_tools.sh and set PYTHONPATH=/work/ros2tools'))

LAUNCH_FILE = ROOT / 'src' / 'swarm_tools' / 'launch' / 'swarm.launch.py'
ROS2 = [sys.executable, '-c', 'import sys; from ros2cli.cli import main; sys.exit(main())']
BIN = Path(sys.executable).parent


def ros2_env(tmp_path, **more):
    return dict(os.environ, ROS_LOG_DIR=str(tmp_path / 'roslog'), PATH=f'{BIN}:{os.environ["PATH"]}', **more)


def children_of(pid) -> list:
    out = subprocess.run(['ps', '-eo', 'pid,ppid'], capture_output=True, text=True).stdout.split('\n')[1:]
    return [int(a) for a, b in (ln.split() for ln in out if ln.strip()) if int(b) == pid]


def read_proc(pid):
    """(argv, environment) of a live process, or None."""
    try:
        argv = Path(f'/proc/{pid}/cmdline').read_bytes().split(b'\0')[:-1]
        env = Path(f'/proc/{pid}/environ').read_bytes().split(b'\0')
    except OSError:
        return None
    return [a.decode() for a in argv], dict(e.decode().split('=', 1) for e in env if b'=' in e)


def watch_children(proc, lines, timeout) -> dict:
    """{pid: (argv, env)} of every child ``proc`` starts, read again until each one ends (a
    child read between fork and exec would still show its parent's argv)."""
    seen = {}
    end = time.monotonic() + timeout
    while proc.poll() is None and time.monotonic() < end:
        for pid in children_of(proc.pid):
            got = read_proc(pid)
            if got is not None and got[0]:
                seen[pid] = got
        time.sleep(0.1)
    lines.t.join(timeout=10)
    return seen


def ros_view(argv) -> tuple:
    """(executable name, arguments, ROS arguments as a set, with the parameters file as FILE):
    ``argv`` of a node's process (a console script: the interpreter first) or as launch_ros
    builds it for a Node action."""
    if Path(argv[0]).name.startswith('python') and len(argv) > 1:
        argv = argv[1:]
    if '--ros-args' not in argv:
        return Path(argv[0]).name, tuple(argv[1:]), frozenset()
    i = argv.index('--ros-args')
    ros = argv[i + 1:]
    pairs = {(a, 'FILE' if a == '--params-file' else b) for a, b in zip(ros[::2], ros[1::2])}
    return Path(argv[0]).name, tuple(argv[1:i]), frozenset(pairs)


def planned(values, tmp_path) -> list:
    """What the launch file starts for ``values`` (its own plan, out redirected: planning makes
    the output directory ready), as `ros_view`s."""
    from swarm_tools.run import launch_description as ld
    run = ld.prepare(dict(values, out=str(tmp_path / 'plan_out')), workdir=tmp_path / 'plan')
    views = []
    for a in run.actions:
        kw = a.kwargs
        ros = ['--ros-args'] + (['-r', f'__node:={kw["name"]}'] if kw['name'] else []) + (
            ['-r', f'__ns:={kw["namespace"]}'] if kw['namespace'] else []) + ['--params-file', kw['parameters'][0]]
        views.append(ros_view([kw['executable'], *kw['arguments'], *ros]))
    return views


def check_lockstep_outputs(out: Path, scenario: str, duration: float, text: str):
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(load(scenario, duration=duration))
    assert got.r.shape == ref.r.shape, text[-3000:]
    assert np.abs(got.r - ref.r).max() <= 1e-9
    assert np.abs(got.u - ref.u).max() <= 1e-9
    assert np.abs(got.theta - ref.theta).max() <= 1e-9
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)
    metrics = json.loads((out / 'metrics.json').read_text())
    assert metrics, 'metrics.json is empty'
    run = json.loads((out / 'run.json').read_text())
    assert run['exit_code'] == 0 and run['processes'] and run['agents'] == got.r.shape[1]
    assert 'swarm run: done in' in text and f'wrote {out}/trajectory.npz, metrics.json' in text, text[-3000:]
    assert 'Traceback' not in text, text[-5000:]


def test_ros2_launch_by_path_starts_the_swarm_run_graph_and_equals_simulate(tmp_path, ros_domain, processes):
    out = tmp_path / 'run'
    values = dict(scenario='global_alignment', duration='4', mode='lockstep', no_figure='true')
    p = processes.start([*ROS2, 'launch', LAUNCH_FILE, *[f'{k}:={v}' for k, v in values.items()], f'out:={out}'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path,
                        env=ros2_env(tmp_path))
    lines = Lines(p)
    seen = watch_children(p, lines, 300)
    assert p.wait(timeout=60) == 0, ''.join(lines.lines[-40:])
    text = ''.join(lines.lines)
    check_lockstep_outputs(out, 'global_alignment', 4.0, text)
    # the processes: those of the plan (swarm run's), with the run's DDS set-up and our domain
    assert sorted(ros_view(argv) for argv, _ in seen.values()) == sorted(planned(values, tmp_path)), text[-3000:]
    for argv, env in seen.values():
        assert env['ROS_DOMAIN_ID'] == str(ros_domain) and env['RMW_IMPLEMENTATION'] == 'rmw_fastrtps_cpp'
        assert Path(env['FASTRTPS_DEFAULT_PROFILES_FILE']).name == 'fastdds_loopback.xml', argv
    pids = json.loads((out / 'pids.json').read_text())
    agents = {pid for pid, (argv, _) in seen.items() if ros_view(argv)[0] == 'swarm_agent'}
    assert set(pids) == {f'agent_{i}' for i in range(6)} and set(pids.values()) == agents
    # the run's working directory (parameters file, DDS profile) is gone with the run
    files = {argv[argv.index('--params-file') + 1] for argv, _ in seen.values() if '--params-file' in argv}
    assert len(files) == 1 and not Path(files.pop()).parent.exists()


def test_ros2_launch_a_3d_scenario_equals_simulate(tmp_path, ros_domain, processes):
    """homotopy_3d, shortened (6 s: leaders at 2, λ up from 4), by ``ros2 launch``: r, x, y, z,
    u, v, λ and the leaders equal `swarm simulate`'s bit for bit, with swarm run's outputs."""
    from tests.agent.test_natural_core import short_3d
    path, out = short_3d(tmp_path / 'h3.yaml', duration=6.0), tmp_path / 'run'
    p = processes.start([*ROS2, 'launch', LAUNCH_FILE, f'scenario:={path}', f'out:={out}', 'no_figure:=true'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path,
                        env=ros2_env(tmp_path))
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    text = ''.join(lines.lines)
    got, ref = Trajectory.load(out / 'trajectory.npz'), simulate(load(str(path)))
    assert got.r.shape == ref.r.shape == (61, 6, 3) and ref.leader.any() and np.abs(ref.v).max() > 0
    for key in ('r', 'x', 'y', 'z', 'u', 'v', 'lam', 'leader'):
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)
    assert json.loads((out / 'metrics.json').read_text())
    assert json.loads((out / 'run.json').read_text())['exit_code'] == 0
    assert 'swarm run: done in' in text and 'Traceback' not in text, text[-3000:]


def test_ros2_launch_ctrl_c_keeps_the_steps_done(tmp_path, ros_domain, processes):
    out = tmp_path / 'run'
    p = processes.start([*ROS2, 'launch', LAUNCH_FILE, 'scenario:=homotopy_global', f'out:={out}', 'no_figure:=true',
                         'progress_every:=5'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                        cwd=tmp_path, env=ros2_env(tmp_path))
    lines = Lines(p)
    assert lines.wait_for('[world] t=    5.00', 180), ''.join(lines.lines)
    kids = children_of(p.pid)
    assert len(kids) == 8, ''.join(lines.lines)
    os.kill(p.pid, signal.SIGINT)                       # Ctrl-C
    lines.wait(p, 60)
    lines.t.join(timeout=10)
    text = ''.join(lines.lines)
    assert not [k for k in kids if read_proc(k) is not None], text[-3000:]
    got = Trajectory.load(out / 'trajectory.npz')
    n = len(got.t)
    dt = load('homotopy_global').dt
    assert 5 / dt <= n < 1000 / dt, text[-3000:]
    ref = simulate(load('homotopy_global', duration=(n - 1) * dt))
    assert np.abs(got.r - ref.r[:n]).max() <= 1e-9 and np.array_equal(got.lam, ref.lam[:n])
    assert json.loads((out / 'run.json').read_text())['exit_code'] == 130
    assert (out / 'metrics.json').exists()
    assert 'swarm run: stopped (code 130)' in text and 'partial run' in text, text[-3000:]


def _colcon():
    exe = BIN / 'colcon'
    if not exe.exists():
        pytest.skip('colcon is not installed (requirements.txt: colcon-core, colcon-ros, colcon-python-setup-py, '
                    'colcon-bash)')
    return str(exe)


@pytest.mark.slow
def test_ros2_launch_swarm_tools_after_colcon_build(tmp_path, ros_domain, processes):
    """``ros2 launch swarm_tools swarm.launch.py`` finds the launch file in the colcon install's
    share/swarm_tools/launch (ament index), and runs it: agent containers, equal to simulate."""
    colcon = _colcon()
    env = ros2_env(tmp_path)
    env.pop('AMENT_PREFIX_PATH', None)
    install = tmp_path / 'install'
    r = subprocess.run([colcon, '--log-base', str(tmp_path / 'log'), 'build',
                        '--base-paths', str(ROOT / 'ros2_ws' / 'src'),
                        '--build-base', str(tmp_path / 'build'), '--install-base', str(install)],
                       cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    installed = install / 'swarm_tools' / 'share' / 'swarm_tools' / 'launch' / 'swarm.launch.py'
    assert installed.read_text() == LAUNCH_FILE.read_text()
    setup = install / 'setup.bash'
    find = ('from ros2launch.api import get_share_file_path_from_package as f; '
            "print(f(package_name='swarm_tools', file_name='swarm.launch.py'))")
    # without the workspace (the pip install alone: the venv's ament index has the ROS wheels'
    # packages, not the project's) the package is not found ...
    alone = subprocess.run([sys.executable, '-c', find], capture_output=True, text=True, timeout=60,
                           env=dict(env, AMENT_PREFIX_PATH=sys.prefix))
    assert alone.returncode != 0 and "package 'swarm_tools' not found" in alone.stderr, alone.stderr[-2000:]
    # ... with it sourced, ros2 launch finds the installed file
    looked = subprocess.run(['bash', '-c', f'source {setup} && exec "$@"', '_', sys.executable, '-c', find],
                            capture_output=True, text=True, env=env, timeout=60)
    assert looked.returncode == 0 and looked.stdout.strip() == str(installed), looked.stdout + looked.stderr
    out = tmp_path / 'run'
    p = processes.start(['bash', '-c', f'source {setup} && exec "$@"', '_', *ROS2, 'launch', 'swarm_tools',
                         'swarm.launch.py', 'scenario:=global_alignment', 'duration:=3', 'mode:=lockstep',
                         'agents_per_process:=3', f'out:={out}', 'no_figure:=true'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path, env=env)
    lines = Lines(p)
    seen = watch_children(p, lines, 300)
    assert p.wait(timeout=60) == 0, ''.join(lines.lines[-40:])
    text = ''.join(lines.lines)
    check_lockstep_outputs(out, 'global_alignment', 3.0, text)
    assert '(3 agents per process)' in text and '4 processes' in text, text[:3000]
    containers = sorted(ros_view(argv)[1] for argv, _ in seen.values() if ros_view(argv)[0] == 'swarm_agent_container')
    assert containers == [('agent_0', 'agent_1', 'agent_2'), ('agent_3', 'agent_4', 'agent_5')], text[-3000:]
    shutil.rmtree(tmp_path / 'build', ignore_errors=True)
