"""The control step (no ROS): a step's table and the law's u of its receivers, assembled in one
place for the batch engine, every agent node and every agent container.

`alive_control`: the table holds the agents heard this step (faults: not dead, not frozen), in
index order, and a rendezvous (reunion) changes the law (`faults.agents.reunion_law`).
`belief_controls`: with a radio model (`radio`), each receiver's table is its own state and
what it believes of the others.  Either way the law (`laws.swarm_control`) sums each
receiver's row on its own, so whoever asks gets the same u bit for bit.

In three dimensions (`natural_alive_control`, `natural_belief_controls`) the same rules give
(u, v) of each receiver with `laws.natural_control`; with a radio each receiver's table is its
own (its true state and its beliefs, in agent-index order), one law call per receiver.
"""
from __future__ import annotations

import numpy as np

from swarm_core.faults.agents import reunion_law
from swarm_core.laws import natural_control, swarm_control
from swarm_core.model.frenet import heading_frame
from swarm_core.radio import Beliefs, CommModel


def alive_control(pos, cos_t, sin_t, receivers, law, lam, is_leader, steering, target=None, barrier=None,
                  alive=None, rendezvous=None, pairs=None, t=None):
    """u of the agents ``receivers`` (agent indices, ascending) at one step (eq. 4, 9-16).

    pos (N, 2), cos_t, sin_t, is_leader (N,): the states of all agents in index order (a
    receiver's row holds its own state); steering: the receivers' s_k (or None).  alive (N,)
    bool or None (all): the table holds only the agents alive, in index order; receivers not
    alive get u = 0.  rendezvous: the reunion of the step (`reunion_law`).  pairs: None (sum
    over the whole table) or a function of the table's positions giving its neighbour pairs
    (`laws.swarm_control`).  t: the sim time of the step, for a `Law`'s view.  Receivers are
    rows of the same table whoever asks, so the batch engine and every agent get the same u bit
    for bit."""
    law, target = reunion_law(law, target, rendezvous)
    receivers = np.asarray(receivers, dtype=np.intp)
    if alive is None or np.count_nonzero(alive) == len(alive):
        return swarm_control(pos, cos_t, sin_t, receivers, law, lambda_=float(lam), is_leader=is_leader,
                             steering=steering, target=target, barrier=barrier,
                             pairs=None if pairs is None else pairs(pos), t=t)
    rows = np.flatnonzero(alive)
    heard = np.asarray(alive, bool)[receivers]
    p = np.asarray(pos, float)[rows]
    u = np.zeros(receivers.size)
    u[heard] = swarm_control(p, np.asarray(cos_t)[rows], np.asarray(sin_t)[rows],
                             np.searchsorted(rows, receivers[heard]), law, lambda_=float(lam),
                             is_leader=None if is_leader is None else np.asarray(is_leader, bool)[rows],
                             steering=None if steering is None else np.asarray(steering, float)[heard],
                             target=target, barrier=barrier, pairs=None if pairs is None else pairs(p), t=t)
    return u


def belief_controls(law, beliefs: Beliefs, step: int, model: CommModel, own_xy, own_theta,
                    lambda_, is_leader, steering, target=None, barrier=None, active=None, t=None):
    """u (K,) of the receivers ``beliefs.recv`` at ``step``, each from its own true state
    (own_xy (K, 2), own_theta (K,)) and what it believes of the others (`Beliefs.known_pairs`),
    with THE law `swarm_control`, all receivers in one call: the table holds the receivers'
    own rows, then one row per believed (receiver, sender) pair, and the law sums over that
    pair list (np.bincount, each receiver's senders in index order).  A receiver's sum is
    therefore the same whichever receivers are asked with it: an agent asking for itself
    alone gets the batch engine's u bit for bit.  is_leader (N,): the step's leader flags of
    all agents; steering (K,); active (K,) bool or None: receivers out of the table (dead,
    frozen) get u = 0; t: the sim time of the step, for a `Law`'s view.  (A dead agent stays
    in the others' beliefs until its last state is older than the timeout: a receiver cannot
    know it died.)  How the law reads the table is its own (`Law.believed_controls`: a view per
    receiver, or the paper's laws' one call over the pair list)."""
    K = beliefs.recv.size
    act = slice(None) if active is None else np.flatnonzero(active)
    a, j, x, y, c, s = beliefs.known_pairs(step, model, None if active is None else act)
    own_xy = np.asarray(own_xy, float).reshape(K, 2)[act]
    m = own_xy.shape[0]
    pos = np.empty((m + a.size, 2))
    pos[:m] = own_xy
    pos[m:, 0], pos[m:, 1] = x, y
    oc, os_ = heading_frame(np.asarray(own_theta, float).reshape(K)[act])
    cos_t, sin_t = np.concatenate((oc, c)), np.concatenate((os_, s))
    flags = nearest = None
    if is_leader is not None:
        is_leader = np.asarray(is_leader, bool)
        flags = np.concatenate((is_leader[beliefs.recv[act]], is_leader[j]))
        if law.uses_leaders:
            nearest = _nearest_believed_leader(pos, a, m, flags[m:])
    u = np.zeros(K)
    u[act] = law.believed_controls(pos, cos_t, sin_t, a, m, lambda_=float(lambda_), is_leader=flags,
                                   steering=np.asarray(steering, float).reshape(K)[act], target=target,
                                   barrier=barrier, nearest=nearest, t=t)
    return u


def _nearest_believed_leader(pos, a, m, leader_pair):
    """l(k) (eq. 10) of each of the m receivers: the table row (m + pair index) of the believed
    leader nearest to it (Euclidean, as `pair_sums.nearest_leader` measures it; ties to the
    lower sender row), −1 if it believes in none."""
    out = np.full(m, -1, dtype=np.intp)
    p = np.flatnonzero(leader_pair)
    if p.size:
        d = pos[a[p]] - pos[m + p]
        d *= d
        order = np.lexsort((p, d[:, 0] + d[:, 1], a[p]))       # by receiver, distance, sender
        recv = a[p][order]
        first = np.ones(recv.size, dtype=bool)                  # the first of each receiver
        np.not_equal(recv[1:], recv[:-1], out=first[1:])
        out[recv[first]] = m + p[order[first]]
    return out


# ---------------------------------------------------------------- three dimensions

def natural_alive_control(pos, frames, receivers, law, lam, is_leader, steering, target=None, barrier=None,
                          ground=None, alive=None, rendezvous=None, t=None):
    """(u, v) (K, 2) of the agents ``receivers`` at one step in 3D: `alive_control`'s rules
    (the table holds the agents alive, in index order; receivers not alive get (0, 0); a
    rendezvous changes the law).  pos (N, 3), frames (x, y, z) (N, 3) each; steering (K, 2)."""
    law, target = reunion_law(law, target, rendezvous)
    receivers = np.asarray(receivers, dtype=np.intp)
    world = dict(target=target, barrier=barrier, ground=ground, t=t)
    if alive is None or np.count_nonzero(alive) == len(alive):
        return natural_control(pos, frames, receivers, law, lambda_=float(lam), is_leader=is_leader,
                               steering=steering, **world)
    rows = np.flatnonzero(alive)
    heard = np.asarray(alive, bool)[receivers]
    uv = np.zeros((receivers.size, 2))
    if heard.any():
        uv[heard] = natural_control(np.asarray(pos, float)[rows], tuple(np.asarray(f)[rows] for f in frames),
                                    np.searchsorted(rows, receivers[heard]), law, lambda_=float(lam),
                                    is_leader=None if is_leader is None else np.asarray(is_leader, bool)[rows],
                                    steering=None if steering is None else np.asarray(steering, float)[heard],
                                    **world)
    return uv


def natural_belief_controls(law, beliefs, step: int, model: CommModel, own_pos, own_frames, lambda_, is_leader,
                            steering, target=None, barrier=None, ground=None, active=None, t=None):
    """(u, v) (K, 2) of the receivers ``beliefs.recv`` (a `natural_radio.NaturalBeliefs`) at
    ``step``, each from its own table: its true state (own_pos (K, 3), own_frames (x, y, z) of
    (K, 3)) and what it believes of the others (`Beliefs.known_pairs`, dead-reckoned), in
    agent-index order, with the step's leader flags (N,) of those agents.  One law call per
    receiver on its table alone, so an agent asking for itself gets the same (u, v).  The nearest
    leader l(k) is the believed leader nearest to the receiver's true position.  active (K,) bool
    or None: receivers out of the table (dead, frozen) get (0, 0).  Where every receiver's
    table holds the same agents, each at its state of this very step (a radio that delivered
    all), that one table is the true one and all receivers take it in one call, as without a radio."""
    K = beliefs.recv.size
    act = np.arange(K) if active is None else np.flatnonzero(active)
    a, j, r, x, y, z = beliefs.known_pairs(step, model, None if active is None else act)
    own_pos = np.asarray(own_pos, float)
    own = tuple(np.asarray(f, float) for f in own_frames)
    steering = np.asarray(steering, float).reshape(K, 2)
    flags = np.zeros(len(beliefs.other[0]), bool) if is_leader is None else np.asarray(is_leader, bool)
    uv = np.zeros((K, 2))
    world = dict(target=target, barrier=barrier, ground=ground, t=t)
    shared = _shared_table(beliefs, step, act, a, j)
    if shared is not None:                                   # one table: the true states of this step
        rows, at_j, at_k = shared
        table = []
        for v, mine in ((r, own_pos), (x, own[0]), (y, own[1]), (z, own[2])):
            full = np.empty((rows.size, 3))
            full[at_j], full[at_k] = v, mine[act]
            table.append(full)
        uv[act] = natural_control(table[0], table[1:], at_k, law, lambda_=float(lambda_), is_leader=flags[rows],
                                  steering=steering[act], **world)
        return uv
    bounds = np.searchsorted(a, np.arange(act.size + 1))
    for i, k in enumerate(act):                              # a table per receiver
        lo, hi = bounds[i], bounds[i + 1]
        me = beliefs.recv[k]
        at = int(np.searchsorted(j[lo:hi], me))
        rows = np.insert(j[lo:hi], at, me)
        table = tuple(np.insert(v[lo:hi], at, mine[k], axis=0) for v, mine in ((r, own_pos), (x, own[0]),
                                                                               (y, own[1]), (z, own[2])))
        uv[k] = natural_control(table[0], table[1:], np.array([at]), law, lambda_=float(lambda_),
                                is_leader=flags[rows], steering=steering[k:k + 1], **world)[0]
    return uv


def _shared_table(beliefs, step, act, a, j):
    """(agent rows, table rows of the pairs' senders, table rows of the receivers) if the
    receivers ``act`` all believe the same agents (each all of them but itself) at states of
    ``step`` (age 0, so exactly what was sent), else None."""
    recv = beliefs.recv[act]
    if act.size == 0 or not np.all(beliefs.stamp[act[a], j] == step):
        return None
    rows = np.union1d(j, recv)
    if not np.all(np.bincount(a, minlength=act.size) == rows.size - 1):
        return None
    return rows, np.searchsorted(rows, j), np.searchsorted(rows, recv)
