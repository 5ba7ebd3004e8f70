#!/usr/bin/env python3
"""The floor of a lockstep step: bare raw publish/subscribe over the lockstep topics, side by
side with ``swarm run`` itself.

For N agents with K agents per process (``--per-process 1`` or ``auto``, chosen as
``swarm run --agents-per-process auto`` chooses), each case starts what a lockstep run starts:
one world process, one commander process and ceil(N / K) agent processes, with

- the Fast DDS set-up of ``swarm run``'s processes (`swarm_tools.run.dds.environment`: the UDP
  loopback profile, or a discovery server past `dds.SIMPLE_LIMIT` processes; the commander a
  super client, as `swarm_tools.run.processes.process_specs` makes it);
- the nodes' executor (`swarm_ros.rosutil.make_executor`: the EventsExecutor) spun by
  `spin_until`, the garbage collector settled (`settle_garbage`);
- the lockstep topics with their QoS (`swarm_ros.protocol.qos_latched`, the world's reader of
  answers as deep as the world's) and their message sizes (records encoded once, with zeros:
  /lockstep/agent_states of K agents and /lockstep/step of N agents as `swarm_ros.layouts`
  declares them, /lockstep/states and /lockstep/decision of N agents as the 4-hop protocol
  declared them: `States`, `Decision`), published and read raw;

and nothing else: no law, no decoding, no checks, no /clock, no /swarm/states.  Each process
answers each message with one message, in which it writes the step number (one double; in an
answer the sender tag, the place of which does not depend on K):

- ``2-hop``: world → agents (/lockstep/step) → world (/lockstep/agent_states): the world sends
  the next step once every agent process has answered;
- ``4-hop``: ... → world → commander (/lockstep/states) → world (/lockstep/decision) → agents.

The world times ``--steps`` steps after ``--warmup`` steps; the CPU time of every process of
the case (the run time of all its threads, `cpu_seconds`) is read at the same two moments.
Then, in the same round, the real thing: ``swarm run`` lockstep of `homotopy_global` with N agents
(`bench_ros.scenario_file`) and the same ``--agents-per-process``, for warm-up + steps steps,
measured over the same window (from the world's progress line at the warm-up step to its
``finished`` line; CPU of its node processes at those two lines, the launcher apart).  Rounds
(``--repeat``) interleave the three cases, so that they share the machine's load.

Each run has its own ROS_DOMAIN_ID in 180..230 (claimed with the flock convention of the test
suite's lock directory, and none that a running process has in its environment; at most
`MAX_DOMAINS`, each used again only after it has rested `Domains.REST` s); every process a
case starts is ended when it ends, on Ctrl-C / SIGTERM or on an error (SIGINT, then SIGKILL
of its process group; the floor's processes also die with this script: ``PR_SET_PDEATHSIG``).

    .venv/bin/python scripts/bench_floor.py --agents 6 --steps 3000
    .venv/bin/python scripts/bench_floor.py --agents 1000 --per-process auto --steps 100
"""
from __future__ import annotations

import argparse
import dataclasses
import fcntl
import json
import math
import os
import re
import signal
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_ros as B

from swarm_agent.container_core import agents_per_process, split_agents
from swarm_ros import layouts as L
from swarm_ros.protocol import float64_array_header
from swarm_tools.run import dds
from swarm_tools.run.processes import Supervisor

#: ROS_DOMAIN_IDs of this benchmark (the tests use 1..100)
DOMAINS = range(180, 231)
KINDS = ('2-hop', '4-hop', 'swarm run')
#: ROS_DOMAIN_IDs claimed at most (`Domains` reuses them in turn)
MAX_DOMAINS = 18
#: the world gives up when a step has not completed after this many wall s
STALL_LIMIT = 60.0
#: wall s the floor's processes get to stop after SIGINT before SIGKILL
GRACE = 3.0


# ------------------------------------------------------------------ the floor's processes

#: the 4-hop relay's topics and records: /lockstep/states (the world's table of step n for the
#: commander) and /lockstep/decision (the commander's answer), as the 4-hop protocol declared
#: them in `swarm_ros.layouts`; kept here so that the 4-hop floor stays measurable once a run
#: has fewer hops
STATES_TOPIC, DECISION_TOPIC = '/lockstep/states', '/lockstep/decision'


@L.declare(STATES_TOPIC, L.Field('n', kind='whole'), L.Field('t'), L.Field('N', kind='count'), L.Field('x', 'N'),
           L.Field('y', 'N'), L.Field('qz', 'N'), L.Field('qw', 'N'), L.Field('alive', 'N', 'flag'))
@dataclasses.dataclass(eq=False)
class States(L.Packed):
    n: int
    t: float
    x: Any
    y: Any
    qz: Any
    qw: Any
    alive: Any


@L.declare(DECISION_TOPIC, L.Field('n', kind='whole'), L.Field('t'), L.Field('N', kind='count'), L.Field('lam'),
           L.Field('flags', 'N', 'flag'), L.Field('steering', 'N'), L.Field('slots', 'N', 'int'),
           L.Field('rendezvous', 7, 'rendezvous'))
@dataclasses.dataclass(eq=False)
class Decision(L.Packed):
    n: int
    t: float
    lam: float
    flags: Any
    steering: Any
    slots: Any
    rendezvous: Any


def dummy(cls, counts: dict):
    """A record of ``cls`` (a `swarm_ros.layouts` message) for the count values ``counts``
    ({count name: value}), every value zero (no point, no barrier, no rendezvous)."""
    values = {}
    for f in cls.LAYOUT.fields:
        if f.kind == 'count':
            continue
        shape = f.shape(counts)
        if f.kind in ('point', 'points', 'rendezvous'):
            values[f.name] = None
        elif not shape:
            values[f.name] = False if f.kind == 'flag' else 0
        else:
            values[f.name] = np.zeros(shape, bool if f.kind == 'flag' else float)
    return cls(**values)


def records(n: int, k: int, run_id: str) -> dict:
    """{name: (serialized record, byte offset of its step number)} of the messages of a step of
    N agents, for an agent process of k agents: its answer on /lockstep/agent_states (the step
    number in its ``tag``: at one place whatever k, so that the world reads every answer alike),
    the step on /lockstep/step (both as `swarm_ros.layouts` declares them now), the table on
    /lockstep/states and the decision on /lockstep/decision (`States`, `Decision`)."""
    counts = dict(K=k, N=n, M=0)
    out = {}
    for name, cls, field in (('answer', L.AgentStates, 'tag'), ('step', L.Step, 'n'),
                             ('states', States, 'n'), ('decision', Decision, 'n')):
        raw = dummy(cls, counts).to_cdr(run_id)
        plan = cls.LAYOUT.plan(tuple(counts[c] for c in cls.LAYOUT.counts))
        head = len(float64_array_header(plan.dtype.itemsize // 8))
        start = next(a for f, a, _, _ in plan.slots if f.name == field)
        assert len(raw) == head + plan.dtype.itemsize, name
        out[name] = (raw, head + 8 * start)
    return out


class Relay:
    """A message that goes out again and again with a new step number (one double)."""

    def __init__(self, pub, raw: bytes, at: int):
        self.pub, self.buf, self.at = pub, bytearray(raw), at

    def send(self, n):
        struct.pack_into('<d', self.buf, self.at, n)
        self.pub.publish(bytes(self.buf))


def step_of(raw, at: int) -> float:
    return struct.unpack_from('<d', raw, at)[0]


def child_main(argv) -> int:
    """One process of the floor: ``child world|commander|agents`` with the case's sizes."""
    ap = argparse.ArgumentParser(prog='bench_floor.py child')
    ap.add_argument('role', choices=('world', 'commander', 'agents'))
    ap.add_argument('--n', type=int, required=True)
    ap.add_argument('--k', type=int, default=1)
    ap.add_argument('--first', type=int, default=0)
    ap.add_argument('--procs', type=int, default=1)
    ap.add_argument('--hops', type=int, choices=(2, 4), default=2)
    ap.add_argument('--warmup', type=int, default=0)
    ap.add_argument('--steps', type=int, default=0)
    ap.add_argument('--run-id', default='floor')
    ap.add_argument('--start-timeout', type=float, default=180.0)
    a = ap.parse_args(argv)

    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import Float64MultiArray

    from swarm_ros import protocol as P
    from swarm_ros.rosutil import make_executor, settle_garbage, spin_until, steady_clock, stop_on_signals

    stop, wake, _ = stop_on_signals()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    ctx = rclpy.get_default_context()
    name = f'floor_agents_{a.first}' if a.role == 'agents' else f'floor_{a.role}'
    node = rclpy.create_node(name, context=ctx)
    rec = records(a.n, a.k, a.run_id)
    F = Float64MultiArray
    state = dict(done=False, code=0)

    if a.role == 'agents':
        step_at = rec['step'][1]
        answer = Relay(node.create_publisher(F, P.LOCK_AGENT_STATES, P.qos_latched()), *rec['answer'])
        node.create_subscription(F, P.LOCK_STEP, lambda raw: answer.send(step_of(raw, step_at)),
                                 P.qos_latched(), raw=True)
    elif a.role == 'commander':
        states_at = rec['states'][1]
        decision = Relay(node.create_publisher(F, DECISION_TOPIC, P.qos_latched()), *rec['decision'])
        node.create_subscription(F, STATES_TOPIC, lambda raw: decision.send(step_of(raw, states_at)),
                                 P.qos_latched(), raw=True)
    else:
        world = FloorWorld(node, a, rec, state)
        node.create_timer(0.05, world.tick, clock=steady_clock())
    ex = make_executor(ctx)
    ex.add_node(node)
    settle_garbage()
    spin_until(ex, ctx, lambda: bool(stop) or state['done'], wake=wake)
    sys.stdout.flush()
    node.destroy_node()
    rclpy.try_shutdown()
    return state['code']


class FloorWorld:
    """The floor's world: starts once every reader and writer has matched, sends step 0, then
    the next step once every agent process has answered (2 hops) or once the commander has
    answered the table of the step (4 hops); says ``floor: mark 0|1 <monotonic s>`` at the
    first measured step and after the last."""

    def __init__(self, node, a, rec, state):
        from std_msgs.msg import Float64MultiArray as F

        from swarm_ros import protocol as P
        self.node, self.a, self.state = node, a, state
        self.answer_at, self.decision_at = rec['answer'][1], rec['decision'][1]
        self.sub_answers = node.create_subscription(F, P.LOCK_AGENT_STATES, self.on_answer,
                                                    P.qos_latched(max(100, 4 * a.n)), raw=True)
        self.states = Relay(node.create_publisher(F, STATES_TOPIC, P.qos_latched()), *rec['states'])
        self.step = Relay(node.create_publisher(F, P.LOCK_STEP, P.qos_latched()), *rec['step'])
        self.sub_decision = node.create_subscription(F, DECISION_TOPIC, self.on_decision, P.qos_latched(), raw=True)
        self.n, self.got, self.started = -1, 0, False
        self.t0 = time.monotonic()
        self.last = (self.n, self.t0)
        self.end = a.warmup + a.steps

    def say(self, text):
        print(f'floor: {text}', flush=True)

    def give_up(self, why):
        self.say(f'error: {why}')
        self.state.update(done=True, code=1)

    def tick(self):
        now = time.monotonic()
        if self.state['done']:
            return
        if not self.started:
            a = self.a
            matched = (self.step.pub.get_subscription_count() >= a.procs
                       and self.sub_answers.get_publisher_count() >= a.procs)
            if a.hops == 4:
                matched = (matched and self.states.pub.get_subscription_count() >= 1
                           and self.sub_decision.get_publisher_count() >= 1)
            if matched:
                self.started = True
                self.say(f'started after {now - self.t0:.2f} s')
                self.last = (0, now)
                self.next(0)
            elif now - self.t0 > a.start_timeout:
                self.give_up(f'not matched after {a.start_timeout:g} s: step readers '
                             f'{self.step.pub.get_subscription_count()}/{a.procs}, answer writers '
                             f'{self.sub_answers.get_publisher_count()}/{a.procs}')
            return
        if self.last[0] != self.n:
            self.last = (self.n, now)
        elif now - self.last[1] > STALL_LIMIT:
            self.give_up(f'step {self.n} not complete after {STALL_LIMIT:g} s ({self.got}/{self.a.procs} answers)')

    def next(self, m):
        """Step m: to the agents (2 hops), or its table to the commander (4 hops: the step goes
        out with the decision)."""
        self.n = m
        (self.step if self.a.hops == 2 else self.states).send(m)

    def on_answer(self, raw):
        if step_of(raw, self.answer_at) != self.n:
            return                          # a sample of an earlier step (transient local)
        self.got += 1
        if self.got < self.a.procs:
            return
        self.got = 0
        m = self.n + 1
        if m == self.a.warmup:
            self.say(f'mark 0 {time.monotonic():.6f}')
        elif m == self.end:
            self.say(f'mark 1 {time.monotonic():.6f}')
            self.state['done'] = True
            return
        self.next(m)

    def on_decision(self, raw):
        n = step_of(raw, self.decision_at)
        if n == self.n:
            self.step.send(n)


# ------------------------------------------------------------------ the parent

def domains_in_use() -> set:
    """The ROS_DOMAIN_IDs in the environments of the processes running now (those we may read)."""
    out = set()
    for d in os.listdir('/proc'):
        if d.isdigit():
            try:
                env = Path(f'/proc/{d}/environ').read_bytes()
            except OSError:
                continue
            m = re.search(rb'(?:^|\0)ROS_DOMAIN_ID=(\d+)(?:\0|$)', env)
            if m:
                out.add(int(m.group(1)))
    return out


def claim_domains(count: int) -> list:
    """Up to ``count`` (ROS_DOMAIN_ID, open lock file) in `DOMAINS` that no other holder of the
    lock directory has and no running process has in its environment (at least one)."""
    B.LOCK_DIR.mkdir(parents=True, exist_ok=True)
    out, busy = [], domains_in_use()
    for dom in DOMAINS:
        if len(out) == count:
            break
        if dom in busy:
            continue
        f = open(B.LOCK_DIR / f'{dom}.lock', 'a')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            out.append((dom, f))
        except OSError:
            f.close()
    if not out:
        raise SystemExit(f'bench_floor: no free ROS_DOMAIN_ID in {DOMAINS.start}..{DOMAINS.stop - 1}')
    return out


class Domains:
    """Each run its own ROS_DOMAIN_ID: the one used longest ago, after it has rested `REST` s
    (a killed process's DDS participant lingers until its lease ends, and a world that hears
    another /world node on its domain refuses to start)."""

    REST = 30.0

    def __init__(self, ids):
        self.last = {d: -math.inf for d in ids}

    def take(self) -> int:
        dom = min(self.last, key=self.last.get)
        wait = self.last[dom] + self.REST - time.monotonic()
        if wait > 0:
            print(f'    (domain {dom} rests {wait:.0f} s more)', flush=True)
            time.sleep(wait)
        return dom

    def done(self, dom):
        self.last[dom] = time.monotonic()


def base_env(domain: int) -> dict:
    """This environment with the case's domain, without a DDS set-up of its own (the launcher's
    and `dds.environment` choose, as for ``swarm run``)."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED='1')
    for k in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS', 'FASTRTPS_DEFAULT_PROFILES_FILE',
              'FASTDDS_DEFAULT_PROFILES_FILE', 'ROS_DISCOVERY_SERVER', 'ROS_SUPER_CLIENT'):
        env.pop(k, None)
    return env


def cpu_seconds(pid: int):
    """CPU s of a process, to the ns: the run time of each of its threads (/proc/PID/task/*/schedstat;
    /proc/PID/stat counts in clock ticks of 10 ms, too coarse for a window of a few hundred ms over
    a dozen processes); None if it is gone.  (A thread that ends between two readings takes its time
    with it: the nodes' threads live as long as their process.)"""
    total = 0
    try:
        tasks = os.listdir(f'/proc/{pid}/task')
    except OSError:
        return None
    for tid in tasks:
        try:
            with open(f'/proc/{pid}/task/{tid}/schedstat') as f:
                total += int(f.read().split()[0])
        except (OSError, ValueError, IndexError):
            continue
    return total / 1e9


def cpu_by_pid(pids) -> dict:
    return {pid: cpu_seconds(pid) for pid in pids}


def delta_by_role(c0: dict, c1: dict, roles: dict) -> dict:
    """CPU s between two snapshots ({pid: s}), summed by role (``roles``: {pid: role})."""
    out = {}
    for pid, a in c0.items():
        b = c1.get(pid)
        if a is not None and b is not None:
            out[roles[pid]] = out.get(roles[pid], 0.0) + b - a
    return out


def per_step(cpu: dict, steps: int) -> dict:
    """CPU ms per step by role and in total (the roles of the nodes: not the launcher)."""
    out = {r: round(1000 * v / steps, 3) for r, v in sorted(cpu.items())}
    out['total'] = round(sum(v for r, v in out.items() if r != 'launcher'), 3)
    return out


class FloorRun:
    """One floor case: its processes under a `Supervisor`, the world's lines read, CPU read at
    its marks; `end` stops them all."""

    current = None

    def __init__(self, n, k, hops, warmup, steps, domain, timeout, workdir: Path):
        self.n, self.k, self.hops, self.warmup, self.steps = n, k, hops, warmup, steps
        self.domain, self.timeout, self.workdir = domain, timeout, workdir
        self.sup = Supervisor()
        self.lines, self.marks, self.roles = [], {}, {}

    def end(self):
        self.sup.stop(grace=GRACE)

    def _read(self, proc):
        for line in proc.stdout:
            now = time.monotonic()
            self.lines.append(line)
            m = re.match(r'floor: mark (\d) ([0-9.]+)', line)
            if m:
                self.marks[int(m.group(1))] = (float(m.group(2)), now, cpu_by_pid(self.roles))
            elif line.startswith('floor: '):
                print('      ' + line.rstrip(), flush=True)

    def go(self) -> dict:
        FloorRun.current = self
        try:
            return self._go()
        finally:
            self.end()
            FloorRun.current = None

    def _go(self) -> dict:
        groups = split_agents([f'agent_{i}' for i in range(self.n)], self.k)
        n_proc = len(groups) + 2
        use_server = n_proc > dds.SIMPLE_LIMIT                  # as `swarm run --discovery auto`
        base = base_env(self.domain)
        server = dds.DiscoveryServer() if use_server else None
        env = dds.environment(n_proc, self.workdir, base=base, server=server.locator if server else None)
        me = [sys.executable, str(Path(__file__).resolve()), 'child']
        size = ['--n', str(self.n), '--hops', str(self.hops), '--warmup', str(self.warmup),
                '--steps', str(self.steps), '--run-id', f'floor{self.domain}']
        t0 = time.monotonic()
        if server is not None:
            proc = server.start(self.sup.start, base, self.workdir)
            self.roles[proc.pid] = 'discovery server'
        world = self.sup.start('world', me + ['world', '--procs', str(len(groups))] + size, env,
                               stdout=subprocess.PIPE, text=True, bufsize=1)
        self.roles[world.pid] = 'world'
        reader = threading.Thread(target=self._read, args=(world,), daemon=True)
        reader.start()
        p = self.sup.start('commander', me + ['commander'] + size, dds.super_client(env))
        self.roles[p.pid] = 'commander'
        first = 0
        for i, g in enumerate(groups):
            p = self.sup.start(f'agents{i}', me + ['agents', '--k', str(len(g)), '--first', str(first)] + size, env)
            self.roles[p.pid] = 'agents'
            first += len(g)
        out = dict(processes=n_proc, discovery='server' if use_server else 'simple')
        code = None
        while time.monotonic() - t0 < self.timeout:
            code = world.poll()
            if code is not None:
                break
            dead = [k for k, q in self.sup.procs.items() if q.poll() is not None and k != 'world']
            if dead:
                out['error'] = f'{dead[0]} exited with code {self.sup.procs[dead[0]].returncode}'
                break
            time.sleep(0.1)
        else:
            out['error'] = f'timed out after {self.timeout:g} s'
        reader.join(timeout=5)
        out['exit_code'] = code
        out['wall_s'] = round(time.monotonic() - t0, 2)
        for ln in self.lines:
            m = re.match(r'floor: started after ([0-9.]+) s', ln)
            if m:
                out['start_s'] = float(m.group(1))
            if ln.startswith('floor: error'):
                out['error'] = ln[len('floor: error: '):].strip()
        if code == 0 and 0 in self.marks and 1 in self.marks:
            (w0, _, c0), (w1, _, c1) = self.marks[0], self.marks[1]
            out.update(steps=self.steps, window_s=round(w1 - w0, 3), steps_per_s=round(self.steps / (w1 - w0), 1),
                       cpu_ms_per_step=per_step(delta_by_role(c0, c1, self.roles), self.steps))
        return out


class RealRun(B.Run):
    """``swarm run`` as bench_ros runs it (`bench_ros.Run`), measured over a window: from the
    world's first progress line at or past step ``warm`` to its ``finished`` line; the CPU of
    the run's processes (found at the world's discovery line) read at those two lines instead of
    bench_ros's sampling every 0.1 s."""

    def __init__(self, args, env, timeout, warm: int, dt: float):
        super().__init__(args, env, timeout)
        self.warm, self.dt = warm, dt
        self.roles, self.marks = {}, []

    def _read(self):
        for line in self.proc.stdout:
            now = time.monotonic()
            self.lines.append(line)
            if 'discovered in' in line and self.t_discovered is None:
                self.t_discovered = now
                self.roles = {pid: B.role(pid) for pid in B.session_pids(self.proc.pid)}
            m = re.search(r'\[world\] t=\s*([0-9.]+)\s', line)
            if m and not self.marks and round(float(m.group(1)) / self.dt) >= self.warm:
                self.marks.append((round(float(m.group(1)) / self.dt), now, cpu_by_pid(self.roles)))
            m = re.search(r'\[world\] finished t=\S+ \((\d+) steps\)', line)
            if m and self.t_finished is None:
                self.t_finished = now
                self.marks.append((int(m.group(1)), now, cpu_by_pid(self.roles)))
            if '[world]' in line or 'swarm run:' in line:
                print('      ' + line.rstrip(), flush=True)

    def _sample(self):
        """No sampling thread: the window's two readings instead."""

    def window(self) -> dict:
        if len(self.marks) < 2:
            return {}
        (k0, t0, c0), (k1, t1, c1) = self.marks[:2]
        if k1 <= k0 or t1 <= t0:
            return {}
        roles = {pid: 'agents' if r in ('agent', 'container') else r for pid, r in self.roles.items()}
        return dict(steps=k1 - k0, window_s=round(t1 - t0, 3), steps_per_s=round((k1 - k0) / (t1 - t0), 1),
                    cpu_ms_per_step=per_step(delta_by_role(c0, c1, roles), k1 - k0))


def real_run(n, k, warmup, steps, domain, timeout, tmp: Path) -> dict:
    scn = B.scenario_file(n, warmup + steps, tmp)
    dt = float(yaml.safe_load(scn.read_text())['dt'])
    args = [B.DEFAULT_SWARM, 'run', str(scn), '--no-figure', '--out', str(tmp / f'run-{n}-{k}-{domain}'),
            '--progress-every', repr(warmup * dt), '--agents-per-process', str(k)]
    run = RealRun(args, base_env(domain), timeout, warmup, dt)
    whole = run.go()
    out = dict(exit_code=whole['exit_code'], start_s=whole.get('start_s'), discovery_s=whole.get('discovery_s'),
               run_steps_per_s=whole.get('steps_per_s'), stalls=whole.get('stalls'), command=' '.join(args[1:]))
    if whole['exit_code'] == 0:
        out.update(run.window())
    else:
        said = [ln.strip() for ln in run.lines if re.search(r'error|refusing|timed out|stopping', ln, re.I)]
        out['error'] = said[0] if said else 'failed'
    return out


def on_signal(signum, frame):
    print(f'\nbench_floor: {signal.Signals(signum).name}: stopping the current case', file=sys.stderr, flush=True)
    for run in (FloorRun.current, B.Run.current):
        if run is not None:
            run.end()
    raise SystemExit(130)


def configs(agents, per, cores, max_processes):
    """[(N, K)] to measure (duplicates gone) and lines on those skipped."""
    out, said = [], []
    for n in agents:
        for p in per:
            k = agents_per_process(n, cores) if p == 'auto' else int(p)
            if math.ceil(n / k) + 2 > max_processes:
                said.append(f'{n} agents, {k} per process: {math.ceil(n / k) + 2} processes, more than '
                            f'--max-processes {max_processes}; skipped')
            elif (n, k) not in out:
                out.append((n, k))
    return out, said


def ratio(a, b):
    """a / b to 3 significant digits (None if either is missing)."""
    return float(f'{a / b:.3g}') if a and b else None


def add_ratios(results):
    """On each swarm run row: its steps/s and CPU per step over those of the floors of the same
    round and size."""
    rows = results['runs']
    for r in rows:
        if r['case'] != 'swarm run':
            continue
        for hops in ('2-hop', '4-hop'):
            f = next((x for x in rows if x['case'] == hops and x['repeat'] == r['repeat']
                      and x['agents'] == r['agents'] and x['per_process'] == r['per_process']), None)
            if f is None:
                continue
            r[f'rate_over_{hops}'] = ratio(r.get('steps_per_s'), f.get('steps_per_s'))
            r[f'cpu_over_{hops}'] = ratio(r.get('cpu_ms_per_step', {}).get('total'),
                                          f.get('cpu_ms_per_step', {}).get('total'))


def table(results) -> str:
    head = ('| agents | per process | case | steps/s | CPU ms/step | agents / world / commander '
            '| swarm run ÷ 2-hop (steps/s, CPU) | swarm run ÷ 4-hop (steps/s, CPU) |')
    rows = [head, '|---|---|---|---|---|---|---|---|']
    for r in results['runs']:
        cpu = r.get('cpu_ms_per_step', {})
        c = lambda key, cpu=cpu: '—' if cpu.get(key) is None else f'{cpu[key]:.3f}'
        sps = r.get('steps_per_s') or f"failed ({str(r.get('error') or r.get('exit_code'))[:80]})"
        rr = lambda h, r=r: (f"{r.get(f'rate_over_{h}')}, ×{r.get(f'cpu_over_{h}')}"
                             if r['case'] == 'swarm run' and f'rate_over_{h}' in r else '')
        rows.append(f"| {r['agents']} | {r['per_process']} | {r['case']} | {sps} | {c('total')} | "
                    f"{c('agents')} / {c('world')} / {c('commander')} | {rr('2-hop')} | {rr('4-hop')} |")
    if len({r['repeat'] for r in results['runs']}) > 1:
        rows.append('')
        for key in sorted({(r['agents'], r['per_process']) for r in results['runs']}):
            for h in ('2-hop', '4-hop'):
                v = [r.get(f'rate_over_{h}') for r in results['runs'] if r['case'] == 'swarm run'
                     and (r['agents'], r['per_process']) == key and r.get(f'rate_over_{h}')]
                u = [r.get(f'cpu_over_{h}') for r in results['runs'] if r['case'] == 'swarm run'
                     and (r['agents'], r['per_process']) == key and r.get(f'cpu_over_{h}')]
                if v and u:
                    rows.append(f'median, {key[0]} agents, {key[1]} per process: swarm run ÷ {h} floor: '
                                f'steps/s {statistics.median(v):.3g}, CPU ×{statistics.median(u):.3g} '
                                f'({len(v)} rounds)')
    return '\n'.join(rows)


def parse_list(text, what, allowed=None):
    items = [v.strip() for v in text.split(',') if v.strip()]
    for v in items:
        if not (v.isdigit() and int(v) >= 1) and v not in (allowed or ()):
            raise ValueError(f'{what} {text!r}: {v!r} is not a whole number ≥ 1' + (
                f' or {", ".join(allowed)}' if allowed else ''))
    return items


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ['child']:
        return child_main(argv[1:])
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0], epilog=__doc__.split('\n\n', 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--agents', default='6,1000', help='agent counts, comma-separated (default 6,1000)')
    ap.add_argument('--per-process', default='1,auto', help="agents per process, comma-separated: numbers or auto "
                    "(as swarm run --agents-per-process; default 1,auto: one case where both are one)")
    ap.add_argument('--steps', type=int, help='measured steps per case (default by agent count, as bench_ros: '
                    '4000 for 6 agents, 150 for 1000)')
    ap.add_argument('--warmup', type=int, help='steps before the measured ones (default steps / 5, at least 20)')
    ap.add_argument('--repeat', type=int, default=1, help='rounds of the interleaved cases (default 1)')
    ap.add_argument('--max-processes', type=int, default=dds.SIMPLE_LIMIT,
                    help=f'skip a case of more processes than this (default {dds.SIMPLE_LIMIT})')
    ap.add_argument('--timeout', type=float, default=900.0, help='give up on one case after this many s (default 900)')
    ap.add_argument('--out', default='bench/floor.json', help='results JSON (default bench/floor.json)')
    a = ap.parse_args(argv)
    try:
        agents = [int(v) for v in parse_list(a.agents, '--agents')]
        per = parse_list(a.per_process, '--per-process', ('auto',))
    except ValueError as err:
        ap.error(str(err))
    for opt, v, lo in (('--steps', a.steps, 1), ('--warmup', a.warmup, 1), ('--repeat', a.repeat, 1)):
        if v is not None and v < lo:
            ap.error(f'{opt} {v}: must be ≥ {lo}')
    cases, skipped = configs(agents, per, os.cpu_count(), a.max_processes)
    for line in skipped:
        print(f'bench_floor: {line}', flush=True)
    if not cases:
        ap.error('nothing to measure')
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, on_signal)
    locks = claim_domains(min(MAX_DOMAINS, len(cases) * len(KINDS) * a.repeat))
    domains = Domains([d for d, _ in locks])
    results = dict(command=' '.join([Path(sys.argv[0]).name] + argv),
                   date=time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()), cpus=os.cpu_count(),
                   load_start=B.loadavg(), runs=[])
    out_path = Path(a.out)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    print(f'bench_floor: {len(cases)} sizes x {len(KINDS)} cases x {a.repeat} rounds; load {B.loadavg()}', flush=True)
    try:
        with tempfile.TemporaryDirectory(prefix='bench_floor_') as tmp:
            tmp = Path(tmp)
            for rep in range(a.repeat):
                for n, k in cases:
                    steps = a.steps or B.DEFAULT_STEPS.get(n, max(150, 24000 // n))
                    warm = a.warmup or max(20, steps // 5)
                    for kind in KINDS:
                        dom = domains.take()
                        load0 = B.loadavg()
                        print(f'  {kind}: {n} agents, {k} per process, {warm}+{steps} steps, domain {dom} '
                              f'(round {rep + 1}/{a.repeat}); load {load0}', flush=True)
                        try:
                            if kind == 'swarm run':
                                r = real_run(n, k, warm, steps, dom, a.timeout, tmp)
                            else:
                                work = tmp / f'floor-{n}-{k}-{kind}-{rep}'
                                work.mkdir()
                                r = FloorRun(n, k, int(kind[0]), warm, steps, dom, a.timeout, work).go()
                        except (RuntimeError, OSError, ValueError) as err:
                            r = dict(exit_code=None, error=str(err))
                        domains.done(dom)
                        r.update(case=kind, agents=n, per_process=k, warmup=warm, repeat=rep, domain=dom,
                                 load_before=load0, load_after=B.loadavg())
                        results['runs'].append(r)
                        print(f"    -> {r.get('steps_per_s', '—')} steps/s, CPU ms/step "
                              f"{r.get('cpu_ms_per_step', {})}" + (f", error: {r['error']}" if 'error' in r else ''),
                              flush=True)
                        add_ratios(results)
                        out_path.write_text(json.dumps(results, indent=1))
    finally:
        results['load_end'] = B.loadavg()
        add_ratios(results)
        out_path.write_text(json.dumps(results, indent=1))
        for _, f in locks:
            f.close()
    print(table(results))
    print(f'bench_floor: wrote {out_path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
