"""The realtime tick of the agents of one process (an agent container, or a lone agent as a
container of one), without ROS.

Per tick at sim time ``now`` each agent that is not halted moves by every control period that
passed since its state (`agent_core.catch_up`, `due_periods`): a late tick never loses sim
time.  The agents that move and hear perfectly (no radio model) read ONE table,
`HeardStates`: the newest state of every agent heard within ``stale_after`` of now, the agents
of the process among them with their own states (they are heard in-process, the moment they
publish).  Their controls come from ONE call of the core law
for those receivers (`shared_controls`; `swarm_core.step.alive_control` sums each receiver's row on its
own, so every u is bit for bit the one that agent computes alone from the same heard states,
`agent_core.known_table`).  An agent with a radio model has a table of its own (what its radio
delivered, its process's other agents' states included: `hear_mates`) and a law call of its
own.  The agents then move together, one batched ZOH step per period (`ContainerCore.advance`)."""
from __future__ import annotations

import math
import signal
import threading

import numpy as np

from swarm_agent.agent_core import Seen, catch_up, received_table
from swarm_core.laws import LawError, failed_at
from swarm_core.step import alive_control
from swarm_ros.msg_checks import NewestStates


class HeardStates(NewestStates):
    """The newest state heard of every agent of the roster (`msg_checks.NewestStates`: t, x, y,
    qz, qw, u as arrays in roster order, so that a tick's table is one mask, not a loop over
    the roster; a batch of states is checked and taken at once, `take`)."""

    def __init__(self, roster, width=4, controls=()):
        self.roster = list(roster)
        self.row = {nm: i for i, nm in enumerate(self.roster)}
        super().__init__(len(self.roster), width, controls)

    def hear(self, name, state):
        """State (t, x, y, qz, qw, u) of agent ``name`` (one of the reader's own, just published)."""
        self.put(self.row[name], state[0], state[1:5], state[5])

    @property
    def newest(self):
        """name -> (t, x, y, qz, qw, u) of the agents heard (`agent_core.known_table`)."""
        return self.by_name(self.roster)

    def table(self, now, stale_after, receivers):
        """(rows, states (m, 4)): the agents heard within ``stale_after`` of ``now`` and the
        ``receivers`` (rows that are always in), in roster order."""
        keep = now - self.t <= stale_after
        keep[np.asarray(receivers, dtype=np.intp)] = True
        rows = np.flatnonzero(keep)
        return rows, self.state[rows]


def shared_controls(cores, heard: HeardStates, now, stale_after, lam, leader_mask, steering, target, barrier):
    """u (K,) of the agents ``cores`` (one law, all in ``heard`` with their own current states,
    each fresh) from one table of what they heard (eq. 4, 9-16): each agent's own row its own
    state, the others' the newest heard within ``stale_after``.  ``leader_mask`` (n,) bool
    over the roster; ``steering`` the agents' s_k."""
    own = np.array([c.index for c in cores], dtype=np.intp)
    order = np.argsort(own, kind='stable')
    rows, states = heard.table(now, stale_after, own)
    at = np.searchsorted(rows, own[order])
    pos, cos_t, sin_t = received_table(states[:, 0], states[:, 1], states[:, 2], states[:, 3], at,
                                       [cores[j] for j in order])
    flags = leader_mask[rows]
    for j, r in zip(order, at):       # what each agent's u came from (`AgentCore.trial`)
        cores[j].seen = Seen(pos, cos_t, sin_t, int(r), lam, flags, float(steering[j]), target, barrier, t=now)
    try:
        u_sorted = alive_control(pos, cos_t, sin_t, at, cores[0].law, lam, flags,
                                 np.asarray(steering, float)[order], target, barrier, t=now)
    except LawError as err:           # the process stops on it (`swarm_ros.rosutil.run_node`)
        raise failed_at(err, now) from None
    u = np.empty(len(cores))
    u[order] = u_sorted
    return u


#: realtime: an agent's default ``stale_after`` (sim s)
STALE_AFTER = 2.0
#: the longest ``stale_after`` a set may give (sim s): a neighbour killed or gone quiet stays in
#: the agent's table at most this long
STALE_AFTER_MAX = 60.0
#: the longest ``future_tolerance`` a set may give (sim s): it is how far ahead a peer's forged
#: decision or state may be stamped and still be taken (the nodes of a run share one clock)
FUTURE_TOLERANCE_MAX = 10.0


def time_limits(dt: float, default: float, hi: float) -> tuple[float, float]:
    """[lo, hi] of a realtime time parameter (``stale_after``, ``future_tolerance``) of an agent
    with control period ``dt``: from two periods (a neighbour's newest state is up to a period
    old at a tick, and the nodes' clocks differ by about one: below that the agent would refuse
    or drop the states of a healthy swarm and fly blind), never above the ``default``, to ``hi``."""
    return min(2.0 * dt, default), hi


#: the most control periods an agent integrates in one tick (`due_periods`).  A larger gap
#: between its state and the clock is no late tick: the clock started long before the agent
#: (the system clock without use_sim_time, or a run it joined late) or jumped; the agent's time
#: restarts at the clock instead (billions of periods in one callback hung the process)
CATCH_UP_MAX = 1000


def due_periods(now, times, dt, halted, limits=None):
    """([(j, periods, t_new)], [(j, t_new)]): the agents (positions j) that move at ``now`` (at
    least one period since their state of time ``times[j]``, `catch_up`), and the agents whose
    time follows the clock without a move: the ``halted`` ones (a fault froze or killed them),
    so that a frozen agent resumes with one period, not with its whole pause, and those more
    than `CATCH_UP_MAX` periods behind the clock (their time restarts at it).

    Every period that passed is flown (u held): a late tick of a starved process never loses
    sim time, so the agents fly at unit speed however late their process ticks (up to
    `CATCH_UP_MAX` periods).  Only after the process itself was stopped (SIGSTOP ... SIGCONT,
    `Continued`) does each agent move at most ``limits[j]`` periods (its ``catch_up_limit``)
    and restart its time at ``now``."""
    moving, follow = [], []
    for j, t in enumerate(times):
        periods, t_new = catch_up(now, t, dt, math.inf if limits is None else limits[j])
        if halted[j] or periods > CATCH_UP_MAX:
            if periods:
                follow.append((j, t_new))
        elif periods:
            moving.append((j, periods, t_new))
    return moving, follow


#: SIGCONT deliveries to this process (`Continued`)
_CONTINUED = [0]


def _on_sigcont(_signum, _frame):
    _CONTINUED[0] += 1


class Continued:
    """Was this process stopped and continued (SIGCONT: the world's freeze fault on a lone
    agent process, or a shell's Ctrl-Z ... fg) since the last call?  A starved process is
    late but never continued, so its agents fly every period it missed (`due_periods`).
    Installs the process's SIGCONT handler (from the main thread; elsewhere none is seen)."""

    def __init__(self):
        main = threading.current_thread() is threading.main_thread()
        if main and signal.getsignal(signal.SIGCONT) is not _on_sigcont:
            signal.signal(signal.SIGCONT, _on_sigcont)
        self.seen = _CONTINUED[0]

    def __call__(self) -> bool:
        was, self.seen = self.seen != _CONTINUED[0], _CONTINUED[0]
        return was


def hear_mates(agents, sent):
    """Each agent of the process with a radio model (not halted) hears ``sent``, [(index, state)]:
    the new states of the process's other agents, as the radio hears a state (t, x, y, qz, qw, u;
    3D t, r, x, y, z, u, v), through its radio.  They never come back over DDS (a process
    drops its own batch), so without this a radio agent would fly as if its container-mates did
    not exist.  A lone agent has no one to hear."""
    for a in agents:
        if a.radio_on and a.halted is None:
            core, stream = a.core, a.driver.stream
            own = core.states.pos[core.slot]
            for i, state in sent:
                if i != a.index:
                    stream.hear(i, state, own)


def advance_periods(lock, go, periods, us):
    """Move the agents ``go`` (positions in ``lock``, a `ContainerCore`) by ``periods`` ZOH
    steps each with u held: one batched step per period for those still moving."""
    periods = np.asarray(periods)
    us = np.asarray(us, float)
    for p in range(int(periods.max()) if len(periods) else 0):
        still = periods > p
        lock.advance([go[i] for i in np.flatnonzero(still)], list(us[still]))
