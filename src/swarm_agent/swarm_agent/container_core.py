"""The lockstep decisions of the agents that share one process (an agent container), without ROS.

A container holds K agents (`AgentCore`s). Per ``/lockstep/step`` message it decides, for
each agent, what the agent does (`ContainerCore.on_step`), and it computes the controls of
all agents that move with ONE call of the core law `swarm_control` for those K receivers.
`swarm_control` sums each receiver's row on its own, so the K controls are bit for bit the
ones K single agents (and the batch engine) compute. A lone agent process is a container of
one (`AgentNode` uses this class too), so both paths share every rule.

Rules per agent and step message ``s`` (as an agent process has always followed them):
- a repeat of the step before (the world's stall recovery): say the answer again;
- not in the table (``s.alive``: killed or frozen): neither move nor speak;
- back in the table after a freeze: jump to the step;
- any other step than the one the agent holds: reject;
- otherwise move: u from the law (with a radio model: from the agent's own beliefs, one law
  call per agent), one ZOH step (batched over the agents), the agent's own noise.  An agent on
  a MuJoCo robot in lockstep (``reported``) takes its pose from its row of the table first and
  does not integrate: its robot moves, and the robot world reports where to.

`agents_per_process` is the rule behind ``swarm run --agents-per-process auto``, and
`agent_services` the one behind ``--agent-services auto``.
"""
from __future__ import annotations

import math

import numpy as np

from swarm_agent.agent_core import Seen, received_table
from swarm_core.laws import LawError, failed_at
from swarm_core.model.frenet import frame_from_quaternion, quaternion_from_heading
from swarm_core.model.integrate import zoh_step
from swarm_core.step import alive_control

#: ``auto``: one process per agent while there are at most this many agents per core
PROCESSES_PER_CORE = 3
#: ``auto``: agents per container at most (each container reads the O(n) step relay per step)
CONTAINER_SIZE = 100


def agents_per_process(n: int, cores: int | None = None) -> int:
    """K for ``--agents-per-process auto``.

    Measured (BENCHMARKS.md): a container costs less CPU per step than one process per agent
    at every n from 6 on (6 agents: 1.8-3.5 ms against 8.4 ms per step), so processes are kept
    only for a small swarm (n ≤ PROCESSES_PER_CORE per core: each agent a process of its own,
    faults by signal).  Larger swarms get at least one container per core, of at most
    CONTAINER_SIZE agents."""
    n = int(n)
    cores = max(1, int(cores or 1))
    if n <= PROCESSES_PER_CORE * cores:
        return 1
    containers = max(cores, -(-n // CONTAINER_SIZE))
    return max(1, -(-n // containers))


#: ``--agent-services auto``: contained agent nodes keep their services in runs up to this size
SERVICES_UP_TO = 100


def agent_services(n: int, k: int, choice: str = 'auto') -> bool:
    """Do contained agent nodes get their parameter services, type-description service and
    /rosout writer (``swarm run --agent-services``)?  ``auto``: yes up to SERVICES_UP_TO agents
    in the run.  They are 15 of an agent node's 17 DDS endpoints; without them a 1,000-agent run
    discovers and starts several times faster and holds a fraction of the memory (BENCHMARKS.md).
    A lone agent (k = 1) always keeps them."""
    if k <= 1 or choice == 'on':
        return True
    if choice == 'off':
        return False
    return int(n) <= SERVICES_UP_TO


def split_agents(names, k: int) -> list[list]:
    """The agents (in index order) in groups of at most ``k``: one group per process."""
    k = max(1, int(k))
    names = list(names)
    return [names[i:i + k] for i in range(0, len(names), k)]


class ContainerCore:
    """Lockstep of K agents in one process; see the module docstring."""

    def __init__(self, cores):
        self.cores = list(cores)
        if not self.cores:
            raise ValueError('a container needs at least one agent')
        self.n = self.cores[0].n
        self.rows = np.array([c.index for c in self.cores], dtype=np.intp)
        self.dead = [False] * len(self.cores)
        self._laws = self._one_law = None

    @property
    def one_law(self) -> bool:
        """Do all the agents have one law (and dt)?  Looked at again when an agent's law
        changed (a live parameter set: `AgentCore.law` is then a new object)."""
        laws = [c.law for c in self.cores]
        if self._laws is None or any(a is not b for a, b in zip(laws, self._laws)):
            self._laws = laws
            self._one_law = all(c.law == laws[0] and c.dt == self.cores[0].dt for c in self.cores)
        return self._one_law

    def kill(self, j: int):
        """Agent j (position in the container) is dead: it never computes or speaks again."""
        self.dead[j] = True

    def on_step(self, s) -> list[tuple]:
        """What each agent does at step message ``s`` (a `swarm_ros.layouts.Step`): a list of
        (j, kind, detail) with kind 'repeat' (publish the last state again), 'silent' (left the
        table at step detail), 'back' (back in the table; detail: the step it held),
        'reject' (detail: (key, text)), 'moved' (detail: u; the agent advanced one step)."""
        out, go = [], []
        full = len(s.alive) == self.n
        for j, c in enumerate(self.cores):
            if self.dead[j]:
                continue
            if s.n == c.step - 1:
                out.append((j, 'repeat', None))
                continue
            if full and not s.alive[c.index]:
                if s.n >= c.step and not c.silent:
                    c.silent = True
                    out.append((j, 'silent', s.n))
                continue
            if s.n > c.step:
                out.append((j, 'back', c.step))
                c.step = s.n
            if s.n != c.step:
                out.append((j, 'reject', ('step', f'/lockstep/step for step {s.n} (this agent is at step {c.step})')))
                continue
            if len(s.x) != self.n:
                out.append((j, 'reject', ('step-n', f'/lockstep/step with {len(s.x)} agents (roster has {self.n})')))
                continue
            c.silent = False
            go.append(j)
        if not go:
            return out
        for j in go:
            c = self.cores[j]
            if c.reported:
                c.take_reported(s.x[c.index], s.y[c.index], s.qz[c.index], s.qw[c.index])
        us = self.controls(s, go)
        for j, u in zip(go, us):
            if not math.isfinite(u):
                out.append((j, 'reject', ('u-nan', f'non-finite control u={u} at step {s.n}; holding u=0')))
        self.advance(go, us)
        for j, _u in zip(go, us):
            self.cores[j].step = s.n + 1
            out.append((j, 'moved', self.cores[j].u_last))
        return out

    def controls(self, s, go) -> list[float]:
        """u of the agents ``go`` (positions in the container) at step message ``s``."""
        cores = [self.cores[j] for j in go]
        alive = s.alive if len(s.alive) == self.n else None
        if not self.one_law or any(c.comms is not None for c in cores):
            # a radio model (each agent its own beliefs) or different laws: one call per agent
            return [c.comms_control(s.n, s.x, s.y, s.qz, s.qw, s.u, s.lam, s.flags, s.steering[c.index],
                                    s.target, s.barrier, alive=alive, rendezvous=s.rendezvous, t=s.t)
                    if c.comms is not None else
                    c.control(s.x, s.y, s.qz, s.qw, s.lam, s.flags, s.steering[c.index], s.target,
                              s.barrier, alive=s.alive, rendezvous=s.rendezvous, t=s.t)
                    for c in cores]
        idx = self.rows[go]
        pos, cos_t, sin_t = received_table(s.x, s.y, s.qz, s.qw, idx, cores)
        for c in cores:             # what each agent's u came from (`AgentCore.trial`)
            c.seen = Seen(pos, cos_t, sin_t, c.index, s.lam, s.flags, float(s.steering[c.index]), s.target,
                          s.barrier, s.alive, s.rendezvous, s.t)
        try:
            u = alive_control(pos, cos_t, sin_t, idx, cores[0].law, s.lam, s.flags, np.asarray(s.steering, float)[idx],
                              s.target, s.barrier, alive=s.alive, rendezvous=s.rendezvous, t=s.t)
        except LawError as err:       # the process stops on it (`swarm_ros.rosutil.run_node`)
            raise failed_at(err, s.t) from None
        return [float(v) for v in u]

    def advance(self, go, us):
        """One ZOH step of the agents ``go`` with controls ``us`` (non-finite -> 0): one
        elementwise `zoh_step` over all of them (the same bits as one call per agent), then each
        agent's own noise draw."""
        u = np.array([v if math.isfinite(v) else 0.0 for v in us])
        for j, v in zip(go, u.tolist()):
            if self.cores[j].reported:        # its robot moves (no integration, no noise draw)
                self.cores[j].u_last = v
        keep = [i for i, j in enumerate(go) if not self.cores[j].reported]
        if len(keep) < len(go):
            go, u = [go[i] for i in keep], u[keep]
        if not go:
            return
        cores = [self.cores[j] for j in go]
        if len(cores) == 1:
            cores[0].advance(float(u[0]))
            return
        pos = np.concatenate([c.pos for c in cores])
        theta = np.concatenate([c.theta for c in cores])
        pos, theta = zoh_step(pos, theta, u, cores[0].dt)
        for i, c in enumerate(cores):
            c.moved_to(pos[i:i + 1].copy(), theta[i:i + 1].copy(), float(u[i]))
        # what each agent publishes (qz, qw) and its own frame next step, for all at once
        # (elementwise: the same bits as `AgentCore.quaternion` and `_own_frame` one by one)
        qz, qw = quaternion_from_heading(np.concatenate([c.theta for c in cores]))
        cos_t, sin_t = frame_from_quaternion(qz, qw)
        for i, c in enumerate(cores):
            c._quat = (float(qz[i]), float(qw[i]))
            c._frame = (cos_t[i], sin_t[i])
