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


class AgentCore:
    def __init__(self, index: int, n_agents: int, x: float, y: float, theta: float,
                 law: Law, dt: float, noise=(0.0, 0.0), noise_rng=None):
        self.index = int(index)
        self.n = int(n_agents)
        self.pos = np.array([[float(x), float(y)]])
        self.theta = np.array([float(theta)])
        self.law = law
        self.dt = float(dt)
        self.noise_scale = np.array([noise[0], noise[0], noise[1]], dtype=float)
        self.noisy = bool(np.any(self.noise_scale > 0))
        self.rng = noise_rng
        self.u_last = 0.0
        self.comms = None
        self.beliefs = None
        self._frame = None                  # own (cos θ, sin θ), see `_own_frame`
        self._quat = None                   # own (qz, qw) as published (cached until it moves)
        self.step = 0                       # lockstep: the step whose state it holds
        self.silent = False                 # lockstep: not in the table (frozen or killed)
        self.reported = False               # lockstep on a MuJoCo robot: its pose is its row of the table
        self.seen = None                    # the inputs of its last u (`Seen`, `Believed`; `trial`)

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
        if self._quat is None:
            qz, qw = quaternion_from_heading(self.theta)
            self._quat = (float(qz[0]), float(qw[0]))
        return self._quat

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
                              barrier, alive=alive, rendezvous=rendezvous, t=t)
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
                                  rendezvous=seen.rendezvous, t=seen.t)
        except LawError as err:
            return str(err)
        if not np.all(np.isfinite(u)):
            return f'law {law.kind} gives a non-finite u ({float(u[0])!r}) on this agent\'s last table'
        return None

    def _own_frame(self):
        """(cos θ, sin θ) of the agent's own heading through its quaternion, as its neighbours
        see it (cached until the next `advance`)."""
        if self._frame is None:
            c, s = frame_from_quaternion(*quaternion_from_heading(self.theta))
            self._frame = (c[0], s[0])
        return self._frame

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
        self._frame = self._quat = None
        self.u_last = float(u)

    def take_reported(self, x: float, y: float, qz: float, qw: float):
        """Lockstep on a MuJoCo robot: its pose of the step is its row of the step's table (the
        robot world's report): the table's quaternion is its frame, as every neighbour sees it;
        its heading (a radio model's law reads it) is unwrapped near the one before."""
        qz, qw = float(qz), float(qw)
        self.pos = np.array([[float(x), float(y)]])
        self.theta = np.array([reported_heading(qz, qw, float(self.theta[0]))])
        self._quat = (qz, qw)
        c, s = frame_from_quaternion(np.array([qz]), np.array([qw]))
        self._frame = (c[0], s[0])

    def moved_to(self, pos, theta, u: float):
        """Take the state (pos (1, 2), θ (1,)) that one ZOH step with u gave (`advance`, or
        the batched step of a container), then the agent's own noise draw."""
        self.pos, self.theta = pos, theta
        self._frame = self._quat = None
        if self.noisy:
            draw = self.rng.uniform(-1.0, 1.0, size=3) * self.noise_scale
            self.pos = self.pos + draw[None, :2]
            self.theta = self.theta + draw[2:3]
        self.u_last = u
        return u
