"""colcon: ros2_ws (src -> ../src) builds with colcon from PyPI, ``install/setup.bash`` exists,
and ``ros2 run PKG EXE`` finds and starts every executable of every package.

``ros2 run`` is emulated as ros2cli (Jazzy) does the lookup:

* ``ros2run/api/__init__.py`` ``get_executable_path``: the one path among
  ``ros2pkg.api.get_executable_paths(package_name)`` whose basename equals EXE;
* ``ros2pkg/api/__init__.py`` ``get_executable_paths``: ``os.walk`` of
  ``<prefix>/lib/<package>`` (folders starting with ``.`` skipped), files with ``os.X_OK``;
* the prefix is ``ament_index_python.get_package_prefix`` (``packages.py``): the
  ``AMENT_PREFIX_PATH`` entry holding ``share/ament_index/resource_index/packages/<package>``;
* ``run_executable`` then runs ``[path] + argv`` as a child process.

So an executable installed anywhere else (``bin/``, as setuptools does without the packages'
``setup.cfg``) is not found.  The real ``ament_index_python`` wheel does the prefix lookup here.
"""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import PACKAGES, ROOT, console_scripts

BIN = Path(sys.executable).parent

# the lookup of `ros2 run PKG EXE` (see the module docstring), run in the sourced workspace
LOOKUP = r'''
import json, os, sys
from ament_index_python import get_package_prefix
def get_executable_paths(package_name):
    base_path = os.path.join(get_package_prefix(package_name), 'lib', package_name)
    out = []
    for dirpath, dirnames, filenames in os.walk(base_path):
        dirnames[:] = sorted(d for d in dirnames if d[0] not in ['.'])
        for filename in sorted(filenames):
            path = os.path.join(dirpath, filename)
            if os.access(path, os.X_OK):
                out.append(path)
    return out
def get_executable_path(package_name, executable_name):
    paths = [p for p in get_executable_paths(package_name) if os.path.basename(p) == executable_name]
    if len(paths) > 1:
        raise SystemExit(f'multiple executables: {paths}')
    return paths[0] if paths else None
print(json.dumps({pkg: {'prefix': get_package_prefix(pkg),
                        'all': [os.path.basename(p) for p in get_executable_paths(pkg)],
                        'found': {exe: get_executable_path(pkg, exe) for exe in exes}}
                  for pkg, exes in json.loads(sys.argv[1]).items()}))
'''


def _colcon():
    exe = BIN / 'colcon'
    if not exe.exists():
        pytest.skip('colcon is not installed (requirements.txt: colcon-core, colcon-ros, '
                    'colcon-python-setup-py, colcon-bash)')
    return str(exe)


@pytest.mark.slow          # ROS: the nodes started get as far as reading their parameters
def test_colcon_build_and_ros2_run_finds_every_executable(tmp_path, ros_domain):
    colcon = _colcon()
    ws = ROOT / 'ros2_ws'
    assert (ws / 'src').resolve() == (ROOT / 'src').resolve()
    env = dict(os.environ, PATH=f'{BIN}:{os.environ["PATH"]}')
    env.pop('AMENT_PREFIX_PATH', None)
    install = tmp_path / 'install'
    r = subprocess.run([colcon, '--log-base', str(tmp_path / 'log'), 'build', '--base-paths', str(ws / 'src'),
                        '--build-base', str(tmp_path / 'build'), '--install-base', str(install)],
                       cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    for pkg in PACKAGES:
        assert f'Finished <<< {pkg}' in r.stdout, r.stdout[-2000:]
        assert (install / pkg / 'share' / pkg / 'package.xml').exists()
    setup = install / 'setup.bash'
    assert setup.exists(), 'no install/setup.bash: colcon-bash missing'

    def sourced(cmd, **kw):
        return subprocess.run(['bash', '-c', f'source {setup} && {cmd}'], capture_output=True, text=True,
                              env=env, **kw)

    wanted = {pkg: console_scripts(pkg) for pkg in PACKAGES}
    look = subprocess.run(['bash', '-c', f'source {setup} && exec python3 -c "$LOOKUP" "$WANTED"'],
                          capture_output=True, text=True, timeout=120,
                          env=dict(env, LOOKUP=LOOKUP, WANTED=json.dumps(wanted)))
    assert look.returncode == 0, look.stdout + look.stderr
    found = json.loads(look.stdout)
    for pkg, exes in wanted.items():
        assert found[pkg]['prefix'] == str(install / pkg), found[pkg]
        assert sorted(found[pkg]['all']) == exes, (pkg, found[pkg])
        for exe in exes:
            assert found[pkg]['found'][exe] == str(install / pkg / 'lib' / pkg / exe), (pkg, exe)
    # `swarm run` (the launcher) finds the node executables the same way when neither this
    # interpreter's directory nor PATH has them (a colcon install under a system Python)
    exes = ['swarm', 'swarm_world', 'swarm_agent', 'homotopy_commander', 'swarm_robots']
    probe = ("import json, sys; sys.executable = '/nonexistent/python3'; "
             "from swarm_tools.run.processes import _exe; print(json.dumps({e: _exe(e) for e in %r}))" % exes)
    launch = subprocess.run(['bash', '-c', f'source {setup} && PATH=/usr/bin:/bin exec {sys.executable} -c "$PROBE"'],
                            capture_output=True, text=True, timeout=120, env=dict(env, PROBE=probe))
    assert launch.returncode == 0, launch.stdout + launch.stderr
    from swarm_tools.run.processes import EXE_PACKAGE
    assert json.loads(launch.stdout) == {e: found[EXE_PACKAGE[e]]['found'][e] for e in exes}
    # the installed copies are the ones imported once the workspace is sourced
    where = sourced('python3 -c "import swarm_agent; print(swarm_agent.__file__)"', timeout=60)
    assert str(install) in where.stdout, where.stdout + where.stderr

    # start each one as `ros2 run` does ([path] + argv): the nodes exit with a one-line error on
    # a bad parameter (they got as far as reading their parameters), the tools print --help
    nodes = {'swarm_agent': 'cutoff_radius:=-1.0', 'swarm_world': 'scenario:=no_such_scenario',
             'homotopy_commander': 'mode:=sideways', 'swarm_robots': 'mode:=sideways'}
    for pkg, exes in wanted.items():
        for exe in exes:
            path = found[pkg]['found'][exe]
            argv = ['--ros-args', '-p', nodes[exe]] if exe in nodes else ['--help']
            run = sourced(' '.join([path, *argv]), timeout=120)
            out = run.stdout + run.stderr
            assert 'Traceback' not in out, (exe, out)
            if exe in nodes:
                assert run.returncode == 2, (exe, out)
                assert f'parameter {nodes[exe].split(":=")[0]}' in out, (exe, out)
            else:
                assert run.returncode == 0 and 'usage:' in out, (exe, out)
    shutil.rmtree(tmp_path / 'build', ignore_errors=True)
