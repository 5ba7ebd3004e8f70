"""The radio model in three dimensions (no ROS): what each agent believes of the others.

The fates of the messages are the planar radio's (`radio.CommModel`: loss, latency, jitter,
partitions, events; the radio range is a distance in space).  What a message carries is the
sender's 3D state: its position r, its natural frame [x y z] and the curvatures (u, v) it held
over the step that ended at t_n.  `NaturalBeliefs` keeps, per (receiver, sender), the newest
state received, as `radio.Beliefs` does; with ``dead_reckoning`` a belief of t_m is predicted to
t_n on the exact arc of unit speed with its frame and (u, v) held (`model.natural.natural_step`
with dt = t_n − t_m).  The frame is carried as it is (9 numbers, not a quaternion), so a belief
of age 0 is the sender's true state bit for bit.  A realtime agent hears through a
`NaturalStreamRadio`: the fates of `radio.StreamRadio`, 3D states dead-reckoned the same way.
"""
from __future__ import annotations

import numpy as np

from swarm_core.model.natural import natural_step
from swarm_core.radio import Beliefs, StreamRadio

#: rows of a 3D state message: r (0-2), x (3-5), y (6-8), z (9-11), u (12), v (13)
R, X, Y, Z, U, V = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), 12, 13


def natural_states(pos, x, y, z, uv) -> np.ndarray:
    """The messages (14, N) of N agents: position, frame and the (u, v) they held."""
    uv = np.asarray(uv, float)
    return np.concatenate((pos.T, x.T, y.T, z.T, uv.T), axis=0)


def natural_dead_reckon(r, x, y, z, u, v, horizon):
    """States predicted ``horizon`` (R,) sim seconds ahead at unit speed with (u, v) held, on the
    exact arc (`natural_step`, elementwise, so a row's prediction is the same whichever rows
    come with it); rows with horizon 0 are returned unchanged.  Returns (r, x, y, z)."""
    r, x, y, z = (np.array(a, float) for a in (r, x, y, z))
    for h in np.unique(horizon[horizon > 0]):           # one call per age, not per message
        rows = np.flatnonzero(horizon == h)
        r[rows], x[rows], y[rows], z[rows] = natural_step(r[rows], x[rows], y[rows], z[rows], u[rows], v[rows],
                                                          float(h))
    return r, x, y, z


class NaturalBeliefs(Beliefs):
    """`Beliefs` of 3D states: per (receiver, sender) the newest r, [x y z] and (u, v) received."""

    FIELDS = 14

    def _predicted(self, step, model, rows, j, age):
        """(r, x, y, z), each (R, 3), of the beliefs (rows, j) of the given ages, dead-reckoned to
        t_step if the model says so."""
        st = self.state[:, rows, j]
        r, x, y, z = st[R].T, st[X].T, st[Y].T, st[Z].T
        if model.dead_reckoning and np.any(age > 0):
            r, x, y, z = natural_dead_reckon(r, x, y, z, st[U], st[V], age * model.dt)
        return r, x, y, z


class NaturalStreamRadio(StreamRadio):
    """`StreamRadio` of 3D states (t, r, x, y, z, u, v): the fate by the distance in space, and
    each belief dead-reckoned on the exact arc of its (u, v) (`natural_dead_reckon`)."""

    POSITION, CONTROLS = slice(1, 4), 2

    def _dead_reckon(self, st, age, moved):
        r, x, y, z = natural_dead_reckon(st[:, 1:4], st[:, 4:7], st[:, 7:10], st[:, 10:13], st[:, 13], st[:, 14],
                                         np.where(moved, age, 0.0))
        st[:, 1:13] = np.concatenate([r, x, y, z], axis=1)
