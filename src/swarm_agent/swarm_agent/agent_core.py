"""One agent's arithmetic, without ROS (used by `AgentNode`, tested on its own).

`AgentCore` keeps the agent's own state (position float64, heading θ unwrapped float64) and
advances it by one zero-order-hold step from a table of ALL agents' states in agent-index
order, exactly as `swarm_core.engine.reference.SwarmStepper` does for the whole swarm:

1. table rows: positions as received (exact float64), frames from the received quaternions
   (`frame_from_quaternion`); the agent's own row from its own θ via `quaternion_from_heading`;
2. u = `swarm_control(..., receivers=[own_row])` with λ, leader flags and s_k of that step;
3. `zoh_step` on 1-element arrays, then the agent's own seeded noise (if any).

With faults the table holds only the agents alive at that step, in index order, and a
rendezvous (reunion) switches the target term on: `swarm_core.step.alive_control`, the same
function the batch engine and an agent container call.

Because `swarm_control` reduces each receiver's row of pair terms on its own (numpy row sums
over the whole table, or `np.bincount` over a neighbour list, in table order) and every other
operation is elementwise, the agent's u equals the batch engine's bit for bit.

With a communication model (`attach_comms`), `comms_control` first lets the agent's radio
decide which states of the step's table it receives (`swarm_core.radio`, the same pure fate
function the batch engine uses for every link), folds them into its beliefs and computes u on
its beliefs (`swarm_core.step.belief_controls`, itself the only receiver): again bit for bit
the batch engine's u.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from swarm_core.faults.agents import reunion_law
from swarm_core.laws import Law, LawError, failed_at
from swarm_core.laws.paper.compiled_sums import COMPILED, warm_up
from swarm_core.model.frenet import frame_from_quaternion, quaternion_from_heading
from swarm_core.model.integrate import zoh_step
from swarm_core.radio import Beliefs, CommModel
from swarm_core.robot_units import reported_heading
from swarm_core.step import alive_control, belief_controls

#: a tick this few periods short of a boundary is on it (t_state sums dt in floats; the clock
#: comes in whole ns)
ON_BOUNDARY = 1e-6


def catch_up(now: float, t_state: float, dt: float, limit: int) -> tuple[int, float]:
    """Realtime: how many control periods to integrate (u held, ZOH) at sim time ``now`` when
    the agent holds its state of time ``t_state``, and the time of the state that results.

    periods = floor((now − t_state)/dt), the whole periods that have begun: a /clock jump may
    cover two periods (one timer call) or none (a second call at the same time: 0 periods, no
    new state).  A tick half a period late still makes the state of the period it is in, not
    the next one's, stamped ahead of the clock (a period skipped, counted late).  The new
    state's time is t_state + periods·dt, so rounding never accumulates.  A gap of more than
    ``limit`` periods moves the agent ``limit`` periods and restarts its time at ``now`` (the
    limit applies after the process was stopped, `realtime_core.due_periods`; a late tick
    flies every period)."""
    periods = math.floor((now - t_state) / dt + ON_BOUNDARY)
    if periods < 1:
        return 0, t_state
    if periods > limit:
        return limit, now
    return periods, t_state + periods * dt


def received_table(x, y, qz, qw, rows, cores):
    """pos (N, 2), cos θ, sin θ (N,) of a step's table as received (frames from the
    quaternions, eq. 3), with rows ``rows`` holding the own states of the agents ``cores``
    (their positions, their frames through the quaternions they publish)."""
    pos = np.empty((len(x), 2))
    pos[:, 0] = x
    pos[:, 1] = y
    cos_t, sin_t = frame_from_quaternion(qz, qw)            # new arrays
    for r, c in zip(rows, cores):
        pos[r] = c.pos[0]
        cos_t[r], sin_t[r] = c._own_frame()                 # (cached until the agent moves)
    return pos, cos_t, sin_t


class Seen(NamedTuple):
    """The inputs an agent's u came from last (`AgentCore.seen`): the table (pos (N, 2), cos θ,
    sin θ (N,)), the agent's row in it, λ, the leader flags, its s_k, target, barrier, the
    alive mask, the rendezvous and the sim time; a live law parameter set is tried on them
    (`AgentCore.trial`)."""
    pos: np.ndarray
    cos_t: np.ndarray
    sin_t: np.ndarray
    row: int
    lam: float
    is_leader: object
    steering: float
    target: object = None
    barrier: object = None
    alive: object = None
    rendezvous: object = None
    t: float | None = None


class Believed(NamedTuple):
    """The inputs an agent's u came from last through a radio model (`AgentCore.comms_control`):
    its beliefs of step ``step`` with its own pose of then (pos (1, 2), θ (1,))."""
    step: int
    pos: np.ndarray
    theta: np.ndarray
    lam: float
    is_leader: object
    steering: float
    target: object = None
    barrier: object = None
    rendezvous: object = None
    t: float | None = None


def roster_index(roster, agent_name: str, index: int) -> tuple[list, int]:
    """(roster, this agent's row in it) from the parameters agent_names, agent_name and
    agent_index (-1: look the name up; [''] : the agent alone); ValueError names the bad one."""
    roster = list(roster)
    if roster == ['']:
        roster = [agent_name]
    if len(set(roster)) != len(roster):
        raise ValueError('parameter agent_names: names must be unique')
    if agent_name not in roster:
        raise ValueError(f'parameter agent_name: {agent_name!r} is not in agent_names')
    if index < 0:
        return roster, roster.index(agent_name)
    if index >= len(roster) or roster[index] != agent_name:
        raise ValueError(f'parameter agent_index: {index} does not name {agent_name!r} in agent_names')
    return roster, index


def known_table(roster, own: str, own_state, newest: dict, leaders, now: float, stale_after: float):
    """Realtime without a radio model: (own row, states (m, 4) of x, y, qz, qw, leader flags
    (m,)) of this agent (``own``, state ``own_state``) and the agents whose newest state
    (``newest``: name -> (t, x, y, qz, qw, ...)) is at most ``stale_after`` old at ``now``, in
    roster order."""
    names = [nm for nm in roster if nm == own or (nm in newest and now - newest[nm][0] <= stale_after)]
    rows = np.array([newest[nm][1:5] if nm != own else own_state for nm in names])
    flags = np.array([nm in leaders for nm in names])
    return names.index(own), rows, flags


class States:
    """The own states of the agents of one process, a row each: position (K, 2), heading θ (K,),
    the u held, the step held, whether each is out of the table (``silent``), and the
    quaternion and frame each publishes (``qz``, ``qw``, ``cos``, ``sin``; valid where
    ``fresh``).  An agent's `AgentCore` reads and writes its own row; an agent container steps
    all rows at once (`swarm_agent.container_core`), with no Python per agent."""

    #: the arrays of one row per agent (`of` copies them)
    ROWS = ('pos', 'theta', 'u', 'step', 'silent', 'qz', 'qw', 'cos', 'sin', 'fresh', 'shared', 'radio', 'robot',
            'noisy')
    __slots__ = ROWS + ('table', 'changes')

    def __init__(self, k: int):
        self.pos = np.zeros((k, 2))
        self.theta, self.u, self.qz, self.qw, self.cos, self.sin = (np.zeros(k) for _ in range(6))
        self.step = np.zeros(k, dtype=np.int64)
        self.silent = np.zeros(k, dtype=bool)
        self.fresh = np.zeros(k, dtype=bool)
        self.shared = np.zeros(k, dtype=bool)     # the row's last u came from `table`
        self.radio = np.zeros(k, dtype=bool)      # the agent hears through a radio model (`comms`)
        self.robot = np.zeros(k, dtype=bool)      # on a MuJoCo robot in lockstep (`reported`)
        self.noisy = np.zeros(k, dtype=bool)      # draws its own noise each step
        self.table = None       # the inputs of one call's u of several rows (`SharedTable`)
        self.changes = 0        # laws and flags given to the rows' agents so far (`AgentCore.law`, comms, reported)

    @classmethod
    def of(cls, cores) -> States:
        """One bank for ``cores``: their rows copied in, each core reading and writing its row
        here from now on."""
        bank = cls(len(cores))
        for j, c in enumerate(cores):
            c.seen = c.seen               # a shared table's row becomes the core's own
            old, i = c.states, c.slot
            for name in cls.ROWS:
                getattr(bank, name)[j] = getattr(old, name)[i]
            c.states, c.slot = bank, j
        return bank

    def share(self, table, rows, cores):
        """``table`` (a `SharedTable`) gave the u of ``rows``: their `Seen` is their row of it
        from now on; a row that still read the table before gets its own `Seen` first."""
        if self.table is not None and len(rows) < len(self.shared):
            left = self.shared.copy()
            left[rows] = False
            for j in np.flatnonzero(left):
                cores[j].seen = cores[j].seen
        self.table = table
        self.shared[rows] = True

    def refresh(self, rows):
        """The quaternions and frames of ``rows`` (stale ones; None: every row, new arrays)
        from their headings: elementwise, so the same bits as one agent's alone."""
        if rows is None:
            self.qz, self.qw = quaternion_from_heading(self.theta)
            self.cos, self.sin = frame_from_quaternion(self.qz, self.qw)
            self.fresh[:] = True
            return
        qz, qw = quaternion_from_heading(self.theta[rows])
        self.qz[rows], self.qw[rows] = qz, qw
        self.cos[rows], self.sin[rows] = frame_from_quaternion(qz, qw)
        self.fresh[rows] = True


class SharedTable(NamedTuple):
    """The inputs of one u call of several agents (`States.table`): each agent's `Seen` is its
    row of it (made when asked, `AgentCore.seen`)."""
    pos: np.ndarray
    cos_t: np.ndarray
    sin_t: np.ndarray
    lam: float
    is_leader: object
    steering: np.ndarray
    target: object
    barrier: object
    alive: object
    rendezvous: object
    t: float | None


def _row(name, kind):
    """A property of `AgentCore` that is the agent's row of its bank's array ``name``: read as a
    fresh (1,) / (1, 2) array (pos, theta) or a number, written into the row."""
    if kind == 'array':
        def get(self):
            return getattr(self.states, name)[self.slot:self.slot + 1].copy()

        def put(self, value):
            getattr(self.states, name)[self.slot] = np.reshape(value, getattr(self.states, name).shape[1:])
    else:
        def get(self):
            return kind(getattr(self.states, name)[self.slot])

        def put(self, value):
            getattr(self.states, name)[self.slot] = value
    return property(get, put)


class AgentCore:
    pos = _row('pos', 'array')            # (1, 2) float64
    theta = _row('theta', 'array')        # (1,), unwrapped
    u_last = _row('u', float)
    step = _row('step', int)              # lockstep: the step whose state it holds
    silent = _row('silent', bool)         # lockstep: not in the table (frozen or killed)

    def _flag(name, row):
        """An attribute whose state its bank's row ``row`` mirrors (a container looks at one
        array, not at each agent): comms (a radio model), reported (a robot's pose)."""
        def get(self):
            return getattr(self, '_' + name)

        def put(self, value):
            setattr(self, '_' + name, value)
            getattr(self.states, row)[self.slot] = value is not None if name == 'comms' else bool(value)
            self.states.changes += 1
        return property(get, put)

    comms = _flag('comms', 'radio')       # a radio model (`attach_comms`), or None
    reported = _flag('reported', 'robot')  # lockstep on a MuJoCo robot: its pose is its row of the table
    del _flag

    @property
    def law(self):
        return self._law

    @law.setter
    def law(self, law):
        """A new law (a live parameter set): its container looks again at whether one law
        serves all its agents (`ContainerCore.one_law`)."""
        self._law = law
        self.states.changes += 1

    def __init__(self, index: int, n_agents: int, x: float, y: float, theta: float,
                 law: Law, dt: float, noise=(0.0, 0.0), noise_rng=None):
        self.index = int(index)
        self.n = int(n_agents)
        self.states, self.slot = States(1), 0         # its row (an agent container's bank: `States.of`)
        self._seen = None
        self.pos = np.array([[float(x), float(y)]])
        self.theta = np.array([float(theta)])
        self.law = law
        self.dt = float(dt)
        self.noise_scale = np.array([noise[0], noise[0], noise[1]], dtype=float)
        self.noisy = bool(np.any(self.noise_scale > 0))
        self.states.noisy[0] = self.noisy
        self.rng = noise_rng
        self.comms = None
        self.beliefs = None
        self.reported = False
        self.pairs = None                   # the law's pairs (`alive_control`): None, or the compiled sums'

    @property
    def seen(self):
        """The inputs of its last u (`Seen`, `Believed`; `trial`), or None."""
        b = self.states
        if b.shared[self.slot]:            # its row of the table, made once
            table, j = b.table, self.index
            self.seen = Seen(table.pos, table.cos_t, table.sin_t, j, table.lam, table.is_leader,
                             float(table.steering[j]), table.target, table.barrier, table.alive, table.rendezvous,
                             table.t)
        return self._seen

    @seen.setter
    def seen(self, value):
        self._seen = value
        self.states.shared[self.slot] = False

    def sums_compiled(self):
        """Sum the law's pairs in the compiled kernels (`compiled_sums`: a run's ``--compiled``),
        loaded now (`compiled_sums.warm_up`), not at the first step."""
        warm_up()
        self.pairs = lambda _pos: COMPILED

    def attach_comms(self, model: CommModel):
        """Receive through ``model`` from now on (lockstep: `comms_control`)."""
        self.comms = model
        self.beliefs = Beliefs([self.index], self.n)

    def comms_control(self, step, x, y, qz, qw, u_sent, lam, is_leader, steering_own,
                      target=None, barrier=None, alive=None, rendezvous=None, t=None):
        """u of this agent at ``step`` (sim time ``t``) from what its radio delivers of the step's table
        (x, y, qz, qw, u_sent: arrays of length N, the states of t_step as sent).

        alive (N,) bool, faults: agents out of the table send nothing (the relay still carries
        their last rows); rendezvous: the reunion of this step, as in `control`."""
        k = self.index
        xy = np.stack([np.asarray(x, float), np.asarray(y, float)], axis=1)
        arrival = self.comms.decide(step, [k], xy[k:k + 1], np.arange(self.n), xy)
        self.beliefs.receive(step, arrival, xy[:, 0], xy[:, 1], np.asarray(qz, float), np.asarray(qw, float),
                             np.asarray(u_sent, float), alive=alive)
        self.seen = Believed(step, self.pos, self.theta, lam, is_leader, float(steering_own), target, barrier,
                             rendezvous, t)
        law, target = reunion_law(self.law, target, rendezvous)
        try:
            return float(belief_controls(law, self.beliefs, step, self.comms, self.pos, self.theta, lam,
                                         is_leader, [float(steering_own)], target, barrier, t=t)[0])
        except LawError as err:       # the process stops on it (`swarm_ros.rosutil.run_node`)
            raise failed_at(err, t) from None

    # -- what the agent publishes
    @property
    def quaternion(self):
        b, j = self.states, self.slot
        if not b.fresh[j]:
            b.refresh([j])
        return float(b.qz[j]), float(b.qw[j])

    def control(self, x, y, qz, qw, lam, is_leader, steering_own, target=None, barrier=None,
                alive=None, rendezvous=None, row=None, t=None):
        """u of this agent from the table (arrays of length N in agent-index order) at sim time
        ``t`` (what a `Law`'s view reads: lockstep the step's n·dt, realtime the clock's now).

        alive (N,) bool: only these rows are in the table (this agent must be one);
        rendezvous: the reunion of this step (`swarm_core.faults.agents.reunion_law`), or None; row: this agent's
        row in the table (default: its index; realtime: its row among the agents it knows)."""
        k = self.index if row is None else int(row)
        pos, cos_t, sin_t = received_table(x, y, qz, qw, [k], [self])
        self.seen = Seen(pos, cos_t, sin_t, k, lam, is_leader, float(steering_own), target, barrier, alive,
                         rendezvous, t)
        try:
            u = alive_control(pos, cos_t, sin_t, [k], self.law, lam, is_leader, [float(steering_own)], target,
                              barrier, alive=alive, rendezvous=rendezvous, pairs=self.pairs, t=t)
        except LawError as err:       # the process stops on it (`swarm_ros.rosutil.run_node`)
            raise failed_at(err, t) from None
        return float(u[0])

    def trial(self, law: Law) -> str | None:
        """Try ``law`` on the inputs this agent's u came from last (`seen`; before its first u,
        its own state alone at λ = 0 and the time of its step): None if it gives a u, else the
        one line of its `LawError` (it raised, or gave no finite u there).  A live law
        parameter set is tried so before it is taken; nothing of the agent changes."""
        seen = self.seen
        try:
            if isinstance(seen, Believed):
                law, target = reunion_law(law, seen.target, seen.rendezvous)
                u = belief_controls(law, self.beliefs, seen.step, self.comms, seen.pos, seen.theta, seen.lam,
                                    seen.is_leader, [seen.steering], target, seen.barrier, t=seen.t)
            else:
                if seen is None:
                    c, s = self._own_frame()
                    seen = Seen(self.pos.copy(), np.array([c]), np.array([s]), 0, 0.0, None, 0.0,
                                t=self.step * self.dt)
                u = alive_control(seen.pos, seen.cos_t, seen.sin_t, [seen.row], law, seen.lam, seen.is_leader,
                                  [seen.steering], seen.target, seen.barrier, alive=seen.alive,
                                  rendezvous=seen.rendezvous, pairs=self.pairs, t=seen.t)
        except LawError as err:
            return str(err)
        if not np.all(np.isfinite(u)):
            return f'law {law.kind} gives a non-finite u ({float(u[0])!r}) on this agent\'s last table'
        return None

    def _own_frame(self):
        """(cos θ, sin θ) of the agent's own heading through its quaternion, as its neighbours
        see it (cached until the next `advance`)."""
        b, j = self.states, self.slot
        if not b.fresh[j]:
            b.refresh([j])
        return b.cos[j], b.sin[j]

    def advance(self, u: float):
        """One ZOH step with the held control u (a non-finite u is replaced by 0)."""
        if not math.isfinite(u):
            u = 0.0
        pos, theta = zoh_step(self.pos, self.theta, np.array([u]), self.dt)
        return self.moved_to(pos, theta, u)

    def place(self, x: float, y: float, theta: float, u: float):
        """Take a measured pose (a robot's odometry, model units; θ unwrapped): no integration,
        no noise draw (the robot's own motion and errors are real)."""
        self.pos = np.array([[float(x), float(y)]])
        self.theta = np.array([float(theta)])
        self.states.fresh[self.slot] = False
        self.u_last = float(u)

    def take_reported(self, x: float, y: float, qz: float, qw: float):
        """Lockstep on a MuJoCo robot: its pose of the step is its row of the step's table (the
        robot world's report): the table's quaternion is its frame, as every neighbour sees it;
        its heading (a radio model's law reads it) is unwrapped near the one before."""
        qz, qw = float(qz), float(qw)
        self.pos = np.array([[float(x), float(y)]])
        self.theta = np.array([reported_heading(qz, qw, float(self.theta[0]))])
        b, j = self.states, self.slot
        c, s = frame_from_quaternion(np.array([qz]), np.array([qw]))
        b.qz[j], b.qw[j], b.cos[j], b.sin[j] = qz, qw, c[0], s[0]
        b.fresh[j] = True

    def moved_to(self, pos, theta, u: float):
        """Take the state (pos (1, 2), θ (1,)) that one ZOH step with u gave (`advance`, or
        the batched step of a container), then the agent's own noise draw."""
        self.pos, self.theta = pos, theta
        self.states.fresh[self.slot] = False
        if self.noisy:
            draw = self.rng.uniform(-1.0, 1.0, size=3) * self.noise_scale
            self.pos = self.pos + draw[None, :2]
            self.theta = self.theta + draw[2:3]
        self.u_last = u
        return u
