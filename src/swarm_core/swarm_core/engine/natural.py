"""The batch engine in three dimensions (no ROS): a 3D scenario's swarm in numpy arrays.

Each step, as the planar engine (`reference`) does it: the commander plan gives λ, the leaders
and s_k = (s_u, s_v) from the states of t_n (the leader rule reads the positions and headings
seen from above: "lateral" is along e_z × the mean heading); the law gives (u_k, v_k)
(`laws.natural_control`); every agent moves by the exact zero-order-hold step
(`model.natural.natural_step`, Gram-Schmidt every `ORTHONORMALISE_EVERY` steps) or by RK4.
Faults, the radio, noise and live commands are planar only (the loader refuses them in 3D).
"""
from __future__ import annotations

import time

import numpy as np

from swarm_core.engine.trajectory import Trajectory
from swarm_core.faults.agents import event_names
from swarm_core.laws import LawError, LawFailed, natural_control
from swarm_core.model.integrate import chosen_integrator
from swarm_core.model.natural import ORTHONORMALISE_EVERY, natural_rk4_step, natural_step, orthonormalise


class NaturalStepper:
    """Steps a 3D scenario's swarm: positions (N, 3) and frames x, y, z (N, 3)."""

    def __init__(self, scn, integrator: str | None = None):
        self.scn = scn
        self.law = scn.law
        self.integrator = chosen_integrator(integrator or scn.spec.integrator)
        self.n = len(scn.names)
        self.dt = scn.dt
        self.pos = scn.pos0.copy()
        self.x, self.y, self.z = (f.copy() for f in scn.frames0)
        self.plan = scn.command_plan()
        self.receivers = np.arange(self.n)
        self.step_index = 0
        self.events = []

    def control(self, t, pos, frames, lam, is_leader, steering):
        """(u, v) (N, 2) of every agent."""
        return natural_control(pos, frames, self.receivers, self.law, lambda_=lam, is_leader=is_leader,
                               steering=steering, target=self.scn.target, barrier=self.scn.barrier,
                               ground=self.scn.ground, t=t)

    def inputs(self):
        """t, λ, leader flags (n,) and steering (n, 2) of the current step (the commander's job)."""
        t = self.step_index * self.dt
        lam, leaders, steering = self.plan.update(t, self.pos[:, :2], self.x[:, 0], self.x[:, 1])
        self.events.extend(event_names(ev, self.scn.names) for ev in self.plan.events)
        is_leader = np.zeros(self.n, dtype=bool)
        is_leader[leaders] = True
        return t, lam, is_leader, steering

    def advance(self, t, uv, is_leader):
        if self.integrator == 'zoh':
            self.pos, self.x, self.y, self.z = natural_step(self.pos, self.x, self.y, self.z, uv[:, 0], uv[:, 1],
                                                            self.dt)
            if (self.step_index + 1) % ORTHONORMALISE_EVERY == 0:
                self.x, self.y, self.z = orthonormalise(self.x, self.y)
        else:
            def control(tt, p, x, y, z):
                # λ and s_k at the stage time; the leaders stay as chosen at t_n
                steer = np.zeros((self.n, 2))
                for idx, prog in self.plan.leaders.items():
                    steer[idx] = prog.value(tt, p[idx], None)
                return self.control(tt, p, (x, y, z), float(self.plan.schedule.value(tt)), is_leader, steer)
            self.pos, self.x, self.y, self.z = natural_rk4_step(self.pos, self.x, self.y, self.z, t, self.dt, control)
        self.step_index += 1


def simulate(scn, *, integrator: str | None = None, record_every: int = 1, progress=None, **unused) -> Trajectory:
    """Run a 3D scenario to its duration: a `Trajectory` with r, x, y, z (T, n, 3) and u, v (T, n).
    ``progress(step, steps)`` is called now and then; a law that fails raises `LawFailed` with
    the steps done, Ctrl-C keeps them (``meta['interrupted']``)."""
    stepper = NaturalStepper(scn, integrator)
    steps, n = scn.steps, stepper.n
    n_rec = steps // record_every + 1
    rec = {k: np.empty((n_rec, n, 3)) for k in ('r', 'x', 'y', 'z')}
    uv_rec = np.empty((n_rec, n, 2))
    t_rec, lam_rec = np.empty(n_rec), np.empty(n_rec)
    lead_rec = np.zeros((n_rec, n), dtype=bool)
    wall, report_every = time.perf_counter(), max(1, steps // 100)
    recorded, interrupted, failed = 0, False, None
    try:
        for i in range(steps + 1):
            t, lam, is_leader, steering = stepper.inputs()
            uv = stepper.control(t, stepper.pos, (stepper.x, stepper.y, stepper.z), lam, is_leader, steering)
            if i % record_every == 0:
                s = i // record_every
                for key, val in zip('rxyz', (stepper.pos, stepper.x, stepper.y, stepper.z)):
                    rec[key][s] = val
                t_rec[s], uv_rec[s], lam_rec[s], lead_rec[s] = t, uv, lam, is_leader
                recorded = s + 1
            if i == steps:
                break
            stepper.advance(t, uv, is_leader)
            if progress is not None and i % report_every == 0:
                progress(i, steps)
    except KeyboardInterrupt:
        interrupted = True
    except LawError as err:
        failed = LawFailed(f'{err} (at t = {i * scn.dt:g}, step {i})', t=i * scn.dt)
        interrupted = True
    if progress is not None and not interrupted:
        progress(steps, steps)
    meta = dict(scenario=scn.name, seed=scn.seed, dt=scn.dt, duration=scn.duration, integrator=stepper.integrator,
                steps=steps, record_every=record_every, wall_seconds=time.perf_counter() - wall,
                interrupted=interrupted, events=stepper.events, dim=3)
    k = recorded
    traj = Trajectory(scn.names, t_rec[:k], rec['r'][:k], None, uv_rec[:k, :, 0], lam_rec[:k], lead_rec[:k], meta,
                      x=rec['x'][:k], y=rec['y'][:k], z=rec['z'][:k], v=uv_rec[:k, :, 1])
    if failed is not None:
        meta['stopped'] = str(failed)
        failed.trajectory = traj
        raise failed
    return traj
