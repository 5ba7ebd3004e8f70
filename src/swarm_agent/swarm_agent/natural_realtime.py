"""The realtime tick of a 3D run's agents (``dim: 3``), without ROS: `process_io.realtime_tick`'s
rules over a `natural_core.NaturalContainerCore`.

Per tick each agent that is not halted flies every control period that passed since its state
(`realtime_core.due_periods`), (u, v) held.  The agents of the process read ONE table of what
they heard (`realtime_core.HeardStates` of width 12: r, x, y, z; their own rows their own
states) and get (u, v) from one `natural_alive_control` call for their rows; then one batched
`natural_step` per period, Gram-Schmidt after each tick's move, and each agent publishes its
state; the process sends them in one ``/swarm/agent_states`` message (`NaturalProcessStates`).
An agent with a radio model has a table of its own: what its radio (`natural_radio.NaturalStreamRadio`)
delivered of the states heard, its process's other agents' included, dead-reckoned to now; and a
law call of its own.  A realtime run is not bit for bit: the table is what was heard when the tick came.
"""
from __future__ import annotations

import numpy as np

from swarm_agent.realtime_core import HeardStates, due_periods, hear_mates
from swarm_core.laws import LawError, failed_at
from swarm_core.model.natural import orthonormalise
from swarm_core.step import natural_alive_control
from swarm_ros.rosutil import fail


def natural_heard(roster) -> HeardStates:
    """The newest states heard of a 3D run's agents: r, x, y, z (12) and (u, v)."""
    return HeardStates(roster, width=12, controls=(2,))


def own_state(core):
    """(r, x, y, z) of an agent's row as 12 numbers, and its (u, v)."""
    b, j = core.states, core.slot
    return np.concatenate([b.pos[j], b.x[j], b.y[j], b.z[j]]), np.array([b.u[j], b.v[j]])


def hear_own(heard, agent):
    """The agent's state just published, heard by its own process."""
    state, uv = own_state(agent.core)
    heard.put(agent.index, agent.t, state, uv)


def natural_controls(lock, go, heard, now, stale, lam, flags, steering, target, barrier, ground=None):
    """(u, v) (len(go), 2) of the agents ``go`` from the table they heard within ``stale``."""
    rows, states = heard.table(now, stale, lock.rows[go])
    return table_controls(lock, go, rows, states, now, lam, flags, steering, target, barrier, ground)


def radio_controls(lock, agent, j, now, lam, flags, steering, target, barrier, ground=None):
    """(u, v) (1, 2) of ``agent`` (position j in ``lock``) from what its radio delivered."""
    state, _ = own_state(agent.core)
    rows, states = agent.driver.stream.table(now, state)
    return table_controls(lock, np.array([j]), rows, states, now, lam, flags, steering, target, barrier, ground)


def table_controls(lock, go, rows, states, now, lam, flags, steering, target, barrier, ground=None):
    """(u, v) (len(go), 2) of the agents ``go`` from the table of agents ``rows`` (states (m, 12):
    r, x, y, z), their own rows their own states."""
    b = lock.bank
    own = lock.rows[go]
    pos, x, y, z = (np.ascontiguousarray(states[:, 3 * c:3 * c + 3]) for c in range(4))
    at = np.searchsorted(rows, own)
    pos[at], x[at], y[at], z[at] = b.pos[go], b.x[go], b.y[go], b.z[go]
    law = lock.cores[go[0]].law
    try:
        return natural_alive_control(pos, (x, y, z), at, law, lam, flags[rows], steering, target, barrier, ground,
                                     t=now)
    except LawError as err:           # the process stops on it (`swarm_ros.rosutil.run_node`)
        raise failed_at(err, now) from None


def natural_realtime_tick(agents, lock, heard, leader_mask, batch, continued):
    """One realtime tick of a 3D run's agents of a process (see the module docstring)."""
    a0 = agents[0]
    now = a0._now()
    limits = [a.driver.catch_up_limit for a in agents] if continued() else None
    moving, follow = due_periods(now, [a.t for a in agents], a0.dt, [a.halted is not None for a in agents], limits)
    for j, t_new in follow:
        agents[j].t = t_new
    if not moving:
        return
    go = np.array([j for j, _, _ in moving], dtype=np.intp)
    periods = np.array([p for _, p, _ in moving])
    steering = np.array([np.broadcast_to(np.asarray(agents[j].steering, float), 2) for j in go])
    flags = leader_mask(a0.leaders)
    radio = np.array([agents[j].radio_on for j in go])
    uv = np.zeros((go.size, 2))
    try:
        if not radio.all():
            uv[~radio] = natural_controls(lock, go[~radio], heard, now, a0.driver.stale_after, a0.lam, flags,
                                          steering[~radio], a0.target, a0.barrier, a0.ground)
        for i in np.flatnonzero(radio).tolist():      # a radio model: each its own table
            uv[i] = radio_controls(lock, agents[go[i]], go[i], now, a0.lam, flags, steering[i:i + 1], a0.target,
                                   a0.barrier, a0.ground)[0]
    except LawError as err:           # the agents' law failed: the process stops with one line
        fail(err)
        return
    for i in np.flatnonzero(~np.isfinite(uv).all(axis=1)):
        agents[go[i]].reject('u-nan', f'non-finite control (u, v)={uv[i].tolist()}; holding (0, 0)')
        uv[i] = 0.0
    lock.step_n = None                         # realtime: Gram-Schmidt after each tick's move
    for p in range(int(periods.max())):
        still = periods > p
        lock.advance(go[still], uv[still])
    b = lock.bank
    b.x[go], b.y[go], b.z[go] = orthonormalise(b.x[go], b.y[go])
    for (j, n_periods, t_new), (u, v) in zip(moving, uv.tolist()):
        a = agents[j]
        for _ in range(n_periods):
            a.applied((u, v))
        a.step += n_periods
        a.t = t_new
        a.publish_state()
        hear_own(heard, a)
    if radio.any() and len(agents) > 1:
        hear_mates(agents, [(a.index, (a.t, *np.concatenate(own_state(a.core)))) for a in (agents[j] for j in go)])
    batch.publish([agents[j] for j in go])
