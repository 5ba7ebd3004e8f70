"""Drive a live swarm from Python: a script, a notebook or a user's own integration test.

    from swarm_tools.api import Swarm

    with Swarm.start('homotopy_global', duration=60, out='runs/try') as swarm:
        swarm.set_lambda(1.0, ramp=5)
        swarm.wait_until(lambda m: m['clusters'] >= 2, timeout=40)
    print(swarm.metrics_json()['final_clusters'])

`Swarm.start` runs ``swarm run`` (the same launcher, as a child process) and returns once the
run has announced itself and its sim time runs; leaving the ``with`` block stops it as Ctrl-C
does (SIGINT; the outputs are kept).  `Swarm.attach` joins a run that is already going.  The
commands and the observation go through one rclpy node (`swarm_tools.live.client.Client`) in a
Context of its own, spun in a background thread: two Swarm objects on two domains work in one
script, and a Jupyter kernel's loop is never blocked.  docs/python-api.md lists every call.
"""
from __future__ import annotations

import atexit
import json
import numbers
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from swarm_core.checks import MAX_TIME, Bound
from swarm_core.engine.trajectory import Trajectory
from swarm_ros import protocol as P
from swarm_ros import runinfo
from swarm_tools.live.client import Client, NoSwarm, SwarmError, TwoRuns, UnknownAgent
from swarm_tools.live.observe import Observer, States, States3D
from swarm_tools.run.processes import die_with_parent

__all__ = ['Swarm', 'States', 'States3D', 'SwarmError', 'NoSwarm', 'TwoRuns', 'UnknownAgent', 'WaitTimeout', 'run_argv']


#: the launcher's output in a started run's output directory
LOG_NAME = 'swarm_run.log'


class WaitTimeout(SwarmError, TimeoutError):
    """`Swarm.wait_until`: the predicate was not true within the timeout."""


def check_timeout(name: str, value, none=False):
    """A timeout (wall or sim seconds) given to a `Swarm` method, as a float: ValueError (an
    `InputError`) naming the argument for one that is not a finite number in [0, `MAX_TIME`]
    (NaN, ∞, negative, a bool or a string); None stays None where ``none`` allows it."""
    if value is None and none:
        return None
    return Bound(name, 0.0, MAX_TIME).check(value)


def run_argv(scenario, *, mode='lockstep', rtf=1.0, duration=None, out=None, agents_per_process=1,
             record=None, **overrides) -> list:
    """The ``swarm run`` arguments of `Swarm.start`'s keywords: ``seed=3`` → ``--seed 3``,
    ``no_figure=True`` → ``--no-figure``, False or None → left out."""
    opts = dict(mode=mode, rtf=rtf, duration=duration, out=out, agents_per_process=agents_per_process,
                record=record, **overrides)
    argv = [str(scenario)]
    for key, value in opts.items():
        flag = '--' + key.replace('_', '-')
        if value is None or value is False:
            continue
        argv += [flag] if value is True else [flag, str(value)]
    return argv


def finished_run(log, code, run):
    """The run of a ``swarm run`` that exited with ``code`` after printing ``log`` (its lines),
    if it ran to its end: ``run`` (its announcement, if heard) or the run id its first line
    names; None if it did not start or failed."""
    rid = next((ln.split()[3].rstrip(':') for ln in log if ln.startswith('swarm run: run ')), None)
    if code != 0 or rid is None or not any(ln.startswith('swarm run: done') for ln in log):
        return None
    return run if run is not None else {'run_id': rid}


class Swarm:
    """A live run: commands, observation, and (after it) its outputs.  Make one with
    `Swarm.start` or `Swarm.attach`."""

    def __init__(self, client: Client, run: dict, proc=None, out=None, log=None):
        self.client, self.run, self.proc = client, run, proc
        self.out = None if out is None else Path(out)
        self.log = [] if log is None else log       # what `swarm run` printed (started runs; `LOG_NAME`)
        self._obs = Observer(client, self)
        client.follow_clock()

    # ------------------------------------------------------------ making one
    @classmethod
    def start(cls, scenario, mode='lockstep', rtf=1.0, duration=None, out=None, agents_per_process=1,
              record=None, *, domain=None, start_timeout=180.0, echo=False, busy_wait=None,
              **overrides) -> 'Swarm':
        """Start ``swarm run SCENARIO`` with these options (``overrides``: any other ``swarm
        run`` option as a keyword, e.g. ``seed=3``, ``no_figure=True``) on ``domain`` (None:
        ROS_DOMAIN_ID); ``out`` None: a new temporary directory.  Returns once the run has
        announced itself and its sim time runs; `SwarmError` (with what ``swarm run`` said) if
        it ends or does not start within ``start_timeout`` wall s, or naming the other run if
        one is already on the domain (then nothing is started: that run's clients see nothing
        of this one; ``busy_wait``: wall s to listen for one (None: `runinfo.discovery_settle`),
        0 on a domain held for this run alone, as the pytest plugin's).  ``echo``: print its lines."""
        start_timeout = check_timeout('start_timeout', start_timeout)
        busy_wait = check_timeout('busy_wait', runinfo.discovery_settle() if busy_wait is None else busy_wait)
        domain = runinfo.check_domain(domain)
        busy = _run_on_domain(domain, busy_wait) if busy_wait > 0 else None
        if busy:
            raise SwarmError(busy)
        out = Path(out if out is not None else tempfile.mkdtemp(prefix='swarm_api_')).resolve()
        argv = run_argv(scenario, mode=mode, rtf=rtf, duration=duration, out=out,
                        agents_per_process=agents_per_process, record=record, **overrides)
        env = dict(os.environ, PYTHONUNBUFFERED='1')
        if domain is not None:
            env['ROS_DOMAIN_ID'] = str(domain)
        # its lines go to a file (a pipe would break, and the launcher with it, if this process
        # died); a session of its own (the script's Ctrl-C reaches it through `stop`), and SIGINT
        # (a stop that keeps the outputs) if this process dies; started before any thread of ours
        try:
            out.mkdir(parents=True, exist_ok=True)
            log_file = open(out / LOG_NAME, 'w')
        except OSError as err:
            raise SwarmError(f'Swarm.start: cannot write {out / LOG_NAME}: {err.strerror or err}') from None
        with log_file:
            proc = subprocess.Popen([sys.executable, '-m', 'swarm_tools.cli', 'run', *argv], env=env,
                                    start_new_session=True, preexec_fn=die_with_parent(os.getpid(), signal.SIGINT),
                                    stdout=log_file, stderr=subprocess.STDOUT)
        try:
            client = Client(domain, name='swarm_api')
        except BaseException:
            _signal_group(proc.pid, signal.SIGKILL)
            raise
        log = []
        reader = threading.Thread(target=_read_lines, args=(proc, out / LOG_NAME, log, echo), daemon=True)
        reader.start()
        swarm = cls(client, {}, proc=proc, out=out, log=log)
        swarm._reader = reader
        atexit.register(swarm.close)             # a script that never left `with` stops it too
        try:
            swarm._wait_started(start_timeout)
        except BaseException:
            swarm.close()
            raise
        return swarm

    def _wait_started(self, timeout: float):
        def started():
            rid = next((ln.split()[3].rstrip(':') for ln in self.log if ln.startswith('swarm run: run ')), None)
            run = self.client.runs.get(rid) if rid else None
            return run is not None and self.client.clock is not None, run
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            ok, run = started()
            if ok:              # the clock is this run's only if no other run is on the domain
                Client.until(self.client.watch.heard_all, min(runinfo.ANNOUNCE_WAIT, max(0.0, end - time.monotonic())))
                others = [r for rid, r in self.client.runs.items() if rid != run['run_id']]
                if others:
                    raise SwarmError(_busy_line(others, self.client.ctx.get_domain_id()))
                self.run = run
                return
            if self.proc.poll() is not None:
                self._reader.join(timeout=5.0)          # its last lines
                done = finished_run(self.log, self.proc.returncode, run)
                if done is not None:    # a short run may end before this client hears its clock
                    self.run = done
                    return
                raise SwarmError(f'swarm run ended (exit code {self.proc.returncode}) before the run started:\n'
                                 + ''.join(self.log[-30:]))
            time.sleep(0.05)
        raise SwarmError(f'the run did not start within {timeout:g} s; swarm run printed:\n' + ''.join(self.log[-30:]))

    @classmethod
    def attach(cls, domain=None, run_id=None, *, out=None, wait=10.0) -> 'Swarm':
        """Join the run going on ``domain`` (None: ROS_DOMAIN_ID): the one there, or the one of
        ``run_id``; ``out``: its output directory (for `trajectory`).  Waits up to ``wait``
        wall s for its announcement; `NoSwarm`, or `TwoRuns` when two share the domain and no
        ``run_id`` is given."""
        wait = check_timeout('wait', wait)
        client = Client(runinfo.check_domain(domain), name='swarm_api')
        try:
            Client.until(lambda: (run_id in client.runs) if run_id else client.runs, wait)
            time.sleep(0.5)                             # a second run's announcement may come just after
            runs = client.runs
            if run_id:
                run = runs.get(run_id)
                err = None if run else f'Swarm.attach: no run {run_id!r} heard (runs: {sorted(runs) or "none"})'
            else:
                run, err = runinfo.one_run(runs, 'Swarm.attach')
                err = err or (None if run else 'Swarm.attach: no run announces itself on /swarm/run; '
                              "is ROS_DOMAIN_ID the same as the run's?")
            if err:
                raise (TwoRuns if len(runs) > 1 and not run_id else NoSwarm)(err)
            return cls(client, run, out=out)
        except BaseException:
            client.close()
            raise

    @property
    def run_id(self) -> str:
        return self.run.get('run_id', '')

    @property
    def agents(self) -> list:
        return list(self.run.get('agents', []))

    # ------------------------------------------------------------ commands
    def _taken(self, match, before: tuple, what: str, timeout: float):
        """Wait (``timeout`` wall s) for an event that ``match``es, heard after the first
        ``before[0]`` and stamped at most a sim second before ``before[1]`` (`_mark`): not an
        old one a late transient-local delivery brings."""
        count, t0 = before

        def recent(ev):
            return t0 is None or not isinstance(ev.get('t'), (int, float)) or ev['t'] >= t0 - 1.0

        def seen():
            with self._obs.lock:
                return any(match(ev) and recent(ev) for ev in self._obs.events[count:])
        if not Client.until(seen, timeout):
            raise SwarmError(f'{what}: sent, but the swarm did not take it within {timeout:g} s'
                             + self._ended_note())

    def _mark(self) -> tuple:
        """(events heard, sim time) before a command is sent (for `_taken`)."""
        with self._obs.lock:
            return len(self._obs.events), self.client.clock

    def _call(self, command, *args, **kw):
        """``command`` of the client; its `NoSwarm` says so if the run has ended."""
        try:
            return command(*args, **kw)
        except NoSwarm as err:
            if self.running:
                raise
            raise NoSwarm(f'{err}{self._ended_note()}') from None

    def _ended_note(self) -> str:
        return '' if self.running else f' (the run has ended: exit code {self.proc.returncode})'

    def set_lambda(self, value: float, ramp: float = 20.0, *, wait: float = 10.0, timeout: float = 30.0) -> None:
        """Ramp λ to ``value`` over ``ramp`` sim s; returns once the commander has applied the
        set-point (its ``command`` event); without a commander, once λ is on ``/swarm/lambda``."""
        wait, timeout = check_timeout('wait', wait), check_timeout('timeout', timeout)
        before = self._mark()
        if self._call(self.client.set_lambda, value, ramp, wait, prog='Swarm.set_lambda') != 'commander':
            return                      # no commander: λ went out on /swarm/lambda as it is
        self._taken(lambda ev: ev.get('kind') == 'command' and ev.get('command') == 'lambda'
                    and ev.get('value') == float(value), before, f'Swarm.set_lambda({value:g})', timeout)

    def steer(self, agent: str, curvature, *, wait: float = 10.0, timeout: float = 30.0) -> None:
        """Make ``agent`` a leader steering the constant ``curvature`` (a 3D run: a pair
        (s_u, s_v)); returns once the commander has applied it."""
        wait, timeout = check_timeout('wait', wait), check_timeout('timeout', timeout)
        before = self._mark()
        name = self._call(self.client.steer, agent, curvature, wait, prog='Swarm.steer')
        values = [float(v) for v in ((curvature,) if isinstance(curvature, numbers.Real) else curvature)]
        want = values[0] if len(values) == 1 else values        # the event's value: s_k, or [s_u, s_v]
        self._taken(lambda ev: ev.get('kind') == 'command' and ev.get('command') == 'steer'
                    and ev.get('agent') == name and ev.get('value') == want, before,
                    f'Swarm.steer({name!r}, {", ".join(f"{v:g}" for v in values)})', timeout)

    def kill(self, agent: str, *, wait: float = 10.0, timeout: float = 30.0) -> None:
        """Kill ``agent``; returns once the world has taken it out (its ``kill`` event)."""
        wait, timeout = check_timeout('wait', wait), check_timeout('timeout', timeout)
        before = self._mark()
        name = self._call(self.client.fault, 'kill', agent, wait=wait, prog='Swarm.kill')
        self._taken(lambda ev: ev.get('kind') == 'kill' and ev.get('agent') == name, before,
                    f'Swarm.kill({name!r})', timeout)

    def pause(self, agent: str, seconds: float, *, wait: float = 10.0, timeout: float = 30.0) -> None:
        """Freeze ``agent`` for ``seconds`` sim s; returns once the world has frozen it."""
        wait, timeout = check_timeout('wait', wait), check_timeout('timeout', timeout)
        before = self._mark()
        name = self._call(self.client.fault, 'freeze', agent, seconds, wait=wait, prog='Swarm.pause')
        self._taken(lambda ev: ev.get('kind') == 'freeze' and ev.get('agent') == name, before,
                    f'Swarm.pause({name!r}, {seconds:g})', timeout)

    def partition(self, *groups, wait: float = 10.0) -> float:
        """Groups of agent names that cannot hear each other (no groups: heal); returns the sim
        time it was stamped with, once every agent's reader has acknowledged it."""
        wait = check_timeout('wait', wait)
        return self._call(self.client.partition, list(groups), wait, prog='Swarm.partition')[0]

    def drop(self, loss: float, duration=None, *, wait: float = 10.0) -> float:
        """Burst loss ``loss`` on every link for ``duration`` sim s (None: until changed)."""
        wait = check_timeout('wait', wait)
        return self._call(self.client.drop, loss, duration, wait, prog='Swarm.drop')[0]

    # ------------------------------------------------------------ observation
    def metrics(self):
        """The newest ``/world/metrics``: dict of t, lambda, clusters, polarisation,
        min_distance (None before the first)."""
        with self._obs.lock:
            return None if self._obs.metrics is None else dict(self._obs.metrics)

    def states(self):
        """The newest `States` (a 3D run: `States3D`, positions (N, 3) and frames); None
        before the first state."""
        return self._obs.snapshot(self.agents)

    def events(self) -> list:
        """Every ``/swarm/events`` event heard so far (dicts, in arrival order)."""
        with self._obs.lock:
            return [dict(ev) for ev in self._obs.events]

    @property
    def t(self):
        """Sim time of the newest ``/clock`` (None before the first)."""
        return self.client.clock

    def wait_until(self, predicate, timeout: float, *, on='metrics', wall_timeout=None):
        """Wait until ``predicate(sample)`` is true for the newest ``metrics()`` (or, with
        ``on='states'``, ``states()``) and return that sample.  ``timeout``: sim seconds from
        now (``/clock``), counted on the samples' own time, so a stream that lags the clock is
        waited for; `WaitTimeout` once a sample that late has been seen, or after
        ``wall_timeout`` wall s (default 60 + 10 × timeout) if the samples stall; `SwarmError`
        if the run ends first."""
        timeout = check_timeout('timeout', timeout)
        wall_timeout = check_timeout('wall_timeout', wall_timeout, none=True)
        if on not in ('metrics', 'states'):
            raise ValueError(f"on={on!r}: 'metrics' or 'states'")
        sample_of = {'metrics': self.metrics, 'states': self.states}[on]
        wall = 60.0 + 10.0 * timeout if wall_timeout is None else wall_timeout
        wall_end = time.monotonic() + wall
        t0 = self.t
        while True:
            sample = sample_of()
            if sample is not None and predicate(sample):
                return sample
            now = _sample_time(sample)
            if t0 is None:
                t0 = now
            if now is not None and t0 is not None and now - t0 >= timeout:
                raise WaitTimeout(f'wait_until: {_name(predicate)} not true after {timeout:g} sim s '
                                  f'(t {t0:.2f} → {now:.2f}); newest {on}: {sample}')
            if not self.running and self.proc is not None:
                raise SwarmError(f'wait_until: the run ended (exit code {self.proc.returncode}) before '
                                 f'{_name(predicate)} was true; newest {on}: {sample}')
            if time.monotonic() > wall_end:
                raise WaitTimeout(f'wait_until: {_name(predicate)} not true after {wall:g} wall s '
                                  f'(samples stalled at t = {now}, /clock at {self.t}); newest {on}: {sample}')
            time.sleep(0.05)

    # ------------------------------------------------------------ the end
    @property
    def running(self) -> bool:
        """A started run whose ``swarm run`` has not exited (attached runs: always True)."""
        return self.proc is None or self.proc.poll() is None

    def wait(self, timeout=None) -> int:
        """Wait for the run to end by itself (``timeout`` wall s, None: for ever); its exit code."""
        timeout = check_timeout('timeout', timeout, none=True)
        if self.proc is None:
            raise SwarmError('Swarm.wait: an attached run is not ours to wait for')
        return self.proc.wait(timeout=timeout)

    def stop(self, grace: float = 60.0):
        """Stop a started run as Ctrl-C does (SIGINT; the outputs are written), SIGKILL after
        ``grace`` wall s; its exit code (None for an attached run, which goes on)."""
        grace = check_timeout('grace', grace)
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            _signal_group(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                _signal_group(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
        # the launcher's session holds every process of the run: none may outlive it
        if not Client.until(lambda: not self.leftover(), 5.0):
            for pid in self.leftover():
                _kill(pid)
            Client.until(lambda: not self.leftover(), 5.0)
        return self.proc.returncode

    def leftover(self) -> list:
        """Pids of the processes of a started run still there (its launcher's session)."""
        return [] if self.proc is None else session_pids(self.proc.pid)

    def close(self):
        """Stop a started run (`stop`) and shut the client down (again: nothing)."""
        atexit.unregister(self.close)
        try:
            self.stop()
        finally:
            self.client.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _output(self, name: str) -> Path:
        if self.out is None:
            raise SwarmError(f'{name}: the output directory is not known (Swarm.attach(..., out=DIR))')
        if self.running and self.proc is not None:
            raise SwarmError(f'{name}: the run is still going; stop() or wait() first')
        path = self.out / name
        if not path.is_file():
            raise SwarmError(f'{name}: not in {self.out} (the run wrote none)')
        return path

    def trajectory(self):
        """The run's `swarm_core.engine.trajectory.Trajectory` (trajectory.npz), after the run."""
        return Trajectory.load(self._output('trajectory.npz'))

    def metrics_json(self) -> dict:
        """The run's metrics.json (its summary and series), after the run."""
        return json.loads(self._output('metrics.json').read_text())


def _busy_line(runs, domain) -> str:
    """The error of a `Swarm.start` on a domain where ``runs`` are already announced."""
    return (f'Swarm.start: another swarm run is on ROS_DOMAIN_ID={domain} ('
            + '; '.join(runinfo.describe(r) for r in runs)
            + '): refusing to start one more (give each run its own ROS_DOMAIN_ID)')


def _run_on_domain(domain, wait):
    """The error line if a run already announces itself on ``domain`` (None: ROS_DOMAIN_ID),
    else None: listens ``wait`` wall s for a ``/swarm/run`` writer or a ``/world``
    node, and then for every writer's announcement (at most `runinfo.ANNOUNCE_WAIT` s).  A
    client of its own, closed before the run starts."""
    with Client(domain, name='swarm_api_probe') as probe:
        def seen():
            return probe.node.count_publishers(P.RUN) > 0 or runinfo.has_world(probe.node)
        if Client.until(seen, wait):
            Client.until(lambda: probe.runs and probe.watch.heard_all(), runinfo.ANNOUNCE_WAIT)
        runs = list(probe.runs.values())
        return _busy_line(runs, probe.ctx.get_domain_id()) if runs else None


def _read_lines(proc, path: Path, log: list, echo: bool):
    """Follow the launcher's log file into ``log`` until it has exited and all is read."""
    with open(path, errors='replace') as f:
        part = ''
        while True:
            ended = proc.poll() is not None
            chunk = f.readline()
            if not chunk:
                if ended:
                    return
                time.sleep(0.05)
                continue
            part += chunk
            if part.endswith('\n') or ended:
                log.append(part)
                if echo:
                    print(part, end='', flush=True)
                part = ''


def _signal_group(pid: int, sig):
    try:
        os.killpg(pid, sig)
    except ProcessLookupError:
        pass


def _kill(pid: int):
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def session_pids(sid: int) -> list:
    """Pids of the live (not zombie) processes of session ``sid`` (from /proc)."""
    pids = []
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
        except (OSError, IndexError):
            continue
        if fields[0] != 'Z' and int(fields[3]) == sid:
            pids.append(int(stat.parent.name))
    return pids


def _name(predicate) -> str:
    return getattr(predicate, '__name__', None) or repr(predicate)


def _sample_time(sample):
    """The sim time a `wait_until` sample stands for: a metrics dict's ``t``, the newest row of
    a `States` (None before the first sample)."""
    if sample is None:
        return None
    if isinstance(sample, (States, States3D)):
        return float(np.max(sample.t)) if len(sample.t) else None
    return float(sample['t'])
