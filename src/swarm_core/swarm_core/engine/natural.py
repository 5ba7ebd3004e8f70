"""The batch engine in three dimensions (no ROS): a 3D scenario's swarm in numpy arrays.

Each step, as the planar engine (`reference`) does it: the fault timeline says who is heard;
the commander plan gives λ, the leaders and s_k = (s_u, s_v) from the states of t_n (the
leader rule reads the positions and headings seen from above: "lateral" is along e_z × the
mean heading; failover and the rendezvous centroid measure in space); the law gives (u_k, v_k)
(`step.natural_alive_control`, or with a radio `step.natural_belief_controls`); every agent
heard moves by the exact zero-order-hold step (`model.natural.natural_step`, Gram-Schmidt every
`ORTHONORMALISE_EVERY` steps) or by RK4; then noise is added per agent from its own seeded
stream.  Dead and frozen agents do not move or draw noise; a dead agent's rows are NaN.
Recorded live commands (λ, an agent's law) are replayed at their steps.
"""
from __future__ import annotations

import time

import numpy as np

from swarm_core.command.plan import law_timeline
from swarm_core.engine.trajectory import Trajectory
from swarm_core.faults.agents import event_names, reunion_law
from swarm_core.laws import LawError, LawFailed
from swarm_core.model.integrate import chosen_integrator
from swarm_core.model.natural import ORTHONORMALISE_EVERY, natural_rk4_step, natural_step, orthonormalise
from swarm_core.natural_radio import NaturalBeliefs, natural_states
from swarm_core.radio import delay_stats
from swarm_core.step import natural_alive_control, natural_belief_controls


class NaturalStepper:
    """Steps a 3D scenario's swarm: positions (N, 3) and frames x, y, z (N, 3).
    ``commands``: recorded live commands to replay, {step: [command, ...]} (λ and law changes;
    a steering command carries one curvature, so it is planar only for now)."""

    def __init__(self, scn, integrator: str | None = None, commands=None):
        self.scn = scn
        self.law = scn.law
        self.integrator = chosen_integrator(integrator or scn.spec.integrator)
        self.n = len(scn.names)
        self.dt = scn.dt
        self.pos = scn.pos0.copy()
        self.x, self.y, self.z = (f.copy() for f in scn.frames0)
        self.plan = scn.command_plan()
        self.receivers = np.arange(self.n)
        self.commands = commands or {}
        if any(c['command'] == 'steer' and np.ndim(c['value']) == 0 for cmds in self.commands.values() for c in cmds):
            raise ValueError('a steer command of one curvature is planar (dim: 3 needs (s_u, s_v))')
        self.law_changes = law_timeline(self.commands, self.law, self.n)
        self.law_groups = None              # after a live law change: [(law, agent indices)]
        noise = scn.spec.noise
        self.noise_scale = np.array([noise.position] * 3 + [noise.heading] * 2)
        self.noisy = bool(np.any(self.noise_scale > 0))
        self._rngs = [scn.noise_rng(i) for i in range(self.n)] if self.noisy else None
        self.step_index = 0
        self.faults = scn.fault_timeline()
        self.events = []
        self._init_comms()

    def control(self, t, pos, frames, lam, is_leader, steering):
        """(u, v) (N, 2) of every agent (each group of agents with its own law after a live change)."""
        if self.law_groups is None:
            return self._control(self.law, self.receivers, t, pos, frames, lam, is_leader, steering)
        uv = np.zeros((self.n, 2))
        for law, rows in self.law_groups:
            uv[rows] = self._control(law, rows, t, pos, frames, lam, is_leader, steering)
        return uv

    def _control(self, law, rows, t, pos, frames, lam, is_leader, steering):
        """(u, v) of the agents ``rows`` under ``law``: only agents heard are in the table."""
        steering = np.zeros((self.n, 2)) if steering is None else np.asarray(steering, float)
        if self.comms is not None:
            return self._comms_control(law, rows, t, pos, frames, lam, is_leader, steering)[rows]
        return natural_alive_control(pos, frames, rows, law, lam, is_leader, steering[rows], self.scn.target,
                                     self.scn.barrier, self.scn.ground,
                                     alive=None if self.faults.all_alive else self.faults.alive,
                                     rendezvous=self.plan.rendezvous_now, t=t)

    def _change_laws(self):
        """Apply the live law changes of this step and regroup the agents by law."""
        changes = self.law_changes.get(self.step_index)
        if not changes:
            return
        laws = [self.law] * self.n if self.law_groups is None else \
            [law for k in range(self.n) for law, rows in self.law_groups if k in rows]
        for k, law, parameters in changes:           # the event as the planar engine records it
            laws[k] = law
            ev = dict(t=self.step_index * self.dt, kind='command', command='law', agent=self.scn.names[k],
                      parameters=parameters, step=self.step_index)
            if self.scn.law_hash:
                ev['law_hash'] = self.scn.law_hash
            self.events.append(ev)
        kinds = list(dict.fromkeys(laws))
        self.law_groups = [(law, np.array([k for k in range(self.n) if laws[k] == law], dtype=np.intp))
                           for law in kinds]

    def inputs(self):
        """t, λ, leader flags (n,) and steering (n, 2) of the current step (the commander's job)."""
        t = self.step_index * self.dt
        self.events.extend(self.faults.apply(self.step_index, self.plan.slots))
        self._change_laws()
        commands = [c for c in self.commands.get(self.step_index, ()) if c['command'] != 'law']
        lam, leaders, steering = self.plan.update(t, self.pos, self.x[:, 0], self.x[:, 1], heard=self.faults.alive,
                                                  commands=commands)
        for ev in self.plan.events:
            if ev['kind'] == 'command':
                ev = dict(ev, step=self.step_index)
            self.events.append(event_names(ev, self.scn.names))
        is_leader = np.zeros(self.n, dtype=bool)
        is_leader[leaders] = True
        return t, lam, is_leader, steering

    def advance(self, t, uv, is_leader):
        still = None if self.faults.all_alive else ~self.faults.alive
        if still is not None:
            held = (self.pos[still], self.x[still], self.y[still], self.z[still])
        if self.integrator == 'zoh':
            self.pos, self.x, self.y, self.z = natural_step(self.pos, self.x, self.y, self.z, uv[:, 0], uv[:, 1],
                                                            self.dt)
        else:
            def control(tt, p, x, y, z):
                # λ and s_k at the stage time; the leaders stay as chosen at t_n
                steer = np.zeros((self.n, 2))
                for idx, prog in self.plan.leaders.items():
                    steer[idx] = prog.value(tt, p[idx], None)
                return self.control(tt, p, (x, y, z), float(self.plan.schedule.value(tt)), is_leader, steer)
            self.pos, self.x, self.y, self.z = natural_rk4_step(self.pos, self.x, self.y, self.z, t, self.dt, control)
        if self.comms is not None:          # faults: the dead and frozen keep the (u, v) they last flew
            uv = np.asarray(uv, dtype=float)
            self.uv_prev = uv.copy() if still is None else np.where(still[:, None], self.uv_prev, uv)
        if self.noisy:
            self._add_noise(np.zeros(self.n, bool) if still is None else still)
        if self.integrator == 'zoh' and (self.step_index + 1) % ORTHONORMALISE_EVERY == 0:
            self.x, self.y, self.z = orthonormalise(self.x, self.y)
        if still is not None:                # faults: dead and frozen agents do not move
            self.pos[still], self.x[still], self.y[still], self.z[still] = held
        self.step_index += 1

    def _add_noise(self, quiet):
        """Uniform noise of each agent's own stream (none drawn for the ``quiet``: dead, frozen):
        U(−p, p) on each coordinate of r, and the heading turned by U(−h, h) towards y and
        towards z (the frame turns as a step with (u, v)·dt = those angles, r kept)."""
        draws = np.stack([np.zeros(5) if q else rng.uniform(-1.0, 1.0, size=5) for rng, q in zip(self._rngs, quiet)])
        kick = draws * self.noise_scale
        self.pos = self.pos + kick[:, :3]
        if self.noise_scale[3] > 0:
            _, self.x, self.y, self.z = natural_step(self.pos, self.x, self.y, self.z, kick[:, 3], kick[:, 4], 1.0)

    # ---------------------------------------------------------------- the radio (natural_radio)
    def _init_comms(self):
        self.comms = self.scn.comm_model()
        if self.comms is None:
            return
        if self.integrator != 'zoh':
            raise ValueError('a communication model needs the zoh integrator')
        self.beliefs = NaturalBeliefs(self.receivers, self.n)
        self.uv_prev = np.zeros((self.n, 2))    # (u, v) held over the step that ended at t_n (sent with the state)
        self._comms_step = -1

    def _comms_control(self, law, rows, t, pos, frames, lam, is_leader, steering):
        """(u, v) (N, 2) through the radio: each of ``rows`` from its own beliefs (others: 0)."""
        n, alive = self.step_index, self.faults.alive
        if self._comms_step != n:               # the radio delivers once per step
            arrival = self.comms.decide(n, self.receivers, pos, self.receivers, pos)
            self.beliefs.receive_states(n, arrival, natural_states(pos, *frames, self.uv_prev),
                                        alive=None if self.faults.all_alive else alive)
            self._comms_step = n
        law, target = reunion_law(law, self.scn.target, self.plan.rendezvous_now)
        active = np.zeros(self.n, bool)
        active[rows] = True
        if not self.faults.all_alive:
            active &= alive
        return natural_belief_controls(law, self.beliefs, n, self.comms, pos, frames, lam, is_leader, steering,
                                       target, self.scn.barrier, self.scn.ground, active=active, t=t)

    def comms_stats(self) -> dict | None:
        """What the radio did so far: messages sent/delivered (links j ≠ k), delays."""
        if self.comms is None:
            return None
        b = self.beliefs
        sent, got = int(b.sent.sum()), int(b.delivered.sum())
        return dict(sent=sent, delivered=got, delivered_fraction=got / sent if sent else None,
                    **delay_stats(b.delay_counts, self.dt))


def simulate(scn, *, integrator: str | None = None, record_every: int = 1, progress=None, commands=None,
             **unused) -> Trajectory:
    """Run a 3D scenario to its duration: a `Trajectory` with r, x, y, z (T, n, 3) and u, v (T, n)
    (NaN rows for dead agents).  ``progress(step, steps)`` is called now and then; ``commands``:
    recorded live commands to replay (`NaturalStepper`); a law that fails raises `LawFailed` with
    the steps done, Ctrl-C keeps them (``meta['interrupted']``)."""
    stepper = NaturalStepper(scn, integrator, commands)
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
                if not stepper.faults.all_alive:
                    lead_rec[s] &= stepper.faults.alive
                    dead = stepper.faults.dead
                    for key in 'rxyz':       # faults: a dead agent's rows are NaN
                        rec[key][s, dead] = np.nan
                    uv_rec[s, dead] = np.nan
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
    if stepper.comms is not None:
        meta['comms'] = stepper.comms_stats()
    k = recorded
    traj = Trajectory(scn.names, t_rec[:k], rec['r'][:k], None, uv_rec[:k, :, 0], lam_rec[:k], lead_rec[:k], meta,
                      x=rec['x'][:k], y=rec['y'][:k], z=rec['z'][:k], v=uv_rec[:k, :, 1])
    if failed is not None:
        meta['stopped'] = str(failed)
        failed.trajectory = traj
        raise failed
    return traj
