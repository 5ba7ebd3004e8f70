"""A run's trajectory: the batch engine's output and the world node's record of a ROS run.

`Trajectory` is what every engine writes (``trajectory.npz``).  `TrajectoryRecorder` holds the
rows a ROS world fills as the agents' states arrive, and rebuilds a `Trajectory` from them:
held states between realtime stamps, frozen agents, and headings unwrapped in time.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from swarm_core.files import atomic_open
from swarm_core.model.frenet import yaw_from_quaternion


@dataclass
class Trajectory:
    """A run: samples at t = n·dt (every ``record_every`` steps), n = 0 … steps."""

    names: list
    t: np.ndarray          # (T,)
    r: np.ndarray          # (T, n, 2) positions; (T, n, 3) in 3D
    theta: np.ndarray      # (T, n)    headings; None in 3D
    u: np.ndarray          # (T, n)    the control applied from that sample on
    lam: np.ndarray        # (T,)      λ
    leader: np.ndarray     # (T, n)    bool, leader flags
    meta: dict = field(default_factory=dict)
    x: np.ndarray | None = None    # 3D: the frames x, y, z (T, n, 3) and the second control v (T, n)
    y: np.ndarray | None = None
    z: np.ndarray | None = None
    v: np.ndarray | None = None

    @property
    def dim(self) -> int:
        """2 (planar) or 3."""
        return 2 if self.x is None else 3

    def save(self, path):
        """Write ``path`` atomically (a temporary file in the same directory, then renamed):
        a failed write (full disk) leaves no partial or 0-byte file behind.  A 3D run holds
        x, y, z and v in place of theta."""
        if self.x is None:
            states = dict(theta=self.theta)
        else:
            states = dict(x=self.x, y=self.y, z=self.z, v=self.v)
        with atomic_open(path, 'wb') as fh:
            np.savez_compressed(fh, t=self.t, r=self.r, **states, u=self.u, lam=self.lam,
                                leader=self.leader, names=np.array(self.names))
        return path

    @classmethod
    def load(cls, path):
        with np.load(path) as z:
            frames = {k: z[k] for k in ('x', 'y', 'z', 'v') if k in z.files}
            return cls(names=[str(s) for s in z['names']], t=z['t'], r=z['r'],
                       theta=z['theta'] if 'theta' in z.files else None,
                       u=z['u'], lam=z['lam'], leader=z['leader'], **frames)

    def head(self, rows: int) -> 'Trajectory':
        """The first ``rows`` samples (an interrupted run's part)."""
        cut = {k: None if getattr(self, k) is None else getattr(self, k)[:rows] for k in ('x', 'y', 'z', 'v')}
        return Trajectory(self.names, self.t[:rows], self.r[:rows], None if self.theta is None else self.theta[:rows],
                          self.u[:rows], self.lam[:rows], self.leader[:rows], meta=dict(self.meta, interrupted=True),
                          **cut)


class TrajectoryRecorder:
    """Rows of a ROS run as the world receives them (NaN until known).

    Lockstep fills whole steps (`record_states`, `record_decision`, `record_u`); realtime fills
    one agent's sample at a time (`record_realtime`).  Frozen agents (faults) hold the state of
    their freeze step: `freeze` notes the window, `hold` the state the agent sent at it."""

    def __init__(self, names, steps: int, dt: float, theta0, realtime: bool = False):
        self.names = list(names)
        self.n = len(self.names)
        self.steps = steps
        self.dt = dt
        self.theta0 = np.asarray(theta0, float)
        self.realtime = realtime
        T = steps + 1
        self.r = np.full((T, self.n, 2), np.nan)
        self.theta = np.full((T, self.n), np.nan)
        self.u = np.zeros((T, self.n))
        self.lam = np.full(T, np.nan) if realtime else np.zeros(T)
        self.leader = np.zeros((T, self.n), bool)
        self.freezes = []          # (agent index, k0, k1)
        self.held = {}             # frozen agent index → (step, (x, y, qz, qw), u)
        self.lost = {}             # agent index → the step it is gone from (`mark_lost`)

    # ------------------------------------------------------------------ lockstep rows
    def record_states(self, k, mask, x, y, qz, qw):
        """Positions and headings of the agents in ``mask`` at step k."""
        self.r[k, mask, 0], self.r[k, mask, 1] = x[mask], y[mask]
        self.theta[k, mask] = yaw_from_quaternion(qz[mask], qw[mask])

    def record_u(self, k, mask, u):
        """u_k (held over step k → k+1) of the agents in ``mask``; ignored outside the run."""
        if 0 <= k <= self.steps:
            self.u[k, mask] = u[mask]

    def record_decision(self, k, lam, leaders):
        self.lam[k], self.leader[k] = lam, leaders

    def mark_lost(self, i, k):
        """Agent i is gone from step k on: its u is unknown from u_{k-1} (realtime: and its
        state, not held from its last one)."""
        self.lost[i] = min(int(k), self.lost.get(i, int(k)))
        if k > 0:
            self.u[k - 1:, i] = np.nan

    # ------------------------------------------------------------------ realtime rows
    def record_realtime(self, i, k, vals, u, lam, leaders):
        """The states (x, y, qz, qw) of agents ``i`` (distinct) stamped at steps ``k``, with the
        u they carry and the λ and leaders seen then (arrays, or one of each)."""
        i, k, u = np.atleast_1d(i), np.atleast_1d(k), np.atleast_1d(u)
        vals = np.atleast_2d(np.asarray(vals, float))
        keep = (k >= 0) & (k <= self.steps)
        i, k, vals, u = i[keep], k[keep], vals[keep], u[keep]
        self.lam[k] = lam
        self.leader[k] = leaders
        self.r[k, i] = vals[:, :2]
        self.theta[k, i] = yaw_from_quaternion(vals[:, 2], vals[:, 3])
        after = k > 0
        self.u[k[after] - 1, i[after]] = u[after]

    # ------------------------------------------------------------------ faults
    def freeze(self, i, k0, k1):
        self.freezes.append((i, int(k0), int(k1)))

    def hold(self, i, k, vals, u):
        """The state frozen agent i sent at its freeze step k (and the u that brought it there)."""
        self.held[i] = (k, tuple(vals), u)
        if 0 < k <= self.steps:
            self.u[k - 1, i] = u

    def frozen_state(self, i, k0):
        """(position, θ) agent i held while frozen from step k0, if known."""
        if i in self.held and self.held[i][0] == k0:
            x, y, qz, qw = self.held[i][1]
            return np.array([x, y]), float(yaw_from_quaternion(qz, qw))
        k1 = next((b for a, s0, b in self.freezes if a == i and s0 == k0), None)
        if k1 is None or k1 > self.steps or not np.isfinite(self.r[k1, i]).all():
            return None
        return self.r[k1, i].copy(), float(self.theta[k1, i])

    # ------------------------------------------------------------------ rebuild
    def trajectory(self, meta=None) -> Trajectory:
        T = self.steps + 1
        r, theta, lam, leader = self.r.copy(), self.theta.copy(), self.lam.copy(), self.leader.copy()
        if self.realtime:        # hold each agent's last published state between its stamps
            if not np.isfinite(lam[0]):
                lam[0] = 0.0
            for k in range(1, T):
                miss = ~np.isfinite(theta[k])
                r[k, miss], theta[k, miss] = r[k - 1, miss], theta[k - 1, miss]
                if not np.isfinite(lam[k]):       # no state recorded at step k
                    lam[k], leader[k] = lam[k - 1], leader[k - 1]
            for i, k in self.lost.items():       # a lost agent is not held where it died
                r[max(k, 0):, i], theta[max(k, 0):, i] = np.nan, np.nan
        for i, k0, k1 in self.freezes:           # a frozen agent holds its freeze-step state
            src = self.frozen_state(i, k0)
            if src is not None:
                r[k0:min(k1, T), i] = src[0]
                theta[k0:min(k1, T), i] = src[1]
        theta = unwrap_headings(theta, self.theta0)
        return Trajectory(list(self.names), np.arange(T) * self.dt, r, theta, self.u.copy(), lam, leader,
                          meta=dict(meta or {}))


def unwrap_headings(theta, theta0):
    """Headings travel as quaternions (θ mod 2π): unwrap each agent in time over its finite
    samples, starting at the scenario's θ0."""
    theta = np.array(theta, float)
    good = np.all(np.isfinite(theta), axis=1)
    if good.all():
        theta = np.unwrap(theta, axis=0)
        return theta + np.round((theta0 - theta[0]) / (2 * np.pi)) * 2 * np.pi
    for i in range(theta.shape[1]):
        ok = np.isfinite(theta[:, i])
        if ok.any():
            col = np.unwrap(theta[ok, i])
            theta[ok, i] = col + np.round((theta0[i] - col[0]) / (2 * np.pi)) * 2 * np.pi
    return theta
