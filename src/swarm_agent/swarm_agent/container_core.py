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

With the compiled sums on (a run's ``--compiled``), the usual step of plain agents (one paper
law, planar, no radio, robot or noise) is one compiled call for the law, the move and the new
quaternions (`swarm_core.laws.paper.compiled_step`): the same bits as the numpy step.

`agents_per_process` is the rule behind ``swarm run --agents-per-process auto``, and
`agent_services` the one behind ``--agent-services auto``.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from swarm_agent.agent_core import SharedTable, States
from swarm_core.laws import LawError, failed_at
from swarm_core.laws.paper import compiled_step
from swarm_core.model.frenet import frame_from_quaternion
from swarm_core.model.integrate import zoh_step
from swarm_core.step import alive_control
from swarm_ros.layouts import Step

#: ``auto``: one process per agent while there are at most this many agents per core
PROCESSES_PER_CORE = 3
#: ``auto``: agents per container at most
CONTAINER_SIZE = 2500


def agents_per_process(n: int, cores: int | None = None) -> int:
    """K for ``--agents-per-process auto``.

    Measured (BENCHMARKS.md): a container costs less CPU per step than one process per agent
    at every n from 6 on (6 agents: 1.8-3.5 ms against 8.4 ms per step), so processes are kept
    only for a small swarm (n ≤ PROCESSES_PER_CORE per core: each agent a process of its own,
    faults by signal).  Larger swarms get one container per core (of at most CONTAINER_SIZE
    agents): a container steps its agents as one batch, so more processes than cores only add
    the per-process cost of each step (its relay decoded again, one more wake-up); 1,000 agents
    ran 2.5 times faster in 2 containers than in 10."""
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
    """Lockstep of K agents in one process; see the module docstring.  Their states are one
    bank (`States`, ``bank``): the rules, the law call and the move run over its rows at once.
    (A 3D run's: `natural_core.NaturalContainerCore`.)"""

    dim = 2
    n_dead = 0          # agents killed (`kill`)
    _seen = None        # the bank's changes when `_look` last looked
    _compiled = None    # `compiled`

    @functools.cached_property
    def every(self):
        """0 … K − 1: every position in the container."""
        return np.arange(len(self.cores))
    step_layout = Step

    #: the bank of the agents' states (3D: `natural_core.NaturalStates`)
    states_class = States

    def __init__(self, cores):
        self.cores = list(cores)
        if not self.cores:
            raise ValueError('a container needs at least one agent')
        self.n = self.cores[0].n
        self.rows = np.array([c.index for c in self.cores], dtype=np.intp)
        self.bank = self.states_class.of(self.cores)
        self.dead = np.zeros(len(self.cores), dtype=bool)

    def _look(self):
        """Whether one law (and dt) serves all the agents, and whether any hears through a
        radio, rides a robot or draws noise: looked at again only when an agent's law or
        flags changed (a live parameter set, `AgentCore.law`; `comms`, `reported`)."""
        b = self.bank
        if self._seen != b.changes:
            self._seen = b.changes
            law, dt = self.cores[0].law, self.cores[0].dt
            self._one_law = all(c.law == law and c.dt == dt for c in self.cores)
            self._radio, self._robot, self._noisy = bool(b.radio.any()), bool(b.robot.any()), bool(b.noisy.any())
            plain = self._one_law and self.dim == 2 and not (self._radio or self._robot or self._noisy)
            if not (plain and all(c.pairs is not None for c in self.cores)):
                self._compiled = None
            elif self._compiled is None:
                self._compiled = compiled_step.CompiledStep()

    @property
    def one_law(self) -> bool:
        """Do all the agents have one law (and dt)?"""
        self._look()
        return self._one_law

    def finite(self, us):
        """Which of the controls ``us`` are finite."""
        return np.isfinite(us)

    def kill(self, j: int):
        """Agent j (position in the container) is dead: it never computes or speaks again."""
        self.n_dead += not self.dead[j]
        self.dead[j] = True

    def on_step(self, s) -> list[tuple]:
        """What each agent does at step message ``s`` (a `swarm_ros.layouts.Step`): a list of
        (j, kind, detail) with kind 'repeat' (publish the last state again), 'silent' (left the
        table at step detail), 'back' (back in the table; detail: the step it held),
        'reject' (detail: (key, text)), 'moved' (detail: u; the agent advanced one step)."""
        moved, repeat, out, nan = self.step_rows(s)
        out += [(int(j), 'repeat', None) for j in repeat]
        out.sort(key=lambda o: o[0])       # each agent's outcomes in container order
        return out + nan + [(int(j), 'moved', float(self.bank.u[j])) for j in moved]

    def step_rows(self, s):
        """`on_step` over the bank's rows at once: (the positions that moved, those that repeat
        their answer, [(j, kind, detail)] of the rules' other outcomes: silent, back, reject,
        and the moved agents' 'u-nan' rejects), the rules of the module docstring as masks, no
        Python per agent but for the rare outcomes."""
        b, n = self.bank, s.n
        usual = self.usual(s)                                       # the usual step: every agent moves
        go, repeat, out = (self.every, self.every[:0], []) if usual else self._rules(s)
        if not go.size:
            return go, repeat, out, []
        b.silent[go] = False
        compiled = usual and self.compiled is not None and compiled_step.fits(
            self.cores[0].law, s.target, s.barrier, s.rendezvous, s.alive)
        for j in go.tolist() if self.any_reported else ():         # (never compiled: no robot there)
            c = self.cores[j]
            if c.reported:
                c.take_reported(s.x[c.index], s.y[c.index], s.qz[c.index], s.qw[c.index])
        us = self._compiled_rows(s) if compiled else np.asarray(self.controls(s, go), dtype=float)
        nan = [] if math.isfinite(us.sum()) else [
            (int(go[i]), 'reject', ('u-nan', f'non-finite control u={us[i]} at step {n}; holding u=0'))
            for i in np.flatnonzero(~self.finite(us))]
        if not compiled:                                           # (the compiled call moved them)
            self.advance(go, us)
        b.step[go] = n + 1
        return go, repeat, out, nan

    def usual(self, s) -> bool:
        """Is step message ``s`` the usual one: every agent holds its step, none is dead, all
        are in its table (then no rule but the move applies)?"""
        b, n = self.bank, s.n
        if self.n_dead or len(s.x) != self.n:
            return False
        full = len(s.alive) == self.n
        if len(self.cores) == 1:                  # a lone agent: numbers, not arrays
            return b.step[0] == n and (not full or bool(s.alive[self.rows[0]]))
        return bool((b.step == n).all()) and (not full or bool(s.alive[self.rows].all()))

    def _rules(self, s):
        """The rules of `step_rows` for a step where some agent does not simply move: (the
        positions that move, those that repeat, the other outcomes)."""
        b, n = self.bank, s.n
        live = ~self.dead
        repeat = live & (b.step == n + 1)
        rest = live & ~repeat
        out = []
        if len(s.alive) == self.n:
            in_table = s.alive[self.rows]
            gone = rest & ~in_table
            went = gone & (b.step <= n) & ~b.silent
            b.silent[went] = True
            out += [(int(j), 'silent', n) for j in np.flatnonzero(went)]
            rest &= in_table
        back = rest & (b.step < n)
        if back.any():
            out += [(int(j), 'back', int(b.step[j])) for j in np.flatnonzero(back)]
            b.step[back] = n
        ahead = rest & (b.step != n)
        out += [(int(j), 'reject', ('step', f'/lockstep/step for step {n} (this agent is at step {b.step[j]})'))
                for j in np.flatnonzero(ahead)]
        go = np.flatnonzero(rest & ~ahead)
        if go.size and len(s.x) != self.n:
            out += [(int(j), 'reject', ('step-n', f'/lockstep/step with {len(s.x)} agents (roster has {self.n})'))
                    for j in go]
            go = go[:0]
        return go, np.flatnonzero(repeat), out

    @property
    def compiled(self):
        """The bank's `compiled_step.CompiledStep` where the agents sum their pairs compiled (a
        run's ``--compiled``) with one law, planar, none on a radio, robot or noise; else None."""
        self._look()
        return self._compiled

    def _compiled_rows(self, s):
        """The law and the move of the usual step in one compiled call (`compiled_step`): the
        same bits as `controls` and `advance`; returns u (K,) as the law gave it (the bank holds
        it with non-finite values as 0, as `advance` does)."""
        b, first = self.bank, self.cores[0]
        if not b.fresh.all():
            b.refresh(np.flatnonzero(~b.fresh))
        steering = np.asarray(s.steering, float)
        try:
            u, (pos, cos_t, sin_t) = self._compiled(first.law, b, self.rows, first.dt, s.lam,
                                                    np.asarray(s.flags, bool), steering, s.x, s.y, s.qz, s.qw, s.target)
        except LawError as err:       # the process stops on it (`swarm_ros.rosutil.run_node`)
            raise failed_at(err, s.t) from None
        b.share(SharedTable(pos, cos_t, sin_t, s.lam, s.flags, steering, s.target, s.barrier, s.alive,
                            s.rendezvous, s.t), self.every, self.cores)
        b.u = u if math.isfinite(u.sum()) else np.where(np.isfinite(u), u, 0.0)
        b.fresh[:] = True
        return u

    @property
    def any_reported(self) -> bool:
        """Is any agent on a MuJoCo robot in lockstep (its pose from the table)?"""
        self._look()
        return self._robot

    def controls(self, s, go) -> list[float]:
        """u of the agents ``go`` (positions in the container) at step message ``s``."""
        go = np.asarray(go, dtype=np.intp)
        alive = s.alive if len(s.alive) == self.n else None
        if not self.one_law or self._radio and self.bank.radio[go].any():
            # a radio model (each agent its own beliefs) or different laws: one call per agent
            cores = [self.cores[j] for j in go]
            return [c.comms_control(s.n, s.x, s.y, s.qz, s.qw, s.u, s.lam, s.flags, s.steering[c.index],
                                    s.target, s.barrier, alive=alive, rendezvous=s.rendezvous, t=s.t)
                    if c.comms is not None else
                    c.control(s.x, s.y, s.qz, s.qw, s.lam, s.flags, s.steering[c.index], s.target,
                              s.barrier, alive=s.alive, rendezvous=s.rendezvous, t=s.t)
                    for c in cores]
        b, every = self.bank, go is self.every
        idx = self.rows if every else self.rows[go]
        if not b.fresh.all():
            b.refresh(np.flatnonzero(~b.fresh))
        pos = np.empty((len(s.x), 2))              # the table as received, own rows the agents' own
        pos[:, 0] = s.x
        pos[:, 1] = s.y
        cos_t, sin_t = frame_from_quaternion(s.qz, s.qw)
        if every:
            pos[idx], cos_t[idx], sin_t[idx] = b.pos, b.cos, b.sin
        else:
            pos[idx], cos_t[idx], sin_t[idx] = b.pos[go], b.cos[go], b.sin[go]
        steering = np.asarray(s.steering, float)
        b.share(SharedTable(pos, cos_t, sin_t, s.lam, s.flags, steering, s.target, s.barrier, s.alive,
                            s.rendezvous, s.t), go, self.cores)          # what each u came from (`trial`)
        first = self.cores[go[0]]
        try:
            return alive_control(pos, cos_t, sin_t, idx, first.law, s.lam, s.flags, steering[idx], s.target,
                                 s.barrier, alive=s.alive, rendezvous=s.rendezvous, pairs=first.pairs, t=s.t)
        except LawError as err:       # the process stops on it (`swarm_ros.rosutil.run_node`)
            raise failed_at(err, s.t) from None

    def advance(self, go, us):
        """One ZOH step of the agents ``go`` with controls ``us`` (non-finite -> 0): one
        elementwise `zoh_step` over all their rows (the same bits as one call per agent), then
        each noisy agent's own draw, then their quaternions and frames (`States.refresh`).  An
        agent on a MuJoCo robot in lockstep does not move here: its robot moves."""
        b = self.bank
        u = np.array(us, dtype=float)
        if not math.isfinite(u.sum()):
            u[~np.isfinite(u)] = 0.0
        if go is self.every and not self.any_reported and not self.any_noisy:    # the usual step: whole rows
            b.u = u
            b.pos, b.theta = zoh_step(b.pos, b.theta, u, self.cores[0].dt)
            b.refresh(None)
            return
        go = np.asarray(go, dtype=np.intp)
        b.u[go] = u
        if self.any_reported:
            keep = np.array([not self.cores[j].reported for j in go], dtype=bool)
            go, u = go[keep], u[keep]
        if not go.size:
            return
        pos, theta = zoh_step(b.pos[go], b.theta[go], u, self.cores[go[0]].dt)
        b.pos[go], b.theta[go] = pos, theta
        for j in go.tolist() if self.any_noisy else ():
            c = self.cores[j]
            if c.noisy:
                draw = c.rng.uniform(-1.0, 1.0, size=3) * c.noise_scale
                b.pos[j] = (b.pos[j:j + 1] + draw[None, :2])[0]
                b.theta[j] = (b.theta[j:j + 1] + draw[2:3])[0]
        b.refresh(go)

    @property
    def any_noisy(self) -> bool:
        self._look()
        return self._noisy
