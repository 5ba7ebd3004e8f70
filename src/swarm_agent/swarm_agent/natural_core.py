"""The agents of a 3D run (``dim: 3``), without ROS: their states in one bank and their lockstep
step, exactly as `swarm_core.engine.natural` steps the whole swarm.

Each agent holds its position r (3,) and its frame [x y z] (3 × (3,)) as float64, never a
quaternion: the lockstep messages carry r, x, y and z as they are (`swarm_ros.layouts.NaturalStep`),
so every receiver's table is the batch engine's bit for bit.  Per step message a container
(`NaturalContainerCore`, a lone agent being a container of one) follows the rules of
`container_core.ContainerCore` (repeat, silent, back, reject, move) and then:

1. (u, v) of its moving agents from `swarm_core.step.natural_alive_control` over the step's
   table, asked for their rows: each receiver's sums reduce its own rows
   (`laws.paper.natural_sums`), so each agent's (u, v) is the batch engine's whatever K is.
   An agent with a radio model (`NaturalAgentCore.attach_comms`) first lets its radio decide
   which states of the step's table it receives (r, x, y, z of t_n and the (u, v) each sender
   held), folds them into its `natural_radio.NaturalBeliefs` and takes (u, v) from its own
   beliefs (`swarm_core.step.natural_belief_controls`, itself the only receiver): the batch
   engine's (u, v) bit for bit, as in the plane (`agent_core.AgentCore.comms_control`);
2. one `model.natural.natural_step` over their rows (elementwise: the same bits for any K);
3. each noisy agent's own draw (U(−p, p) on r; the heading turned by two angles, as the engine);
4. Gram-Schmidt (`orthonormalise`) after every `ORTHONORMALISE_EVERY`-th step, as the engine.

What an agent publishes on /swarm/states carries the quaternion of its frame
(`model.natural.quaternion_from_frame`) and twist.angular = (0, −v, u).
"""
from __future__ import annotations

import numpy as np

from swarm_agent.container_core import ContainerCore
from swarm_core.faults.agents import reunion_law
from swarm_core.laws import Law, LawError, failed_at
from swarm_core.model.natural import ORTHONORMALISE_EVERY, natural_step, orthonormalise, quaternion_from_frame
from swarm_core.natural_radio import NaturalBeliefs, natural_states
from swarm_core.radio import CommModel
from swarm_core.step import natural_alive_control, natural_belief_controls
from swarm_ros.layouts import NaturalAgentStates, NaturalStep


class NaturalStates:
    """The own states of the agents of one 3D process, a row each: r, x, y, z (K, 3), the (u, v)
    held, the step held, ``silent`` (out of the table) and the flags a container looks at."""

    ROWS = ('pos', 'x', 'y', 'z', 'u', 'v', 'step', 'silent', 'radio', 'robot', 'noisy')
    __slots__ = ROWS + ('changes',)

    def __init__(self, k: int):
        self.pos, self.x, self.y, self.z = (np.zeros((k, 3)) for _ in range(4))
        self.u, self.v = np.zeros(k), np.zeros(k)
        self.step = np.zeros(k, dtype=np.int64)
        self.silent, self.radio, self.robot, self.noisy = (np.zeros(k, dtype=bool) for _ in range(4))
        self.changes = 0        # laws given to the rows' agents so far (`ContainerCore.one_law`)

    @classmethod
    def of(cls, cores) -> NaturalStates:
        """One bank for ``cores``: their rows copied in; each core reads and writes its row here."""
        bank = cls(len(cores))
        for j, c in enumerate(cores):
            old, i = c.states, c.slot
            for name in cls.ROWS:
                getattr(bank, name)[j] = getattr(old, name)[i]
            c.states, c.slot = bank, j
        return bank

    def message(self, tag, index, rows) -> NaturalAgentStates:
        """The states of the bank's ``rows`` (agents ``index``) for the world."""
        if len(rows) == len(self.step) and np.array_equal(rows, np.arange(len(rows))):   # every row in order: no gather
            return NaturalAgentStates(tag, index, self.step.copy(), np.stack([self.pos, self.x, self.y, self.z]),
                                      np.stack([self.u, self.v], axis=1))
        state = np.stack([self.pos[rows], self.x[rows], self.y[rows], self.z[rows]])
        return NaturalAgentStates(tag, index, self.step[rows], state, np.stack([self.u[rows], self.v[rows]], axis=1))


def _row(name, kind=float):
    def get(self):
        return kind(getattr(self.states, name)[self.slot])

    def put(self, value):
        getattr(self.states, name)[self.slot] = value
    return property(get, put)


class NaturalAgentCore:
    """One agent of a 3D run: its row of a `NaturalStates` bank, its law, dt and noise."""

    step = _row('step', int)
    silent = _row('silent', bool)
    u_last = _row('u')
    dim = 3

    def __init__(self, index: int, n_agents: int, pos, frame, law: Law, dt: float, noise=(0.0, 0.0), noise_rng=None):
        self.index, self.n = int(index), int(n_agents)
        self.states, self.slot = NaturalStates(1), 0
        b = self.states
        b.pos[0] = pos
        b.x[0], b.y[0], b.z[0] = np.asarray(frame, float).reshape(3, 3)
        self.law = law
        self.dt = float(dt)
        self.noise_scale = np.array([noise[0]] * 3 + [noise[1]] * 2, dtype=float)
        self.noisy = bool(np.any(self.noise_scale > 0))
        b.noisy[0] = self.noisy
        self.rng = noise_rng
        self.comms = None           # a radio model (`attach_comms`), or None
        self.beliefs = None         # what its radio delivered (`NaturalBeliefs`)
        self.believed = None        # the inputs of its last (u, v) through the radio (`comms_control`)
        self.reported = False
        self.pairs = None
        self.container = None       # its `NaturalContainerCore` (the inputs of its last (u, v))

    @property
    def law(self):
        return self._law

    @law.setter
    def law(self, law):
        self._law = law
        self.states.changes += 1

    def sums_compiled(self):
        """The 3D sums choose their kernels by the table's size (`natural_compiled.use_compiled`),
        as the batch engine does: nothing to set."""

    def attach_comms(self, model: CommModel):
        """Receive through ``model`` from now on (lockstep: `comms_control`)."""
        self.comms = model
        self.beliefs = NaturalBeliefs([self.index], self.n)
        self.states.radio[self.slot] = True
        self.states.changes += 1

    def comms_control(self, s, alive=None):
        """(u, v) (2,) of this agent at step message ``s`` (a `NaturalStep`) from what its radio
        delivers of the step's table: the states r, x, y, z of t_n as sent and the (u, v) each
        sender held (``s.uv``).  alive (N,) bool, faults: agents out of the table send nothing
        (the relay still carries their last rows)."""
        k, pos = self.index, s.state[0]
        arrival = self.comms.decide(s.n, [k], pos[k:k + 1], np.arange(self.n), pos)
        self.beliefs.receive_states(s.n, arrival, natural_states(*s.state, s.uv), alive=alive)
        b, j = self.states, self.slot
        own = tuple(a[j:j + 1].copy() for a in (b.pos, b.x, b.y, b.z))
        self.believed = (s.n, own, s.lam, s.flags, np.asarray(s.steering, float)[k], s.target, s.barrier, s.ground,
                         s.rendezvous, s.t)
        try:
            return self._believed_control(self.law)
        except LawError as err:       # the process stops on it (`swarm_ros.rosutil.run_node`)
            raise failed_at(err, s.t) from None

    def _believed_control(self, law):
        """(u, v) (2,) under ``law`` from the beliefs and the inputs of the last step (`believed`)."""
        step, own, lam, flags, steering, target, barrier, ground, rendezvous, t = self.believed
        law, target = reunion_law(law, target, rendezvous)
        return natural_belief_controls(law, self.beliefs, step, self.comms, own[0], own[1:], lam, flags, steering,
                                       target, barrier, ground, t=t)[0]

    @property
    def row(self):
        """(r, x, y, z) of this agent, (3,) each (copies)."""
        b, j = self.states, self.slot
        return b.pos[j].copy(), b.x[j].copy(), b.y[j].copy(), b.z[j].copy()

    @property
    def quaternion(self):
        """(qx, qy, qz, qw) of its frame [x y z]."""
        b, j = self.states, self.slot
        return tuple(float(q[0]) for q in quaternion_from_frame(b.x[j], b.y[j], b.z[j]))

    def trial(self, law: Law) -> str | None:
        """Try ``law`` on the table of this agent's last (u, v) (before its first: its own state
        alone at λ = 0): None if it gives a finite (u, v), else the one line why."""
        if self.believed is not None:
            try:
                uv = self._believed_control(law)
            except LawError as err:
                return str(err)
            return None if np.all(np.isfinite(uv)) else \
                f'law {law.kind} gives a non-finite (u, v) ({uv.tolist()!r}) on this agent\'s last beliefs'
        seen = None if self.container is None else self.container.seen
        b, j = self.states, self.slot
        if seen is None:
            seen = (b.pos[j:j + 1], (b.x[j:j + 1], b.y[j:j + 1], b.z[j:j + 1]), 0.0, None, np.zeros((1, 2)), None,
                    None, None, None, None, self.step * self.dt)
            row = 0
        else:
            row = self.index
        pos, frames, lam, flags, steering, target, barrier, ground, alive, rdv, t = seen
        try:
            uv = natural_alive_control(pos, frames, [row], law, lam, flags, steering[[row]], target, barrier,
                                       ground, alive=alive, rendezvous=rdv, t=t)[0]
        except LawError as err:
            return str(err)
        if not np.all(np.isfinite(uv)):
            return f'law {law.kind} gives a non-finite (u, v) ({uv.tolist()!r}) on this agent\'s last table'
        return None


class NaturalContainerCore(ContainerCore):
    """Lockstep of K agents of a 3D run in one process (`ContainerCore`'s rules over a
    `NaturalStates` bank); see the module docstring."""

    dim = 3
    step_layout = NaturalStep
    states_class = NaturalStates

    def __init__(self, cores):
        super().__init__(cores)
        self.seen = None            # the inputs of the last (u, v) (`NaturalAgentCore.trial`)
        for c in self.cores:
            c.container = self

    @property
    def any_reported(self) -> bool:
        return False

    def controls(self, s, go):
        """(u, v) (len(go), 2) of the agents ``go`` at step message ``s`` (a `NaturalStep`): the
        batch engine's call on the step's table, asked for their rows (a receiver's (u, v) does
        not depend on which receivers are asked with it: `laws.paper.natural_sums`)."""
        every = go is self.every                    # the usual step: whole rows, no gathers
        go = np.asarray(go, dtype=np.intp)
        self.step_n = s.n
        b = self.bank
        self._look()
        if self._radio and b.radio[go].any():       # a radio model: each such agent from its own beliefs
            alive = s.alive if len(s.alive) == self.n else None
            radio = b.radio[go]
            uv = np.zeros((len(go), 2))
            for i in np.flatnonzero(radio).tolist():
                uv[i] = self.cores[go[i]].comms_control(s, alive)
            if not radio.all():
                uv[~radio] = self.controls(s, go[~radio])
            return uv
        pos, x, y, z = np.array(s.state)                         # one copy; contiguous (N, 3) each, as the engine's
        if every:
            idx = self.rows
            pos[idx], x[idx], y[idx], z[idx] = b.pos, b.x, b.y, b.z
        else:
            idx = self.rows[go]
            pos[idx], x[idx], y[idx], z[idx] = b.pos[go], b.x[go], b.y[go], b.z[go]
        alive = s.alive if len(s.alive) == self.n and not s.alive.all() else None
        steering = np.asarray(s.steering, float)
        self.seen = (pos, (x, y, z), s.lam, s.flags, steering, s.target, s.barrier, s.ground, alive, s.rendezvous, s.t)

        def call(rows, law):
            try:
                return natural_alive_control(pos, (x, y, z), rows, law, s.lam, s.flags, steering[rows], s.target,
                                             s.barrier, s.ground, alive=alive, rendezvous=s.rendezvous, t=s.t)
            except LawError as err:   # the process stops on it (`swarm_ros.rosutil.run_node`)
                raise failed_at(err, s.t) from None
        if self.one_law:                                        # a plain run: one call, in the order of go
            return call(idx, self.cores[0].law)
        by_law = {}                                             # else one call per law
        for j in go.tolist():
            by_law.setdefault(id(self.cores[j].law), []).append(j)
        uv = np.zeros((len(go), 2))
        for js in by_law.values():
            uv[np.searchsorted(go, js)] = call(self.rows[js], self.cores[js[0]].law)
        return uv

    def advance(self, go, us):
        """One `natural_step` of the agents ``go`` with (u, v) ``us`` (non-finite → 0), each
        noisy agent's own draw, and Gram-Schmidt where the engine does it (after step n with
        (n + 1) a multiple of `ORTHONORMALISE_EVERY`)."""
        b = self.bank
        every = go is self.every                    # the usual step: whole rows, no gathers
        go = np.asarray(go, dtype=np.intp)
        uv = np.asarray(us, dtype=float).reshape(-1, 2).copy()
        uv[~np.isfinite(uv)] = 0.0
        b.u[go], b.v[go] = uv[:, 0], uv[:, 1]
        if not go.size:
            return
        if every:
            b.pos, b.x, b.y, b.z = natural_step(b.pos, b.x, b.y, b.z, b.u, b.v, self.cores[0].dt)
        else:
            pos, x, y, z = natural_step(b.pos[go], b.x[go], b.y[go], b.z[go], uv[:, 0], uv[:, 1],
                                        self.cores[go[0]].dt)
            b.pos[go], b.x[go], b.y[go], b.z[go] = pos, x, y, z
        for j in go.tolist() if b.noisy.any() else ():
            c = self.cores[j]
            if c.noisy:
                kick = c.rng.uniform(-1.0, 1.0, size=5) * c.noise_scale
                b.pos[j] = (b.pos[j:j + 1] + kick[None, :3])[0]
                if c.noise_scale[3] > 0:
                    _, x, y, z = natural_step(b.pos[j:j + 1], b.x[j:j + 1], b.y[j:j + 1], b.z[j:j + 1],
                                              kick[3:4], kick[4:5], 1.0)
                    b.x[j], b.y[j], b.z[j] = x[0], y[0], z[0]
        if self.step_n is not None and (self.step_n + 1) % ORTHONORMALISE_EVERY == 0:
            if every:
                b.x, b.y, b.z = orthonormalise(b.x, b.y)
            else:
                b.x[go], b.y[go], b.z[go] = orthonormalise(b.x[go], b.y[go])

    def finite(self, us):
        """Which rows of ``us`` (K, 2) are finite."""
        return np.isfinite(us).all(axis=1)


def container_of(cores):
    """The lockstep container of ``cores``: a `NaturalContainerCore` for a 3D run's agents."""
    return (NaturalContainerCore if getattr(cores[0], 'dim', 2) == 3 else ContainerCore)(cores)
