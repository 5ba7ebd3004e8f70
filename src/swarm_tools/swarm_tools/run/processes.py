"""The processes of a ``swarm run``: the supervisor that starts them (each dies with the
launcher: ``PR_SET_PDEATHSIG``), where their executables are, and the loop that watches them
until the world ends (agents may die: faults; a dead recorder is a warning)."""
from __future__ import annotations

import contextlib
import ctypes
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from swarm_core.files import write_atomic
from swarm_ros import protocol as P
from swarm_ros.rosutil import FATAL_EXIT, STOPPED_SUFFIX, read_fatal_note
from swarm_tools.run import dds
from swarm_tools.run.params import write_params_file

STOP_GRACE = 4.0
#: what the launcher sends its children to stop them (`Supervisor.stop`)
STOP_SIGNAL = signal.SIGTERM
#: wall seconds a process that writes the run's outputs (the world, the recorder) gets to finish
#: them after the stop signal before it is killed; on a loaded machine saving can outlast `STOP_GRACE`
SAVE_GRACE = 10.0
#: wall seconds the processes stopped last (the discovery server) outlive the others: time to
#: tell the other hosts' participants that the run's have left
LAST_LINGER = 1.0


_PR_SET_PDEATHSIG = 1
try:
    _prctl = ctypes.CDLL(None, use_errno=True).prctl      # looked up before any fork
except (OSError, AttributeError):                         # not Linux
    _prctl = None


def die_with_parent(parent_pid: int, sig=signal.SIGKILL):
    """A ``preexec_fn``: the child gets ``sig`` when the process that started it dies (Linux
    parent-death signal), and exits at once if that happened before this call."""
    def preexec():
        if _prctl is not None:
            _prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
        if os.getppid() != parent_pid:          # the launcher died between fork and prctl
            os._exit(1)
    return preexec


class Supervisor:
    """Child processes in one process group of their own; ended together, and killed by the
    kernel if the launcher dies first (`die_with_parent`)."""

    def __init__(self):
        self.procs = {}
        self.pgid = None

    def start(self, label, args, env, **kw):
        if self.pgid is not None and not self.alive():
            self.pgid = None        # every member has ended (a recorder that failed): so has the group
        kw['process_group'] = 0 if self.pgid is None else self.pgid
        kw['preexec_fn'] = die_with_parent(os.getpid())
        p = subprocess.Popen(args, env=env, **kw)
        if self.pgid is None:
            self.pgid = p.pid
        self.procs[label] = p
        return p

    def alive(self):
        return {k: p for k, p in self.procs.items() if p.poll() is None}

    def signal_all(self, sig):
        for p in self.alive().values():
            try:
                p.send_signal(sig)
            except ProcessLookupError:
                pass

    def stop(self, grace=STOP_GRACE, first=(), keep=(), keep_grace=SAVE_GRACE, last=()):
        """SIGTERM to ``first`` (e.g. the recorder, so it can finish its file) and everyone else
        but ``last``, wait ``grace`` s, SIGKILL all but ``keep`` (the processes that write the
        run's outputs), wait for those up to ``keep_grace`` s from the SIGTERM; then ``last`` (the
        discovery server, which tells the other hosts that the run's participants have left)
        after `LAST_LINGER` s, with ``grace`` s of its own; SIGKILL the process group if any
        process had to be killed.  SIGTERM, not SIGINT: every node and tool stops on either the
        same way once it runs, and a process still importing (a Ctrl-C just after the start)
        ends quietly on SIGTERM, where SIGINT would print a KeyboardInterrupt traceback."""
        self.signal_all(signal.SIGCONT)          # a frozen (SIGSTOPped) agent cannot stop
        for label in first:
            p = self.procs.get(label)
            if p is not None and p.poll() is None:
                p.send_signal(STOP_SIGNAL)
        others = lambda: {k: p for k, p in self.alive().items() if k not in last}
        for p in others().values():
            _signal(p, STOP_SIGNAL)
        start = time.monotonic()
        self._wait_for(others, start + grace)
        killed = [p for label, p in others().items() if label not in keep]
        for p in killed:
            _signal(p, signal.SIGKILL)
        if self._wait_for(others, start + max(grace, keep_grace)):
            print(f'swarm: {", ".join(sorted(others()))} did not stop within {keep_grace:g} s '
                  f'of {STOP_SIGNAL.name}; killed', file=sys.stderr, flush=True)
            killed += list(others().values())
        if self.alive():                         # ``last``: the others' departure relayed first
            time.sleep(LAST_LINGER)
            self.signal_all(signal.SIGINT)
            if self._wait_for(self.alive, time.monotonic() + grace):
                killed += list(self.alive().values())
        if killed:
            self.signal_all(signal.SIGKILL)
            if self.pgid is not None:
                try:
                    os.killpg(self.pgid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for p in self.procs.values():
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass

    @staticmethod
    def _wait_for(busy, deadline) -> bool:
        """Sleep while ``busy()`` until ``deadline``; whether it is still busy."""
        while busy() and time.monotonic() < deadline:
            time.sleep(0.05)
        return bool(busy())


def _signal(p, sig):
    try:
        p.send_signal(sig)
    except ProcessLookupError:
        pass


#: wall seconds to wait for the recorder's subscriptions before the nodes start
RECORDER_READY_TIMEOUT = 30.0


@contextlib.contextmanager
def supervised(prog: str, signals=(signal.SIGINT, signal.SIGTERM, signal.SIGHUP), first=(), keep=(),
               last=()):
    """The processes of one command (``swarm run``, ``swarm join``): yields (`Supervisor`,
    ``stopped``).  ``signals`` set a flag instead of raising in the middle of a start;
    ``stopped()`` says whether one came (printing ``PROG: SIGINT: stopping N processes``
    once).  When the block ends, also on an error, every process is stopped (``first``
    first: the recorder, so it can finish its file; ``keep``, the processes that write the
    outputs, get `SAVE_GRACE`; ``last`` after the others) and the old handlers are back, unless a
    signal came: then later ones are still only noted while the outputs are written
    (`swarm_ros.rosutil.stop_on_signals`: a dying parent's death signal repeats)."""
    sup = Supervisor()
    got, said = [], []
    old = {s: signal.signal(s, lambda signum, _frame: got.append(signum)) for s in signals}

    def stopped() -> bool:
        if got and not said:
            said.append(got[0])
            print(f'{prog}: {signal.Signals(got[0]).name}: stopping {len(sup.alive())} processes',
                  file=sys.stderr, flush=True)
        return bool(got)
    try:
        yield sup, stopped
    finally:
        sup.stop(first=first, keep=keep, last=last)
        for s, h in old.items() if not got else ():
            signal.signal(s, h)


def wait_until_ready(proc, marker: str, timeout: float) -> bool:
    """Forward ``proc``'s stderr lines to ours (on a thread, for its whole life) and wait until
    one contains ``marker`` (the recorder has subscribed to the swarm's topics, so nothing
    published from step 0 on is missed); False on timeout or if ``proc`` ends first."""
    seen, found = threading.Event(), threading.Event()

    def pump():
        for line in proc.stderr:
            sys.stderr.write(line)
            sys.stderr.flush()
            if marker in line:
                found.set()
                seen.set()
        seen.set()

    threading.Thread(target=pump, daemon=True).start()
    return seen.wait(timeout) and found.is_set() and proc.poll() is None


#: the package of each executable the launcher starts (``ros2 run PKG EXE``)
EXE_PACKAGE = {'swarm': 'swarm_tools', 'swarm_world': 'swarm_world', 'swarm_agent': 'swarm_agent',
               'swarm_agent_container': 'swarm_agent',
               'homotopy_commander': 'homotopy_commander', 'swarm_robots': 'swarm_robots'}


def _exe(name):
    """This interpreter's script (pip / venv), else ``PATH``, else where ``ros2 run`` finds it
    after ``colcon build``: ``<prefix>/lib/<pkg>/<name>``, the prefix from the ament index."""
    from ament_index_python import get_package_prefix
    here = Path(sys.executable).parent
    cand = here / name
    if cand.exists():
        return str(cand)
    found = shutil.which(name)
    if found:
        return found
    try:
        cand = Path(get_package_prefix(EXE_PACKAGE[name])) / 'lib' / EXE_PACKAGE[name] / name
        if os.access(cand, os.X_OK):
            return str(cand)
    except (ImportError, LookupError, KeyError, ValueError, OSError):
        pass
    return name


def killed_agents(events_file) -> set:
    """Agents the events file records as killed (deliberately) or lost."""
    out = set()
    try:
        lines = Path(events_file).read_text().splitlines()
    except OSError:
        return out
    for line in lines:
        try:
            ev = json.loads(line)
        except ValueError:
            continue
        if ev.get('kind') in ('kill', 'lost'):
            out.add(ev.get('agent'))
    return out


@dataclass(frozen=True)
class ProcessSpec:
    """One process of a ``--processes`` run, as `run_processes` starts it and as
    ``ros2 launch swarm_tools swarm.launch.py`` declares it (`swarm_tools.run.launch_description`):
    ``command`` is the argv, ``env`` the whole environment."""
    label: str                      # world, commander, robots, agent_0, agents[agent_0..agent_3], view
    package: str                    # the ROS package of the executable (ros2 run PACKAGE EXECUTABLE)
    executable: str                 # its name
    path: str                       # the file started (`_exe`: the venv's script, PATH, or lib/PACKAGE/)
    arguments: tuple = ()           # before --ros-args
    params_file: str | None = None  # --ros-args --params-file FILE (a ROS node process)
    name: str | None = None         # -r __node:=NAME
    namespace: str | None = None    # -r __ns:=NAMESPACE
    env: dict = field(default_factory=dict, repr=False, hash=False)     # the whole environment
    members: tuple = ()             # the agents of an agent process
    vital: bool = True              # its exit stops the run (the agents' does not: faults)

    def ros_args(self, ros=None) -> list:
        """``--ros-args --params-file FILE`` (or ``ros``) and the name and namespace remaps."""
        if ros is None:
            ros = [] if self.params_file is None else ['--ros-args', '--params-file', str(self.params_file)]
        remaps = [('__node', self.name), ('__ns', self.namespace)]
        return list(ros) + [a for k, v in remaps if v is not None for a in ('-r', f'{k}:={v}')]

    @property
    def command(self) -> list:
        return [self.path, *self.arguments] + self.ros_args()


def _node(label, exe, params_file, env, **kw) -> ProcessSpec:
    return ProcessSpec(label=label, package=EXE_PACKAGE[exe], executable=exe, path=_exe(exe),
                       params_file=None if params_file is None else str(params_file), env=env, **kw)


def agent_specs(groups, params_file=None, env=None, services=True) -> list:
    """The agent processes: ``swarm_agent`` for a group of one (label: the agent's name; node
    ``agent`` in the agent's namespace), the container ``swarm_agent_container`` for more (label:
    ``agents[a..b]``; ``services`` False: its agent nodes without services,
    `container_core.agent_services`)."""
    lean = () if services else ('--no-services',)
    env = {} if env is None else env
    out = []
    for g in groups:
        if len(g) == 1:
            out.append(_node(g[0], 'swarm_agent', params_file, env, name='agent', namespace=f'/{g[0]}',
                             members=tuple(g), vital=False))
        else:
            out.append(_node(f'agents[{g[0]}..{g[-1]}]', 'swarm_agent_container', params_file, env,
                             arguments=(*lean, *g), members=tuple(g), vital=False))
    return out


def agent_commands(groups, ros, services=True) -> list:
    """(label, agent names, command) of each agent process (`agent_specs`), with the ROS
    arguments ``ros`` (``--ros-args --params-file FILE``)."""
    return [(s.label, list(s.members), [s.path, *s.arguments] + s.ros_args(ros))
            for s in agent_specs(groups, services=services)]


def process_specs(params_file, env: dict, groups, services=True, robots=False, foxglove=None) -> list:
    """Every process of a ``--processes`` run on this host but the discovery server and the
    recorder (which `run_processes` starts first and waits for), in the order they start: the
    world, the commander (a DDS super client: it opens a command topic's reader once it sees a
    writer there, and a plain CLIENT of a discovery server hears only of topics it reads), the
    MuJoCo robot world if ``robots``, the agent processes (``groups``: the agents of each), the
    live view if ``foxglove`` is a port."""
    out = [_node('world', 'swarm_world', params_file, env, name='world'),
           _node('commander', 'homotopy_commander', params_file, dds.super_client(env), name='commander')]
    if robots:
        out.append(_node('robots', 'swarm_robots', params_file, env, name='robots'))
    out += agent_specs(groups, params_file, env, services)
    if foxglove is not None:
        out.append(ProcessSpec(label='view', package=EXE_PACKAGE['swarm'], executable='swarm', path=_exe('swarm'),
                               arguments=('view', '--port', str(foxglove)), env=env))
    return out


def write_pids(pid_file, members: dict, pids: dict, out_dir=None) -> None:
    """``pid_file``: {agent: pid of its process} (``members``: {label: agents}; ``pids``: {label:
    pid}), for the world's faults, and a copy in ``out_dir``.  Agents sharing a process share
    its pid: the world signals only a pid of one agent."""
    tmp = Path(str(pid_file) + '.tmp')
    tmp.write_text(json.dumps({nm: pids[label] for label, g in members.items() for nm in g}))
    tmp.replace(pid_file)
    if out_dir is not None:
        write_atomic(Path(out_dir) / 'pids.json', Path(pid_file).read_text())


def exit_line(spec: ProcessSpec, rc: int, events_file=None) -> str:
    """What the launcher says when the process of ``spec`` has exited with ``rc`` while the run
    goes on (not the world's end): an agent process is gone (the world drops its agents), any
    other stops the run (`ProcessSpec.vital`)."""
    if spec.vital:      # (as run_processes says it of the discovery server too)
        return f'swarm run: {spec.label} exited with code {rc}; stopping the run'
    if len(spec.members) > 1:
        return (f'swarm run: {spec.label} exited with code {rc}: its {len(spec.members)} agents are gone; the '
                'world drops them from the roster after its missing_timeout')
    if events_file and spec.label in killed_agents(events_file):
        return f'swarm run: {spec.label} killed (fault injection)'
    return (f'swarm run: {spec.label} exited with code {rc}; the world drops it from the roster '
            'after its missing_timeout')


#: the exit code of a node process that refused its parameters (`rosutil.run_node`: a bad
#: start-up parameter, one line)
REFUSED_EXIT = 2


def vanished_line(spec: ProcessSpec, rc: int, notes, pid) -> str | None:
    """The line that stops the run when the agent process of ``spec`` exited with ``rc`` on its
    own without a word: no note (`rosutil.fatal_note`), not stopped by a signal (none came, its
    note `rosutil.stopped_note` says; a process killed by one has ``rc`` < 0), e.g. a law that
    called ``os._exit``.  None for any other exit (the world drops a killed agent and goes on)."""
    if not notes or pid is None or rc < 0 or rc >= 128 or note_of(notes, pid) is not None \
            or (Path(notes) / f'{pid}{STOPPED_SUFFIX}').exists():
        return None
    return (f'{spec.label} vanished: its process exited with code {rc} without a word (a law that '
            'calls os._exit ends it so: nothing can catch that)')


def note_of(notes, pid) -> str | None:
    """The line the process ``pid`` left in the directory ``notes`` when it stopped on an error
    or refused its parameters (`rosutil.fatal_note`), or None."""
    if not notes or pid is None:
        return None
    try:
        with open(Path(notes) / f'{pid}.txt') as fh:
            return fh.read().strip() or None
    except OSError:
        return None


def refusal_line(spec: ProcessSpec, rc: int, note: str | None = None) -> str | None:
    """The line that stops the run at once when the agent process of ``spec`` has exited with
    ``rc`` because it refused its parameters (`REFUSED_EXIT`; ``note``: its own line), else None.
    Such an agent never joins, and a run cannot go on without it (lockstep waits for every agent,
    realtime's world for all of them to start): the run stops, rather than wait out the world's
    ``start_timeout``."""
    if not spec.members or rc != REFUSED_EXIT:
        return None
    return f'{spec.label} refused its parameters: {note or f"exit code {rc} (its line is above)"}'


def refused_label(procs: dict) -> str | None:
    """The label of the first process of ``procs`` (label → Popen) that exited with
    `REFUSED_EXIT` (it refused its parameters), else None."""
    return next((label for label, p in procs.items() if p.poll() == REFUSED_EXIT), None)


def without_recorder(params: dict) -> dict:
    """``params`` for a run whose recorder is gone before the start: the world and the commander
    do not wait for it, and each agent waits for one state reader fewer."""
    out = {fqn: dict(p) for fqn, p in params.items()}
    for fqn, p in out.items():
        if 'wait_for_recorder' in p:
            p['wait_for_recorder'] = False
        if fqn.endswith('/agent') and p.get('state_subscribers', 0) > 0:
            p['state_subscribers'] -= 1
    return out


def start_recorder(sup, record, env, params: dict, params_file) -> bool:
    """Start the recorder of ``--record`` and wait until it is ready; False if it ended first
    (e.g. a full disk): the parameters file is then written again so that no node waits for it."""
    # /lockstep/agent_states, /lockstep/robot_states and /swarm/agent_states hold the /swarm/states
    # again, batched per process (or robot world): not kept; nor /swarm/clock, /clock again
    roster = [p['agent_name'] for fqn, p in params.items() if fqn.endswith('/agent')]
    excluded = [P.LOCK_AGENT_STATES, P.LOCK_ROBOT_STATES, P.AGENT_STATES, P.RUN_CLOCK]
    rec = sup.start('record', [_exe('swarm'), 'record', '--out', str(record), '--exclude', *excluded]
                    + (['--agents', *roster] if roster else [])
                    + (['--dim', '3'] if any(p.get('dim') == 3 for p in params.values()) else []),
                    dds.super_client(env), stderr=subprocess.PIPE, text=True, bufsize=1)
    if wait_until_ready(rec, 'swarm record: ready', RECORDER_READY_TIMEOUT):
        return True
    with contextlib.suppress(subprocess.TimeoutExpired):
        rec.wait(timeout=2)             # (its stderr ends just before it does)
    if rec.poll() is None:
        print(f'swarm run: the recorder did not say it was ready within '
              f'{RECORDER_READY_TIMEOUT:g} s; starting the run anyway', file=sys.stderr, flush=True)
        return True
    print(f'swarm run: the recorder exited with code {rec.returncode} before the start; '
          'the run goes on without a bag', file=sys.stderr, flush=True)
    write_params_file(without_recorder(params), params_file)
    return False


def _stop_code(sup, by_label: dict, members: dict, gone: set, notes=None, events_file=None, record=None,
               stopped_by=None) -> int | None:
    """One look at the processes other than the world (`run_processes`): the exit code that stops
    the run, its line said (a law that failed, an agent that refused its parameters, any other
    vital process that exited), or None while it goes on.  Agent processes and the recorder that
    exited are said once and added to ``gone``."""
    dead = [k for k, p in sup.procs.items() if p.poll() is not None and k != 'world' and k not in gone]
    fatal = [k for k in dead if k in members and sup.procs[k].returncode == FATAL_EXIT]
    if fatal:
        line = (read_fatal_note(notes) if notes else None) or f'{fatal[0]}: its law failed'
        print(f'swarm run: {line}; stopping the run', file=sys.stderr, flush=True)
        if stopped_by is not None:
            stopped_by.append(line)
        return 1
    refused = [(k, refusal_line(by_label[k], sup.procs[k].returncode, note_of(notes, sup.procs[k].pid)))
               for k in dead if k in members and k not in gone]
    refused = [(k, line) for k, line in refused if line]
    if refused:
        line = refused[0][1]
        print(f'swarm run: {line}; stopping the run', file=sys.stderr, flush=True)
        if stopped_by is not None:
            stopped_by.append(line)
        for k, p in sup.alive().items():     # SIGTERM: a node still importing ends without a
            if k != 'record':                 # traceback (SIGINT would raise in it); the rest stop
                p.send_signal(signal.SIGTERM)
        return REFUSED_EXIT
    vanished = [line for k in dead if k in members and k not in gone
                for line in [vanished_line(by_label[k], sup.procs[k].returncode, notes, sup.procs[k].pid)] if line]
    if vanished:
        print(f'swarm run: {vanished[0]}; stopping the run', file=sys.stderr, flush=True)
        if stopped_by is not None:
            stopped_by.append(vanished[0])
        return 1
    for k in [k for k in dead if k in members]:
        gone.add(k)
        print(exit_line(by_label[k], sup.procs[k].returncode, events_file), file=sys.stderr, flush=True)
    if 'record' in dead and 'record' not in gone:
        gone.add('record')
        print(f'swarm run: WARNING: the recorder exited with code {sup.procs["record"].returncode}; '
              f'the run goes on without it (the bag {record} ends here; `swarm bag recover` '
              'repairs a truncated bag)', file=sys.stderr, flush=True)
    dead = [k for k in dead if k not in members and k != 'record']      # ... or the discovery server
    if dead:
        k = dead[0]
        note = note_of(notes, sup.procs[k].pid)
        print(f'swarm run: {k} exited with code {sup.procs[k].returncode}{f": {note}" if note else ""}; '
              'stopping the run', file=sys.stderr, flush=True)
        return 1
    return None


def world_exit(rc: int, stopped_by=None) -> int:
    """The launcher's exit code once the world process has ended with ``rc``: the world's own,
    or, for a world killed by a signal (``rc`` < 0: SIGKILL, or a crash's SIGSEGV or SIGABRT),
    128 + the signal, as a shell gives it (137 for SIGKILL), with one line naming the signal
    (appended to ``stopped_by``)."""
    if rc >= 0:
        return rc
    try:
        name = signal.Signals(-rc).name
    except ValueError:
        name = f'signal {-rc}'
    line = f'the world was killed by {name}'
    print(f'swarm run: {line}; stopping the run (exit code {128 - rc})', file=sys.stderr, flush=True)
    if stopped_by is not None:
        stopped_by.append(line)
    return 128 - rc


def run_processes(params: dict, params_file: Path, specs, env, record=None, out_dir=None,
                  pid_file=None, events_file=None, server=None, notes=None, stopped_by=None) -> int:
    """Start ``specs`` (`process_specs`: world, commander, robots, agents, view) and watch them
    until the world ends.  ``server``: a `dds.DiscoveryServer` started first, stopped with the
    rest; ``record``: the recorder, started (and waited for) before the nodes; ``env``: the
    environment of both.  An agent process that exits is not a run failure; any other process
    that exits stops the run (exit 1), and so does an agent process that exits with
    `FATAL_EXIT` (its law failed): its line (from the directory ``notes``, `rosutil.fatal_note`)
    is said once and appended to ``stopped_by``; the world then saves the steps done.  An agent
    process that refused its parameters stops the run at once (exit `REFUSED_EXIT`), with its
    line (`refusal_line`)."""
    code = 1
    gone = set()
    with supervised('swarm run', first=('record',), keep=('record', 'world'),
                    last=('discovery_server',)) as (sup, stopped):
        if server is not None:
            try:
                server.start(sup.start, env, Path(params_file).parent)
            except RuntimeError as err:
                print(f'swarm run: {err}', file=sys.stderr, flush=True)
                return 1
            print(f'swarm run: discovery server on {server.locator}; tools in another shell: '
                  f'{dds.user_line(server.address, server.port)}', flush=True)
        if record and not start_recorder(sup, record, env, params, params_file):
            gone.add('record')
        by_label = {}
        for spec in specs:
            sup.start(spec.label, spec.command, spec.env)
            by_label[spec.label] = spec
        world = sup.procs['world']
        members = {label: s.members for label, s in by_label.items() if s.members}
        if pid_file is not None:
            write_pids(pid_file, members, {label: sup.procs[label].pid for label in members}, out_dir)
        while True:
            if stopped():
                code = 130
                break
            rc = world.poll()
            if rc is not None:
                code = world_exit(rc, stopped_by)
                break
            stop = _stop_code(sup, by_label, members, gone, notes=notes, events_file=events_file, record=record,
                              stopped_by=stopped_by)
            if stop is not None:
                code = stop
                break
            time.sleep(0.05)
    return code


def read_events(path) -> list:
    """The events of a run (``events.jsonl`` as the world writes it); [] if none."""
    try:
        return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]
    except (OSError, ValueError):
        return []
