"""``ros2 launch swarm_tools swarm.launch.py``: the launch actions built from the plan
(`swarm_tools.run.launch_description`) start what ``swarm run`` starts.  Pure: no ``launch``,
no process, no DDS.  What ``swarm run`` would start is taken from `swarm run` itself
(``launch._run_processes`` with a stand-in for ``subprocess.Popen`` that records each process's
argv, environment and the parameters file it reads); the launch actions' command lines are
rebuilt as launch_ros (Jazzy) builds a ``Node``'s (``launch_ros/actions/node.py``:
``[executable, *arguments, '--ros-args', '-r', '__node:=NAME', '-r', '__ns:=NS',
'--params-file', FILE]``).  The real ``ros2 launch`` runs in tests/e2e/test_ros2_launch.py.
"""
import itertools
import json
import os
import re
import signal
import tempfile
from pathlib import Path

import pytest

from swarm_ros.rosutil import EXIT_NOTES, FATAL_EXIT
from swarm_tools.run import launch, processes
from swarm_tools.run import launch_description as ld
from tests.helpers import ROOT

LAUNCH_FILE = ROOT / 'src' / 'swarm_tools' / 'launch' / 'swarm.launch.py'


def node_command(kw: dict) -> list:
    """The argv launch_ros' ``Node(**kw)`` starts (no ros_namespace / global parameters set)."""
    cmd = [kw['executable'], *kw.get('arguments', []), '--ros-args']
    if kw.get('name') is not None:
        cmd += ['-r', f'__node:={kw["name"]}']
    if kw.get('namespace') is not None:
        ns = kw['namespace'] if kw['namespace'].startswith('/') else '/' + kw['namespace']
        cmd += ['-r', f'__ns:={ns}']
    for p in kw.get('parameters', []):
        cmd += ['--params-file', str(p)]
    return cmd


def normal(cmd: list) -> tuple:
    """(argv before --ros-args, the ROS arguments as a set of (flag, value)): the order of
    ``-r`` and ``--params-file`` does not matter to a ROS node."""
    if '--ros-args' not in cmd:
        return tuple(cmd), frozenset()
    i = cmd.index('--ros-args')
    ros = cmd[i + 1:]
    assert len(ros) % 2 == 0, cmd
    return tuple(cmd[:i]), frozenset(zip(ros[::2], ros[1::2]))


class FakePopen:
    """Records what `swarm run`'s supervisor starts; the world ends at once (code 0), the others
    when signalled, so `run_processes` returns without waiting."""
    started = []
    pids = itertools.count(900001)

    def __init__(self, args, env=None, **kw):
        self.args, self.env, self.pid, self.returncode = list(args), dict(env or {}), next(self.pids), None
        pfile = [a for a, b in zip(self.args, self.args[1:]) if a == '--params-file']
        files = {'params': Path(self.args[self.args.index('--params-file') + 1]).read_text() if pfile else None}
        for var in ('FASTRTPS_DEFAULT_PROFILES_FILE',):
            if self.env.get(var):
                files[var] = Path(self.env[var]).read_text()
        self.files = files
        self.started.append(self)
        if 'swarm_world' in Path(self.args[0]).name:
            self.returncode = 0

    def poll(self):
        return self.returncode

    def send_signal(self, sig):
        if sig != signal.SIGCONT:
            self.returncode = -int(sig)

    def wait(self, timeout=None):
        return self.returncode


def swarm_run_starts(monkeypatch, argv) -> list:
    """What ``swarm run ARGV`` starts (FakePopen each) and the temporary directory it used."""
    FakePopen.started = []
    monkeypatch.setattr(processes.subprocess, 'Popen', FakePopen)
    monkeypatch.setattr(processes.os, 'killpg', lambda *a: pytest.fail(f'killpg{a} in a fake run'))
    run = launch.validate(launch._parser().parse_args(argv))
    assert launch._run_processes(run) == 0
    return FakePopen.started


def unplace(text: str, *dirs) -> str:
    """``text`` with each of the run's working directories replaced by WORKDIR."""
    for d in dirs:
        text = text.replace(str(d), 'WORKDIR')
    return re.sub(re.escape(tempfile.gettempdir()) + r'/swarm_run_\w+', 'WORKDIR', text)


@pytest.fixture
def fixed_run_id(monkeypatch):
    monkeypatch.setattr(launch, 'new_run_id', lambda: 'feedc0de')


CASES = {
    'lockstep': dict(mode='lockstep', duration='3'),
    'realtime': dict(mode='realtime', rtf='4', duration='3', progress_every='1'),
    'containers_and_view': dict(mode='lockstep', agents_per_process='4', agent_services='off', foxglove='0',
                                clock_every='10', seed='3'),
    '3d': dict(scenario='homotopy_3d', mode='lockstep', duration='3'),
}


@pytest.mark.parametrize('case', list(CASES))
def test_launch_actions_are_the_processes_swarm_run_starts(case, tmp_path, monkeypatch, fixed_run_id):
    values = {'scenario': 'homotopy_global', 'out': str(tmp_path / 'out'), 'no_figure': 'true', **CASES[case]}
    work = tmp_path / 'launch'
    work.mkdir()
    plan = ld.prepare(values, workdir=work)
    started = swarm_run_starts(monkeypatch, ld.run_argv(values))
    # the same processes, in the same order
    assert [a.label for a in plan.actions] == [s.label for s in plan.procs.specs]
    assert len(plan.actions) == len(started) == plan.run.processes
    labels = ['world', 'commander'] + ([f'agent_{i}' for i in range(6)] if case != 'containers_and_view'
                                       else ['agents[agent_0..agent_3]', 'agents[agent_4..agent_5]', 'view'])
    assert [a.label for a in plan.actions] == labels
    for action, proc in zip(plan.actions, started):
        kw = action.kwargs
        cmd = node_command(kw) if action.kind == 'node' else kw['cmd']
        # the same executable file, arguments, node name, namespace and parameters file
        assert normal([unplace(c, work) for c in cmd]) == normal([unplace(c, work) for c in proc.args]), action.label
        assert os.path.isabs(cmd[0]) and cmd[0] == proc.args[0]
        # the same whole environment (the DDS profile of run/dds.py), and files of the same content
        assert {k: unplace(v, work) for k, v in kw['env'].items()} == \
               {k: unplace(v, work) for k, v in proc.env.items()}, action.label
        assert kw['env']['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(work / 'fastdds_loopback.xml')
        assert kw['output'] == 'screen'
        if action.kind == 'node':
            text = Path(kw['parameters'][0]).read_text()
            assert unplace(text, work) == unplace(proc.files['params'], work)
            assert kw['parameters'] == [str(work / 'params.yaml')]
        assert Path(kw['env']['FASTRTPS_DEFAULT_PROFILES_FILE']).read_text() == \
               proc.files['FASTRTPS_DEFAULT_PROFILES_FILE']
    kinds = {a.label: a.kind for a in plan.actions}
    assert kinds['world'] == kinds['commander'] == 'node' and kinds.get('view', 'process') == 'process'
    world = next(a for a in plan.actions if a.label == 'world')
    assert world.kwargs['name'] == 'world' and world.kwargs['namespace'] is None
    assert Path(world.kwargs['executable']).name == 'swarm_world' and world.spec.package == 'swarm_world'
    commander = next(a for a in plan.actions if a.label == 'commander')
    assert commander.spec.package == 'homotopy_commander'
    params = json.dumps(plan.procs.params)
    assert plan.run.params['/world']['mode'] == CASES[case]['mode'] and '"run_id": "feedc0de"' in params
    if case == 'realtime':
        assert plan.run.params['/world']['rtf'] == 4.0
    if case == '3d':                             # the agents get the 3D pose: r and the frame
        assert plan.run.scn.dim == 3 and plan.run.params['/agent_2/agent']['dim'] == 3
        assert len(plan.run.params['/agent_2/agent']['frame']) == 9
    if case == 'lockstep':
        agent = next(a for a in plan.actions if a.label == 'agent_2')
        assert (agent.kwargs['name'], agent.kwargs['namespace']) == ('agent', '/agent_2')
        assert agent.spec.package == 'swarm_agent' and Path(agent.kwargs['executable']).name == 'swarm_agent'
    if case == 'containers_and_view':
        box = plan.actions[2]
        assert box.kwargs['arguments'] == ['--no-services', 'agent_0', 'agent_1', 'agent_2', 'agent_3']
        assert box.kwargs['name'] is None and Path(box.kwargs['executable']).name == 'swarm_agent_container'
        assert plan.actions[-1].kwargs['cmd'][1:] == ['view', '--port', '0']
        assert plan.run.params['/world']['clock_every'] == 10 and plan.run.scn.seed == 3


def test_every_swarm_run_option_is_a_launch_argument_or_refused():
    dests = {a.dest for a in launch._parser()._actions if a.dest != 'help'}
    args = {a.name: a for a in ld.launch_arguments()}
    assert set(args) | set(ld.NOT_OFFERED) == dests and not set(args) & set(ld.NOT_OFFERED)
    assert {'scenario', 'duration', 'mode', 'rtf', 'seed', 'out', 'no_figure', 'dt', 'agents_per_process',
            'dds', 'foxglove', 'robots'} <= set(args)
    assert args['scenario'].default is None and 'default_value' not in args['scenario'].declare_kwargs()
    assert args['mode'].declare_kwargs()['choices'] == ['lockstep', 'realtime']
    assert args['no_figure'].default == 'false' and args['rtf'].default == '1.0'
    assert args['duration'].default == ''


def test_launch_values_become_swarm_run_options():
    argv = ld.run_argv(dict(scenario='homotopy_global', duration='60', mode='realtime', rtf='2', seed='',
                            no_figure='true', foxglove='true', robots='external:agent_0-agent_2; mujoco:agent_3',
                            ros_namespace='/ignored'))
    assert argv[0] == 'homotopy_global'
    a = ld.parse(dict(scenario='homotopy_global', duration='60', mode='realtime', rtf='2', seed='',
                      no_figure='true', foxglove='true', robots='external:agent_0-agent_2; mujoco:agent_3'))
    want = launch._parser().parse_args(['homotopy_global', '--duration', '60', '--mode', 'realtime', '--rtf', '2',
                                        '--no-figure', '--foxglove', '--robots', 'external:agent_0-agent_2',
                                        '--robots', 'mujoco:agent_3'])
    assert vars(a) == vars(want)
    assert not ld.parse(dict(scenario='x', no_figure='false', foxglove='')).no_figure
    assert ld.parse(dict(scenario='x', foxglove='9000')).foxglove == 9000
    assert ld.parse(dict(scenario='x', foxglove='0')).foxglove == 0           # a free port, as --foxglove 0
    assert ld.parse(dict(scenario='x', foxglove='false')).foxglove is None
    assert ld.parse(dict(scenario='x', seed='-1')).seed == -1


@pytest.mark.parametrize('values, word', [
    (dict(scenario='homotopy_global', record='x.mcap'), 'record:=x.mcap: not offered'),
    (dict(scenario='homotopy_global', in_process='true'), 'in_process:=true: not offered'),
    (dict(scenario='homotopy_global', remote_agents='2-3'), 'remote_agents:=2-3: not offered'),
    (dict(scenario=''), 'scenario:=NAME is required'),
    (dict(scenario='homotopy_global', no_figure='maybe'), 'no_figure:=maybe: true or false'),
    (dict(scenario='homotopy_global', rtf='fast'), "argument --rtf: invalid float value: 'fast'"),
    (dict(scenario='homotopy_global', mode='sideways'), 'argument --mode: invalid choice'),
])
def test_bad_launch_values_are_named(values, word):
    with pytest.raises(ld.NotStarted, match=re.escape(word)):
        ld.prepare(values, workdir='/nonexistent')


def test_bad_options_and_outputs_are_refused_as_swarm_run_refuses_them(tmp_path):
    with pytest.raises(ld.NotStarted, match=re.escape('--rtf 0.0: must be in (0, 1e4)')):
        ld.prepare(dict(scenario='homotopy_global', rtf='0', out=str(tmp_path / 'o')))
    with pytest.raises(ld.NotStarted, match='cannot be loaded'):
        ld.prepare(dict(scenario='no_such_scenario', out=str(tmp_path / 'o')))
    (tmp_path / 'file').write_text('')
    with pytest.raises(ld.NotStarted):
        ld.prepare(dict(scenario='homotopy_global', out=str(tmp_path / 'file')))


def test_a_run_that_needs_a_discovery_server_is_left_to_swarm_run(tmp_path):
    path = tmp_path / 'big.yaml'
    path.write_text('name: big\nagents: {count: 120}\nduration: 1\n')
    with pytest.raises(ld.NotStarted, match='need a Fast DDS discovery server'):
        ld.prepare(dict(scenario=str(path), out=str(tmp_path / 'o')))
    plan = ld.prepare(dict(scenario=str(path), out=str(tmp_path / 'o'), agents_per_process='40'))
    try:
        assert [a.label for a in plan.actions][2:] == ['agents[agent_0..agent_39]', 'agents[agent_40..agent_79]',
                                                       'agents[agent_80..agent_119]']
    finally:
        plan.close()
    assert not plan.workdir.exists()


def test_the_event_handlers_do_what_swarm_run_does(tmp_path, monkeypatch, capsys):
    plan = ld.prepare(dict(scenario='homotopy_global', out=str(tmp_path / 'out'), duration='2'))
    assert plan.start_lines()[0].startswith('swarm run: run ') and '8 processes' in plan.start_lines()[0]
    # the agents' pids go to the world's pid_file (faults) and pids.json once every agent runs
    for i, label in enumerate(['world', 'commander'] + [f'agent_{k}' for k in range(6)]):
        assert not plan.procs.pid_file.exists()
        plan.started(label, 1000 + i)
    pids = json.loads(plan.procs.pid_file.read_text())
    assert pids == {f'agent_{k}': 1002 + k for k in range(6)}
    assert json.loads((tmp_path / 'out' / 'pids.json').read_text()) == pids
    assert plan.run.params['/world'].get('pid_file') is None and \
           plan.procs.params['/world']['pid_file'] == str(plan.procs.pid_file)
    # an agent that exits: said, the run goes on; the commander: the run stops (code 1)
    lines, stop = plan.exited('agent_3', -9)
    assert not stop and lines == ['swarm run: agent_3 exited with code -9; the world drops it from the roster '
                                  'after its missing_timeout']
    lines, stop = plan.exited('commander', 1)
    assert stop and lines == ['swarm run: commander exited with code 1; stopping the run'] and plan.code == 1
    assert plan.exited('agent_4', -2) == ([], False)        # stopping: the others' exits are not news
    # the world's exit writes the outputs with swarm run's own finish()
    seen = []
    monkeypatch.setattr(launch, 'finish', lambda run, code, wall: seen.append((run, code)) or code)
    assert plan.exited('world', 130) == ([], True)
    assert seen == [(plan.run, 1)] and plan.result == 1 and plan.failed
    plan.close()
    assert not plan.workdir.exists()


def test_an_agent_whose_law_failed_stops_the_run_as_swarm_run_does(tmp_path, monkeypatch):
    """Every process is told of the run's notes directory (SWARM_EXIT_NOTES); an agent process
    that exits with FATAL_EXIT (its law failed) left its one line there: said once, the run stops
    (code 1) and the outputs say why (``run.stopped``), as `processes.run_processes` does."""
    monkeypatch.setattr(launch, 'finish', lambda run, code, wall: code)
    plan = ld.prepare(dict(scenario='homotopy_global', out=str(tmp_path / 'out')))
    notes = Path(plan.procs.env[EXIT_NOTES])
    assert notes.is_dir() and notes.parent == plan.workdir
    assert all(a.kwargs['env'][EXIT_NOTES] == str(notes) for a in plan.actions)
    (notes / '4242.txt').write_text('agent_2: the law failed: boom\n')
    lines, stop = plan.exited('agent_2', FATAL_EXIT)
    assert stop and lines == ['swarm run: agent_2: the law failed: boom; stopping the run']
    assert plan.code == 1 and plan.run.stopped == 'agent_2: the law failed: boom'
    assert plan.exited('agent_3', FATAL_EXIT) == ([], False)          # said once
    plan.shutting_down()
    assert plan.exited('world', 130) == ([], True) and plan.result == 1 and plan.failed
    plan.close()
    assert not plan.workdir.exists()
    # no line left: the agent is named
    bare = ld.prepare(dict(scenario='homotopy_global', out=str(tmp_path / 'out2')))
    assert bare.exited('agent_0', FATAL_EXIT) == (['swarm run: agent_0: its law failed; stopping the run'], True)
    assert bare.exited('commander', 0) == ([], False) and bare.code == 1
    bare.close()


def test_a_shutdown_is_a_ctrl_c_unless_the_run_has_ended(tmp_path, monkeypatch):
    monkeypatch.setattr(launch, 'finish', lambda run, code, wall: code)
    plan = ld.prepare(dict(scenario='homotopy_global', out=str(tmp_path / 'out')))
    plan.shutting_down()
    assert plan.exited('world', 130) == ([], True) and plan.result == 130 and not plan.failed
    plan.close()
    done = ld.prepare(dict(scenario='homotopy_global', out=str(tmp_path / 'out2')))
    assert done.exited('world', 0) == ([], True)
    done.shutting_down()                # the shutdown that follows the world's end
    assert done.result == 0 and done.code == 0 and not done.failed
    done.close()


def test_the_launch_file_is_thin_and_installed():
    text = LAUNCH_FILE.read_text()
    assert 'from swarm_tools.run import launch_description as spec' in text
    assert 'def generate_launch_description' in text and len(text.splitlines()) < 80
    setup = (ROOT / 'src' / 'swarm_tools' / 'setup.py').read_text()
    assert "('share/' + package_name + '/launch', ['launch/swarm.launch.py'])" in setup
    # the pure module does not import launch / launch_ros (CI has neither)
    pure = Path(ld.__file__).read_text()
    assert not re.search(r'^\s*(import|from) launch(_ros)?\b', pure, re.M)
