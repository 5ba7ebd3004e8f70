"""colcon: ros2_ws (src -> ../src) builds with colcon-core + colcon-ros from PyPI, and the
installed executables start (they exit with a one-line error on a bad parameter)."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
PACKAGES = ['homotopy_commander', 'swarm_agent', 'swarm_core', 'swarm_tools', 'swarm_world']


def _colcon():
    exe = BIN / 'colcon'
    if not exe.exists():
        r = subprocess.run([sys.executable, '-m', 'pip', 'install', '-q', 'colcon-core', 'colcon-ros',
                            'colcon-python-setup-py'], capture_output=True, text=True, timeout=600)
        if r.returncode != 0 or not exe.exists():
            pytest.skip(f'colcon-core/colcon-ros not installable here: {r.stderr.strip().splitlines()[-1:]}')
    return str(exe)


@pytest.mark.slow
def test_colcon_build_and_installed_executables_start(tmp_path, ros_domain):
    colcon = _colcon()
    ws = ROOT / 'ros2_ws'
    assert (ws / 'src').resolve() == (ROOT / 'src').resolve()
    env = dict(os.environ, PATH=f'{BIN}:{os.environ["PATH"]}')
    r = subprocess.run([colcon, '--log-base', str(tmp_path / 'log'), 'build', '--base-paths', str(ws / 'src'),
                        '--build-base', str(tmp_path / 'build'), '--install-base', str(tmp_path / 'install')],
                       cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    for pkg in PACKAGES:
        assert f'Finished <<< {pkg}' in r.stdout, r.stdout[-2000:]
        assert (tmp_path / 'install' / pkg / 'share' / pkg / 'package.xml').exists()
    setup = tmp_path / 'install' / 'setup.sh'
    assert setup.exists()
    # the installed copies are the ones imported once the workspace is sourced
    where = subprocess.run(['sh', '-c', f'. {setup} && python3 -c "import swarm_agent; print(swarm_agent.__file__)"'
                            f' && command -v swarm_agent'], capture_output=True, text=True, timeout=60,
                           env=dict(env, PATH=f'{BIN}:{os.environ["PATH"]}'))
    assert str(tmp_path / 'install') in where.stdout, where.stdout + where.stderr
    for exe, bad in (('swarm_agent', 'w:=-1.0'), ('swarm_world', 'scenario:=no_such_scenario'),
                     ('homotopy_commander', 'mode:=sideways')):
        run = subprocess.run(['sh', '-c', f'. {setup} && {exe} --ros-args -p {bad}'], capture_output=True,
                             text=True, timeout=120, env=env)
        out = run.stdout + run.stderr
        assert run.returncode == 2, (exe, out)
        assert f'parameter {bad.split(":=")[0]}' in out and 'Traceback' not in out, (exe, out)
    shutil.rmtree(tmp_path / 'build', ignore_errors=True)
