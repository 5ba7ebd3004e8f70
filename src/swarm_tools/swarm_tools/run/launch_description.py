"""``ros2 launch swarm_tools swarm.launch.py scenario:=NAME [duration:=S mode:=realtime ...]``:
what that launch file (src/swarm_tools/launch/swarm.launch.py, installed by colcon into
``share/swarm_tools/launch``) does, as plain Python: it imports neither ``launch`` nor
``launch_ros``, so CI tests it without them.

The launch arguments are `swarm run`'s options, named by their ``dest`` (``--no-figure`` is
``no_figure:=true``, ``--agents-per-process 4`` is ``agents_per_process:=4``), read from the
same parser (`launch_arguments`), so the two cannot drift.  At launch time `prepare` turns their
values into ``swarm run``'s command line, validates and plans it with `swarm run`'s own code
(`launch.validate`: the scenario, the options, the output directory; `launch.plan_processes`:
the parameters file, the DDS environment, the processes), and gives a `LaunchRun`:

- ``actions``: one `ActionSpec` per process `swarm run` would start (`processes.ProcessSpec`):
  the keyword arguments of a ``launch_ros.actions.Node`` (the same executable file, parameters
  file, node name and namespace, arguments and whole environment), or of a
  ``launch.actions.ExecuteProcess`` for the live view (not a node);
- ``started`` / ``exited`` / ``shutting_down``: what the launch file calls from its
  OnProcessStart / OnProcessExit / OnShutdown handlers.  Once every agent process runs their pids
  go to the world's ``pid_file`` (faults) and ``pids.json`` in the output directory; an agent
  process that exits is reported as `swarm run` reports it, any other process stops the run, and
  so does an agent process whose law failed (exit `rosutil.FATAL_EXIT`: its one line, left in
  the run's notes directory, ``SWARM_EXIT_NOTES`` in every process's environment); when
  the world exits, the outputs are written by `launch.finish` as `swarm run` writes them
  (metrics.json, the figure, run.json, from the trajectory.npz the world wrote).

Not offered by the launch file (`NOT_OFFERED`): what needs the launcher's own supervision before
the nodes start (the recorder that must be ready first, a discovery server, agents on other
hosts) or is not a set of processes (``--in-process``).  Use ``swarm run`` for those.
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from swarm_ros.rosutil import EXIT_NOTES, FATAL_EXIT, read_fatal_note
from swarm_tools.run import launch
from swarm_tools.run.launch import NotStarted
from swarm_tools.run.processes import (
    REFUSED_EXIT,
    ProcessSpec,
    exit_line,
    note_of,
    refusal_line,
    vanished_line,
    write_pids,
)

__all__ = ['NOT_OFFERED', 'ActionSpec', 'LaunchArgument', 'LaunchRun', 'NotStarted', 'action_spec',
           'launch_arguments', 'parse', 'prepare', 'run_argv']

PROG = 'swarm.launch.py'

#: swarm run's options (by dest) that the launch file does not take, and why
NOT_OFFERED = {
    'in_process': 'every node in one process is `swarm run SCENARIO --in-process`',
    'record': ('the recorder must be ready before the nodes start: use `swarm run --record`, or start '
               '`ros2 bag record` first and pass state_readers:=1'),
    'remote_agents': 'agents on other hosts need a discovery server and `swarm join`: use `swarm run`',
    'discovery': 'a Fast DDS discovery server is started and supervised by `swarm run` only',
    'server_port': 'a Fast DDS discovery server is started and supervised by `swarm run` only',
}

_TRUE, _FALSE = ('true', '1', 'yes', 'on'), ('false', '0', 'no', 'off', '')


@dataclass(frozen=True)
class LaunchArgument:
    """One launch argument: a `swarm run` option."""
    name: str                   # the option's dest: scenario, duration, no_figure, ...
    option: str | None          # --duration, --no-figure (None: the positional scenario)
    kind: str                   # value, flag (true/false), list (';'-separated, repeated option), optional
    default: str | None         # None: required (the scenario)
    description: str
    choices: tuple | None = None

    def declare_kwargs(self) -> dict:
        """Keyword arguments of ``launch.actions.DeclareLaunchArgument`` (besides the name)."""
        kw = dict(description=self.description)
        if self.default is not None:
            kw['default_value'] = self.default
        if self.choices:
            kw['choices'] = list(self.choices)
        return kw


def _parser():
    """`swarm run`'s parser, whose errors raise `NotStarted` instead of exiting."""
    p = launch._parser()
    p.prog = PROG

    def error(message):
        raise NotStarted(f'{message} (the launch arguments are the options of `swarm run`, '
                         'e.g. --no-figure is no_figure:=true; see `ros2 launch swarm_tools swarm.launch.py -s`)')
    p.error = error
    return p


def launch_arguments() -> list[LaunchArgument]:
    """The launch arguments, from `swarm run`'s parser: every option but `NOT_OFFERED`."""
    out = []
    for act in _parser()._actions:
        if act.dest in ('help', *NOT_OFFERED):
            continue
        if not act.option_strings:
            out.append(LaunchArgument(act.dest, None, 'value', None, act.help))
            continue
        option = max(act.option_strings, key=len)
        what = f'{act.help} [swarm run {option}]'
        if act.nargs == 0:                                  # store_true
            out.append(LaunchArgument(act.dest, option, 'flag', 'false', what + ' (true or false)'))
        elif isinstance(act, argparse._AppendAction):
            out.append(LaunchArgument(act.dest, option, 'list', '', what + " (several: separated by ';')"))
        elif act.nargs == '?':
            out.append(LaunchArgument(act.dest, option, 'optional', '',
                                      what + f" (true: {act.const}; '' or false: off)"))
        else:
            default = '' if act.default is None else str(act.default)
            out.append(LaunchArgument(act.dest, option, 'value', default, what,
                                      tuple(act.choices) if act.choices else None))
    return out


def run_argv(values: Mapping[str, str]) -> list[str]:
    """`swarm run`'s command line (without ``swarm run``) for the launch arguments ``values``
    (a launch context's launch configurations: other keys are ignored); `NotStarted` for a
    value the launch file cannot take."""
    for name, why in NOT_OFFERED.items():
        if str(values.get(name, '') or '').strip():
            raise NotStarted(f'{name}:={values[name]}: not offered by the launch file: {why}')
    out = []
    for arg in launch_arguments():
        value = values.get(arg.name)
        value = '' if value is None else str(value).strip()
        if arg.option is None:
            if not value:
                raise NotStarted(f'{arg.name}:=NAME is required (a shipped scenario name or a YAML file)')
            out.insert(0, value)
        elif arg.kind == 'flag':
            if value.lower() not in _TRUE + _FALSE:
                raise NotStarted(f'{arg.name}:={value}: true or false')
            out += [arg.option] if value.lower() in _TRUE else []
        elif arg.kind == 'list':
            out += [f'{arg.option}={part}' for part in re.split(r'[;\s]+', value) if part]
        elif arg.kind == 'optional':          # foxglove: true (the default port), a port (0: a free one), off
            if value.lower() == 'true':
                out.append(arg.option)
            elif value.lower() not in ('', 'false'):
                out.append(f'{arg.option}={value}')
        elif value:
            out.append(f'{arg.option}={value}')
    return out


def parse(values: Mapping[str, str]):
    """`swarm run`'s parsed options for the launch arguments ``values``."""
    return _parser().parse_args(run_argv(values))


@dataclass(frozen=True)
class ActionSpec:
    """One launch action: ``kind`` node (``launch_ros.actions.Node(**kwargs)``) or process
    (``launch.actions.ExecuteProcess(**kwargs)``), for the process `spec` of `swarm run`."""
    kind: str
    label: str
    kwargs: dict
    spec: ProcessSpec


def action_spec(spec: ProcessSpec) -> ActionSpec:
    """The launch action that starts ``spec`` as `swarm run` starts it: a node gets the same
    executable file (by path: ``_exe`` found it as `swarm run` does, in the venv, on PATH or
    in ``lib/PACKAGE`` of a colcon install), the same parameters file, node name and namespace
    and arguments; every process gets the same whole environment (``env`` replaces the launch
    process's: the DDS profile of `dds.environment`)."""
    if spec.params_file is not None:
        return ActionSpec('node', spec.label, dict(
            executable=spec.path, name=spec.name, namespace=spec.namespace, parameters=[str(spec.params_file)],
            arguments=list(spec.arguments), env=dict(spec.env), exec_name=spec.label, output='screen'), spec)
    return ActionSpec('process', spec.label, dict(cmd=list(spec.command), env=dict(spec.env), name=spec.label,
                                                  output='screen'), spec)


class LaunchRun:
    """A run started by the launch file: its plan (`launch.RunPlan`), processes
    (`launch.ProcessPlan`) and actions, and what its event handlers do."""

    def __init__(self, run, procs, workdir: Path, own_workdir: bool = False):
        self.run, self.procs, self.workdir, self._own = run, procs, Path(workdir), own_workdir
        self.actions = [action_spec(s) for s in procs.specs]
        self.specs = {s.label: s for s in procs.specs}
        self.members = {s.label: s.members for s in procs.specs if s.members}
        self.pids = {}              # {agent process label: pid}
        self.ended = set()          # labels of the processes that have exited
        self.code = None            # what ends the run: 130 (a shutdown), 1 (a vital process died)
        self.result = None          # `launch.finish`'s exit code, once the world has exited
        self.t0 = time.monotonic()

    def start_lines(self) -> list[str]:
        """What `swarm run` says at the start."""
        return [self.run.summary()] + ([f'swarm run: {self.run.robots_line}'] if self.run.robots_line else [])

    def started(self, label: str, pid: int) -> None:
        """A process has started; once every agent process has, their pids go to the world's
        ``pid_file`` (faults) and to ``pids.json`` in the output directory."""
        if label in self.members and label not in self.pids:
            self.pids[label] = pid
            if len(self.pids) == len(self.members):
                write_pids(self.procs.pid_file, self.members, self.pids, self.run.out)

    def exited(self, label: str, returncode: int) -> tuple[list[str], bool]:
        """(lines to say, stop the run?) when the process ``label`` has exited.  The world's
        exit ends the run: the outputs are written (`launch.finish`, its code in ``result``).
        An agent process whose law failed (`FATAL_EXIT`) stops the run with its line, as
        `processes.run_processes` does (``run.stopped``: the world then saves the steps done).
        After a stop, only the world's exit matters (as `swarm run` waits for it)."""
        self.ended.add(label)
        if label == 'world':
            code = returncode if self.code is None else self.code
            self.code = code
            self.result = launch.finish(self.run, code, time.monotonic() - self.t0)
            return [], True
        if self.code is not None or self.result is not None:
            return [], False
        spec = self.specs[label]
        if label in self.members and returncode == FATAL_EXIT:
            notes = self.procs.env.get(EXIT_NOTES)
            line = (read_fatal_note(notes) if notes else None) or f'{label}: its law failed'
            self.run.stopped, self.code = line, 1
            return [f'swarm run: {line}; stopping the run'], True
        refused = refusal_line(spec, returncode, note_of(self.procs.env.get(EXIT_NOTES), self.pids.get(label)))
        if refused:                 # an agent that refused its parameters: as `run_processes` does
            self.run.stopped, self.code = refused, REFUSED_EXIT
            return [f'swarm run: {refused}; stopping the run'], True
        vanished = label in self.members and vanished_line(spec, returncode, self.procs.env.get(EXIT_NOTES),
                                                           self.pids.get(label))
        if vanished:                # an agent process that exited without a word (os._exit in a law)
            self.run.stopped, self.code = vanished, 1
            return [f'swarm run: {vanished}; stopping the run'], True
        if not spec.vital:
            return [exit_line(spec, returncode, self.run.events_file)], False
        self.code = 1
        return [exit_line(spec, returncode)], True

    @property
    def failed(self) -> bool:
        """The run has ended with an error (not a Ctrl-C)."""
        return self.result not in (None, 0, 130)

    def shutting_down(self) -> None:
        """The launch is shutting down (Ctrl-C, or a stop): the world saves the steps done when
        its SIGINT comes, and the run's exit code is 130 unless something else ended it.  A
        paused agent (SIGSTOP: fault injection) gets SIGCONT first, or it could not stop."""
        if self.code is None and self.result is None:
            self.code = 130
        for pid in [pid for label, pid in self.pids.items() if label not in self.ended]:
            try:
                os.kill(pid, signal.SIGCONT)
            except OSError:
                pass

    def close(self) -> None:
        """Remove the run's working directory (the parameters file, the DDS profile, the pids),
        if `prepare` made it."""
        if self._own:
            shutil.rmtree(self.workdir, ignore_errors=True)


def prepare(values: Mapping[str, str], workdir=None) -> LaunchRun:
    """The run the launch arguments ``values`` ask for, planned as `swarm run` plans it
    (`launch.validate`: the options, the scenario; the output directory made ready) and its
    files written to ``workdir`` (default: a new temporary directory, removed by
    `LaunchRun.close`); `NotStarted` says why it cannot start."""
    a = parse(values)
    run = launch.validate(a)
    if run is None:
        raise NotStarted(f'scenario:={a.scenario}: cannot be loaded (see above)')
    if run.use_server:
        raise NotStarted(f'{run.processes} processes need a Fast DDS discovery server, which only `swarm run` '
                         'starts: use `swarm run`, or fewer processes (agents_per_process:=K)')
    own = workdir is None
    work = Path(tempfile.mkdtemp(prefix='swarm_launch_')) if own else Path(workdir)
    try:
        work.mkdir(parents=True, exist_ok=True)
        procs = launch.plan_processes(run, work, notes=True)       # as `swarm run` plans them
    except BaseException:
        if own:
            shutil.rmtree(work, ignore_errors=True)
        raise
    return LaunchRun(run, procs, work, own_workdir=own)
