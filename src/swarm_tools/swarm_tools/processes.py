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
from pathlib import Path

from swarm_core.atomic import write_atomic
from swarm_ros import protocol as P

from . import dds
from .node_params import write_params_file

STOP_GRACE = 4.0


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

    def stop(self, grace=STOP_GRACE, first=()):
        """SIGINT to ``first`` (e.g. the recorder, so it can finish its file) and everyone else,
        wait, then SIGKILL the process group."""
        self.signal_all(signal.SIGCONT)          # a frozen (SIGSTOPped) agent cannot stop
        for label in first:
            p = self.procs.get(label)
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGINT)
        self.signal_all(signal.SIGINT)
        deadline = time.monotonic() + grace
        while self.alive() and time.monotonic() < deadline:
            time.sleep(0.05)
        if self.alive():
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


#: wall seconds to wait for the recorder's subscriptions before the nodes start
RECORDER_READY_TIMEOUT = 30.0


@contextlib.contextmanager
def supervised(prog: str, signals=(signal.SIGINT, signal.SIGTERM, signal.SIGHUP), first=()):
    """The processes of one command (``swarm run``, ``swarm join``): yields (`Supervisor`,
    ``stopped``).  ``signals`` set a flag instead of raising in the middle of a start;
    ``stopped()`` says whether one came (printing ``PROG: SIGINT: stopping N processes``
    once).  When the block ends, also on an error, every process is stopped (``first``
    first: the recorder, so it can finish its file) and the old handlers are back, unless a
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
        sup.stop(first=first)
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
               'homotopy_commander': 'homotopy_commander', 'swarm_robots': 'swarm_robots'}


def _exe(name):
    """This interpreter's script (pip / venv), else ``PATH``, else where ``ros2 run`` finds it
    after ``colcon build``: ``<prefix>/lib/<pkg>/<name>``, the prefix from the ament index."""
    here = Path(sys.executable).parent
    cand = here / name
    if cand.exists():
        return str(cand)
    found = shutil.which(name)
    if found:
        return found
    try:
        from ament_index_python import get_package_prefix
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


def agent_commands(groups, ros, services=True) -> list:
    """(label, agent names, command) of each agent process: ``swarm_agent`` for a group of one
    (label: the agent's name), the container ``swarm_agents`` for more (label: ``agents[a..b]``;
    ``services`` False: its agent nodes without services, `container_core.agent_services`)."""
    out = []
    lean = [] if services else ['--no-services']
    for g in groups:
        if len(g) == 1:
            out.append((g[0], g, [_exe('swarm_agent')] + ros + ['-r', '__node:=agent', '-r', f'__ns:=/{g[0]}']))
        else:
            out.append((f'agents[{g[0]}..{g[-1]}]', g, [_exe('swarm_agents'), *lean, *g] + ros))
    return out


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
    # again, batched per process (or robot world): not kept
    roster = [p['agent_name'] for fqn, p in params.items() if fqn.endswith('/agent')]
    rec = sup.start('record', [_exe('swarm'), 'record', '--out', str(record), '--exclude', P.LOCK_AGENT_STATES,
                               P.LOCK_ROBOT_STATES, P.AGENT_STATES] + (['--agents', *roster] if roster else []),
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


def run_processes(params: dict, params_file: Path, names, env, record=None, out_dir=None,
                  pid_file=None, events_file=None, foxglove=None, server=None, groups=None,
                  services=True, robots=False) -> int:
    """``names``: the agents started here (a run spread over hosts starts the others with
    ``swarm join``); ``server``: a `dds.DiscoveryServer` started first, stopped with the rest;
    ``groups``: the agents of each agent process (default: one process per agent); ``robots``:
    also the MuJoCo robot world (node ``robots``; the run stops if it dies)."""
    ros = ['--ros-args', '--params-file', str(params_file)]
    code = 1
    gone = set()
    with supervised('swarm run', first=('record',)) as (sup, stopped):
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
        world = sup.start('world', [_exe('swarm_world')] + ros + ['-r', '__node:=world'], env)
        # a super client: it opens a command topic's reader once it sees a writer there (ros2 topic
        # pub, swarm lambda), and a plain CLIENT of a discovery server hears only of topics it reads
        sup.start('commander', [_exe('homotopy_commander')] + ros + ['-r', '__node:=commander'],
                  dds.super_client(env))
        if robots:
            sup.start('robots', [_exe('swarm_robots')] + ros + ['-r', '__node:=robots'], env)
        members = {}                    # agent process label -> its agents
        for label, group, cmd in agent_commands(groups or [[nm] for nm in names], ros, services):
            sup.start(label, cmd, env)
            members[label] = group
        if foxglove is not None:        # the live view (swarm view), a process of the run
            sup.start('view', [_exe('swarm'), 'view', '--port', str(foxglove)], env)
        if pid_file is not None:
            # agents sharing a process share its pid: the world signals only a pid of one agent
            tmp = Path(str(pid_file) + '.tmp')
            tmp.write_text(json.dumps({nm: sup.procs[label].pid for label, g in members.items() for nm in g}))
            tmp.replace(pid_file)
            if out_dir is not None:
                write_atomic(Path(out_dir) / 'pids.json', Path(pid_file).read_text())
        agents = set(members)
        while True:
            if stopped():
                code = 130
                break
            rc = world.poll()
            if rc is not None:
                code = rc
                break
            dead = [k for k, p in sup.procs.items() if p.poll() is not None and k != 'world' and k not in gone]
            for k in [k for k in dead if k in agents]:
                gone.add(k)
                rc = sup.procs[k].returncode
                if len(members[k]) > 1:
                    print(f'swarm run: {k} exited with code {rc}: its {len(members[k])} agents are gone; the '
                          'world drops them from the roster after its missing_timeout', file=sys.stderr, flush=True)
                elif k in killed_agents(events_file) if events_file else ():
                    print(f'swarm run: {k} killed (fault injection)', file=sys.stderr, flush=True)
                else:
                    print(f'swarm run: {k} exited with code {rc}; the world drops it from the roster '
                          'after its missing_timeout', file=sys.stderr, flush=True)
            if 'record' in dead and 'record' not in gone:
                gone.add('record')
                print(f'swarm run: WARNING: the recorder exited with code {sup.procs["record"].returncode}; '
                      f'the run goes on without it (the bag {record} ends here; `swarm bag recover` '
                      'repairs a truncated bag)', file=sys.stderr, flush=True)
            dead = [k for k in dead if k not in agents and k != 'record']
            if dead:
                k = dead[0]
                print(f'swarm run: {k} exited with code {sup.procs[k].returncode}; stopping the run',
                      file=sys.stderr, flush=True)
                code = 1
                break
            time.sleep(0.05)
    return code


def read_events(path) -> list:
    """The events of a run (``events.jsonl`` as the world writes it); [] if none."""
    try:
        return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]
    except (OSError, ValueError):
        return []
