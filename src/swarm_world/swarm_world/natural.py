"""The world of a 3D run (``dim: 3``), without ROS: its lockstep barrier, record and checks.

The agents send r and the frame [x y z] exactly (`swarm_ros.layouts.NaturalAgentStates`); the
barrier holds them as (4, N, 3) (r, x, y, z) and (u, v) as (N, 2), decides each step with the
scenario's plan on the positions in space and the headings x seen from above (as
`swarm_core.engine.natural` calls it), and relays them in one `NaturalStep`.  The record is
what `engine.natural` writes: r, x, y, z (T, N, 3), u and v (T, N).
"""
from __future__ import annotations

import numpy as np

from swarm_core.analysis import metrics as M
from swarm_core.engine.trajectory import Trajectory
from swarm_ros.layouts import NaturalStep
from swarm_ros.msg_checks import check_natural_pose
from swarm_world.lockstep import LockstepBarrier


class NaturalBarrier(LockstepBarrier):
    """`LockstepBarrier` of a 3D run: states (4, N, 3), (u, v) (N, 2); ``ground`` the floor's
    height (or None) relayed with the target and barrier."""

    def __init__(self, *args, ground=None, **kw):
        super().__init__(*args, **kw)
        self.buf = np.zeros((4, self.n, 3))          # r, x, y, z of step cur
        self.buf_u = np.zeros((self.n, 2))           # (u, v)_{cur−1}
        self.ground = ground

    def _decide(self, t, alive):
        """The plan on the positions in space and the headings' (x, y) (`engine.natural`)."""
        r, x = self.buf[0], self.buf[1]
        return self.decide(t, r.copy(), x[:, 0].copy(), x[:, 1].copy(), alive.copy())

    def message(self, k, t, d, alive):
        target, barrier = self.geometry()
        return NaturalStep(k, t, d.lam, d.flags, np.asarray(d.steering, float).reshape(-1, 2), self.buf.copy(),
                           self.buf_u.copy(), alive.copy(), target, barrier, self.ground, d.rendezvous)


class NaturalRecorder:
    """The rows of a 3D lockstep run as the world receives them (NaN until known): r, x, y, z
    (T, n, 3), (u, v) (T, n, 2), λ and the leaders; frozen agents hold their freeze-step state."""

    def __init__(self, names, steps: int, dt: float, realtime: bool = False):
        self.names = list(names)
        self.n, self.steps, self.dt, self.realtime = len(self.names), steps, dt, realtime
        T = steps + 1
        self.r, self.x, self.y, self.z = (np.full((T, self.n, 3), np.nan) for _ in range(4))
        self.u = np.zeros((T, self.n, 2))
        self.lam = np.full(T, np.nan) if realtime else np.zeros(T)
        self.leader = np.zeros((T, self.n), bool)
        self.freezes, self.held, self.lost = [], {}, {}

    @property
    def theta(self):
        """Headings seen from above (T, n): atan2 of x's (y, x) components (the view's)."""
        return np.arctan2(self.x[..., 1], self.x[..., 0])

    def record_states(self, k, mask, r, x, y, z):
        for rows, v in ((self.r, r), (self.x, x), (self.y, y), (self.z, z)):
            rows[k, mask] = v[mask]

    def record_u(self, k, mask, u):
        if 0 <= k <= self.steps:
            self.u[k, mask] = u[mask]

    def record_decision(self, k, lam, leaders):
        self.lam[k], self.leader[k] = lam, leaders

    def mark_lost(self, i, k):
        self.lost[i] = min(int(k), self.lost.get(i, int(k)))
        if k > 0:
            self.u[k - 1:, i] = np.nan

    def record_realtime(self, i, k, vals, u, lam, leaders):
        """Realtime: the states (r, x, y, z as 12 numbers) of agents ``i`` stamped at steps ``k``,
        with the (u, v) they carry and the λ and leaders seen then."""
        i, k = np.atleast_1d(i), np.atleast_1d(k)
        vals, u = np.atleast_2d(np.asarray(vals, float)), np.asarray(u, float).reshape(-1, 2)
        keep = (k >= 0) & (k <= self.steps)
        i, k, vals, u = i[keep], k[keep], vals[keep], u[keep]
        self.lam[k], self.leader[k] = lam, leaders
        for c, rows in enumerate((self.r, self.x, self.y, self.z)):
            rows[k, i] = vals[:, 3 * c:3 * c + 3]
        after = k > 0
        self.u[k[after] - 1, i[after]] = u[after]

    def _hold_between_stamps(self, rows):
        """Realtime: each agent's last published state held between its stamps (not where it
        died), λ and the leaders likewise."""
        lam, leader = self.lam.copy(), self.leader.copy()
        if not np.isfinite(lam[0]):
            lam[0] = 0.0
        for k in range(1, self.steps + 1):
            miss = ~np.isfinite(rows[0][k]).all(axis=1)
            for a in rows:
                a[k, miss] = a[k - 1, miss]
            if not np.isfinite(lam[k]):
                lam[k], leader[k] = lam[k - 1], leader[k - 1]
        for i, k in self.lost.items():
            for a in rows:
                a[max(k, 0):, i] = np.nan
        return lam, leader

    def freeze(self, i, k0, k1):
        self.freezes.append((i, int(k0), int(k1)))

    def hold(self, i, k, vals, u):
        self.held[i] = (k, np.array(vals, float), u)
        if 0 < k <= self.steps:
            self.u[k - 1, i] = u

    def trajectory(self, meta=None) -> Trajectory:
        rows = [a.copy() for a in (self.r, self.x, self.y, self.z)]
        T = self.steps + 1
        lam, leader = self._hold_between_stamps(rows) if self.realtime else (self.lam.copy(), self.leader.copy())
        for i, k0, k1 in self.freezes:           # a frozen agent holds its freeze-step state
            if i in self.held and self.held[i][0] == k0:
                held = self.held[i][1]
            elif k1 <= self.steps and np.isfinite(self.r[k1, i]).all():     # the state it resumed with
                held = [a[k1, i] for a in (self.r, self.x, self.y, self.z)]
            else:
                continue
            for a, v in zip(rows, held):
                a[k0:min(k1, T), i] = v
        r, x, y, z = rows
        return Trajectory(list(self.names), np.arange(T) * self.dt, r, None, self.u[..., 0].copy(), lam, leader,
                          meta=dict(meta or {}, dim=3), x=x, y=y, z=z, v=self.u[..., 1].copy())


def check_natural_states(index, state, n, topic):
    """Why a decoded 3D ``/lockstep/agent_states`` (`NaturalAgentStates`, every value finite)
    must be rejected as a whole (a `Reason`), or None: `msg_checks.check_natural_pose` of its
    states (4, K, 3) as 12 rows."""
    return check_natural_pose(index, state.transpose(0, 2, 1).reshape(12, -1), n, topic)


def natural_check(obs, t, pos, names, barrier=None, ground=None):
    """`observe.Observer.check` in space: (minimum distance, complaints); intrusions are inside
    the barrier's hull or below the ground."""
    md = M.min_distance(pos)
    out = []
    if md < obs.collision_distance:
        obs.collisions += 1
        out.append(('collision', f'nothing: collision at t={t:.2f} (min distance {md:.4f})'))
    inside = np.zeros(len(pos), bool)
    if barrier is not None:
        inside |= barrier.inside(pos)
    if ground is not None:
        inside |= pos[:, 2] < ground
    if inside.any():
        names = names() if callable(names) else names
        obs.intrusions += int(inside.sum())
        out.append(('intrusion', f'nothing: barrier or ground intrusion at t={t:.2f} by '
                    + ', '.join(names[i] for i in np.flatnonzero(inside))))
    return md, out


def natural_newest(heard, keep=None):
    """Realtime: positions and frames (x, y, z), (m, 3) each, of the agents heard (``heard``: a
    `NewestStates` of width 12) and in ``keep``, in roster order."""
    have = np.isfinite(heard.t) if keep is None else np.isfinite(heard.t) & keep
    s = heard.state[have]
    return s[:, 0:3], (s[:, 3:6], s[:, 6:9], s[:, 9:12])


def natural_view(t, pos, headings, w, md, lam, leader_names, target=None, **extra) -> dict:
    """The metric values of one 3D sample: clusters in space, polarisation |mean_k x_k|."""
    clusters, _ = M.cluster_labels_3d(pos, w)
    vals = dict(t=t, clusters=clusters, polarisation=float(np.linalg.norm(headings.mean(axis=0))),
                min_distance=md, **{'lambda': lam}, leaders=','.join(leader_names), agents=len(pos), **extra)
    if target is not None:
        vals['centroid_target_distance'] = float(np.linalg.norm(pos.mean(0) - target))
    return vals
