"""Batch engine: the whole swarm in numpy arrays, no ROS.

The reference the ROS nodes are checked against, and the fast path for sweeps and large
swarms.  Each step: the commander plan gives λ, leaders and s_k from the states of t_n; the
law gives u_k; the integrator advances every agent; noise is added per agent from its own
seeded stream (as each agent node does).

Faults, failover and reunion (swarm_core.faults.agents) are confined to `inputs` (the fault
timeline and the plan's failover), `control` (only agents heard this step are in the table;
a rendezvous adds the target term) and `advance` (agents not heard do not move or draw
noise).  ``simulate`` records NaN for dead agents and the events in ``meta['events']``.
"""
from __future__ import annotations

import time

import numpy as np

from swarm_core.command.plan import law_timeline
from swarm_core.engine import natural
from swarm_core.engine.trajectory import Trajectory
from swarm_core.faults.agents import event_names, reunion_law
from swarm_core.laws import LawError, LawFailed
from swarm_core.laws.paper.compiled_sums import run_sums
from swarm_core.model.frenet import heading_frame, quaternion_from_heading
from swarm_core.model.integrate import chosen_integrator, rk4_step, zoh_step
from swarm_core.radio import Beliefs, delay_stats
from swarm_core.scenario.loader import Scenario
from swarm_core.step import alive_control, belief_controls

#: what a stepper's law sums over (`Law.pair_list`): auto, all, kdtree, and the run's choice of
#: compiled sums (`compiled_sums.run_sums`): compiled, or numpy (auto without them)
SEARCHES = ('auto', 'all', 'kdtree', 'compiled', 'numpy')


def run_search(n: int, steps: int, neighbour_search: str = 'auto', compiled: str = 'auto') -> str:
    """The neighbour search of a run of n agents and ``steps`` steps: auto becomes compiled or
    numpy by the run's ``compiled`` choice (`compiled_sums.run_sums`, as every ROS agent of such
    a run decides); all and kdtree stay."""
    if neighbour_search != 'auto':
        return neighbour_search
    return run_sums(n, steps, compiled)


class SwarmStepper:
    """Steps a scenario's swarm; `simulate` drives it, benchmarks and tests may too."""

    def __init__(self, scn: Scenario, integrator: str | None = None,
                 neighbour_search: str = 'auto', commands=None):
        self.scn = scn
        self.commands = commands or {}      # live commands to replay: step → [command, ...]
        self.law = scn.law
        # agents' live law changes (`law_timeline`): step → [(agent, law, changes)]; then `laws` holds each
        # agent's law and `law_groups` [(law, agent indices)] (None: every agent has `law`)
        self.law_changes = law_timeline(self.commands, self.law, len(scn.names))
        self.laws = self.law_groups = None
        self.integrator = chosen_integrator(integrator or scn.spec.integrator)
        self.n = len(scn.names)
        self.dt = scn.dt
        self.pos = scn.pos0.copy()
        self.theta = scn.theta0.copy()
        self.plan = scn.command_plan()
        self.receivers = np.arange(self.n)
        self.target = scn.target
        self.barrier = scn.barrier
        if neighbour_search not in SEARCHES:
            raise ValueError(f'neighbour_search must be one of {", ".join(SEARCHES)}, got {neighbour_search!r}')
        self.neighbour_search = neighbour_search
        self._is_leader = (None, None)      # (leader indices, flags) of the last step
        noise = scn.spec.noise
        self.noise_scale = np.array([noise.position, noise.position, noise.heading])
        self.noisy = bool(np.any(self.noise_scale > 0))
        self._rngs = [scn.noise_rng(i) for i in range(self.n)] if self.noisy else None
        self.step_index = 0
        self.faults = scn.fault_timeline()
        self.events = []
        self._init_comms()

    def _pairs(self, pos, lam, law=None):
        """What ``law`` (default the run's) sums over for a table at ``pos``: its own choice
        (`Law.pair_list`) under this stepper's neighbour search."""
        return (self.law if law is None else law).pair_list(pos, lam, self.neighbour_search)

    def control(self, t, pos, theta, lam, is_leader, steering, frame=None):
        if self.law_groups is not None:
            return self._grouped_control(t, pos, theta, lam, is_leader, steering, frame)
        if self.comms is not None:
            return self._comms_control(pos, theta, lam, is_leader, steering, t=t)
        cos_t, sin_t = heading_frame(theta) if frame is None else frame
        # faults: the table holds only the agents heard this step, in index order
        return alive_control(pos, cos_t, sin_t, self.receivers, self.law, lam, is_leader, steering, self.target,
                             self.barrier, alive=None if self.faults.all_alive else self.faults.alive,
                             rendezvous=self.plan.rendezvous_now, pairs=lambda p: self._pairs(p, lam), t=t)

    def _grouped_control(self, t, pos, theta, lam, is_leader, steering, frame):
        """u after live law changes: one law call per group of agents that share a law (each
        receiver's sum is its own, so an agent node gets the same u with its law alone)."""
        u = np.zeros(self.n)
        steering = np.zeros(self.n) if steering is None else np.asarray(steering, float)
        if self.comms is None:
            cos_t, sin_t = heading_frame(theta) if frame is None else frame
        for law, rows in self.law_groups:
            if self.comms is not None:
                u[rows] = self._comms_control(pos, theta, lam, is_leader, steering, law, rows, t=t)[rows]
                continue
            u[rows] = alive_control(pos, cos_t, sin_t, rows, law, lam, is_leader, steering[rows], self.target,
                                    self.barrier, alive=None if self.faults.all_alive else self.faults.alive,
                                    rendezvous=self.plan.rendezvous_now,
                                    pairs=lambda p, law=law: self._pairs(p, lam, law), t=t)
        return u

    def _change_laws(self):
        """Apply the law changes of this step (`law_changes`) and regroup the agents by law."""
        changes = self.law_changes.get(self.step_index)
        if not changes:
            return
        if self.laws is None:
            self.laws = [self.law] * self.n
        for k, law, parameters in changes:           # the event as the agent node publishes it
            self.laws[k] = law
            ev = dict(t=self.step_index * self.dt, kind='command', command='law', agent=self.scn.names[k],
                      parameters=parameters, step=self.step_index)
            if self.scn.law_hash:
                ev['law_hash'] = self.scn.law_hash
            self.events.append(ev)
        groups = []
        for k, law in enumerate(self.laws):
            for g in groups:
                if g[0] == law:
                    g[1].append(k)
                    break
            else:
                groups.append((law, [k]))
        self.law_groups = [(law, np.array(rows, dtype=np.intp)) for law, rows in groups]

    def inputs(self):
        """t, λ, leader flags (n,), steering (n,) for the current step (the commander's job),
        and the frames (cos θ, sin θ) they were computed from."""
        t = self.step_index * self.dt
        frame = heading_frame(self.theta)
        names = self.scn.names
        for ev in self.faults.apply(self.step_index, self.plan.slots):
            self.events.append(ev)
        self._change_laws()
        commands = [c for c in self.commands.get(self.step_index, ()) if c['command'] != 'law']
        lam, leaders, steering = self.plan.update(t, self.pos, *frame, heard=self.faults.alive, commands=commands)
        for ev in self.plan.events:
            if ev['kind'] == 'command':
                ev = dict(ev, step=self.step_index)
            self.events.append(event_names(ev, names))
        last, is_leader = self._is_leader
        if leaders != last:                 # the flags are rebuilt only when the leaders change
            is_leader = np.zeros(self.n, dtype=bool)
            is_leader[leaders] = True
            is_leader.flags.writeable = False
            self._is_leader = (leaders, is_leader)
        return t, lam, is_leader, steering, frame

    def step(self):
        """Advance one dt; returns (t, λ, leader flags, u) of the step just taken."""
        t, lam, is_leader, steering, frame = self.inputs()
        u = self.control(t, self.pos, self.theta, lam, is_leader, steering, frame)
        self.advance(t, u, lam, is_leader, steering)
        return t, lam, is_leader, u

    def advance(self, t, u, lam, is_leader, steering):
        if self.faults.all_alive:
            still, held = None, None
        else:
            still = ~self.faults.alive
            held = (self.pos[still], self.theta[still])
        if self.integrator == 'zoh':
            self.pos, self.theta = zoh_step(self.pos, self.theta, u, self.dt)
        else:
            def control(tt, p, th):
                # λ and s_k are evaluated at the stage time; leaders stay as chosen at t_n
                lam_s = float(self.plan.schedule.value(tt))
                c, s = heading_frame(th)
                steer = np.zeros(self.n)
                for idx, prog in self.plan.leaders.items():
                    steer[idx] = prog.value(tt, p[idx], float(np.arctan2(s[idx], c[idx])))
                return self.control(tt, p, th, lam_s, is_leader, steer)
            self.pos, self.theta = rk4_step(self.pos, self.theta, t, self.dt, control)
        if self.comms is not None:          # faults: the dead and frozen keep the u they last flew
            self.u_prev = np.array(u, dtype=float) if still is None else \
                np.where(still, self.u_prev, np.asarray(u, dtype=float))
        if self.noisy:
            quiet = np.zeros(self.n, dtype=bool) if still is None else still   # dead or frozen: no draw
            draws = np.stack([np.zeros(3) if q else rng.uniform(-1.0, 1.0, size=3)
                              for rng, q in zip(self._rngs, quiet)])
            noise = draws * self.noise_scale
            self.pos = self.pos + noise[:, :2]
            self.theta = self.theta + noise[:, 2]
        if held is not None:                 # faults: dead and frozen agents do not move
            self.pos[still], self.theta[still] = held
        self.step_index += 1

    # ---------------------------------------------------------------- communication model
    # A separate path (swarm_core.radio), taken only when the scenario's radio is not perfect:
    # every receiver computes its u with THE law on its own beliefs (one law call over the
    # believed pairs of all receivers; the fates of all links of a step are drawn at once).

    def _init_comms(self):
        self.comms = self.scn.comm_model()
        if self.comms is None:
            return
        if self.integrator != 'zoh':
            raise ValueError('a communication model needs the zoh integrator')
        self.beliefs = Beliefs(self.receivers, self.n)
        self.u_prev = np.zeros(self.n)          # u held over the step that ended at t_n (sent with the state)
        self._comms_step = -1

    def _comms_control(self, pos, theta, lam, is_leader, steering, law=None, rows=None, t=None):
        """u through the radio (all agents with the run's law, or ``rows`` with ``law``) at
        sim time ``t``."""
        n = self.step_index
        alive = self.faults.alive           # faults: the dead and the frozen neither send nor listen
        if self._comms_step != n:               # the radio delivers once per step
            qz, qw = quaternion_from_heading(theta)
            arrival = self.comms.decide(n, self.receivers, pos, self.receivers, pos)
            self.beliefs.receive(n, arrival, pos[:, 0], pos[:, 1], qz, qw, self.u_prev,
                                 alive=None if self.faults.all_alive else alive)
            self._comms_step = n
        s = np.zeros(self.n) if steering is None else np.asarray(steering, dtype=float)
        law, target = reunion_law(self.law if law is None else law, self.target, self.plan.rendezvous_now)
        active = None if self.faults.all_alive else np.asarray(alive, bool)
        if rows is not None:
            mine = np.zeros(self.n, bool)
            mine[rows] = True
            active = mine if active is None else active & mine
        return belief_controls(law, self.beliefs, n, self.comms, pos, self.own_headings(theta), lam, is_leader, s,
                               target, self.barrier, active=active, t=t)

    def own_headings(self, theta):
        """The headings a radio model's law takes as the agents' own: their true ones here
        (a robot engine's robot agents take theirs from the table)."""
        return theta

    def comms_stats(self) -> dict | None:
        """What the radio did so far: messages sent/delivered (links j ≠ k), delays."""
        if self.comms is None:
            return None
        b = self.beliefs
        sent, got = int(b.sent.sum()), int(b.delivered.sum())
        return dict(sent=sent, delivered=got, delivered_fraction=got / sent if sent else None,
                    **delay_stats(b.delay_counts, self.dt))


def simulate(scn: Scenario, *, integrator: str | None = None, record_every: int = 1,
             neighbour_search: str = 'auto', progress=None, commands=None, stepper=None,
             compiled: str = 'auto') -> Trajectory:
    """Run a scenario to its duration; ``progress(step, steps)`` is called now and then.
    ``compiled``: auto, on or off, the compiled pair sums (`run_search`).
    ``commands``: live commands to replay, {step: [command, ...]} (`read_commands`).
    ``stepper``: a prepared `SwarmStepper` of ``scn`` (one that moves some agents otherwise:
    `swarm_robots.engine`); the other arguments are then its own.  A 3D scenario runs in
    `engine.natural`."""
    if scn.dim == 3 and stepper is None:
        return natural.simulate(scn, integrator=integrator, record_every=record_every, progress=progress,
                                commands=commands)
    stepper = stepper or SwarmStepper(scn, integrator, run_search(len(scn.names), scn.steps, neighbour_search,
                                                                  compiled), commands)
    steps = scn.steps
    n = stepper.n
    n_rec = steps // record_every + 1
    t_rec = np.empty(n_rec)
    r_rec = np.empty((n_rec, n, 2))
    th_rec = np.empty((n_rec, n))
    u_rec = np.empty((n_rec, n))
    lam_rec = np.empty(n_rec)
    lead_rec = np.zeros((n_rec, n), dtype=bool)
    wall = time.perf_counter()
    report_every = max(1, steps // 100)
    recorded = 0
    interrupted = False
    failed = None
    try:
        for i in range(steps + 1):
            t, lam, is_leader, steering, frame = stepper.inputs()
            u = stepper.control(t, stepper.pos, stepper.theta, lam, is_leader, steering, frame)
            if i % record_every == 0:
                s = i // record_every
                t_rec[s], r_rec[s], th_rec[s], u_rec[s] = t, stepper.pos, stepper.theta, u
                lam_rec[s] = lam
                if stepper.faults.all_alive:
                    lead_rec[s] = is_leader
                else:
                    lead_rec[s] = is_leader & stepper.faults.alive
                    dead = stepper.faults.dead
                    if dead.any():           # faults: a dead agent's rows are NaN
                        r_rec[s, dead], th_rec[s, dead], u_rec[s, dead] = np.nan, np.nan, np.nan
                recorded = s + 1
            if i == steps:
                break
            stepper.advance(t, u, lam, is_leader, steering)
            if progress is not None and i % report_every == 0:
                progress(i, steps)
    except KeyboardInterrupt:      # keep what was computed: the caller saves a partial run
        interrupted = True
    except LawError as err:        # a law that failed: LawFailed with the steps done
        failed = LawFailed(f'{err} (at t = {i * scn.dt:g}, step {i})', t=i * scn.dt)
        interrupted = True
    if progress is not None and not interrupted:
        progress(steps, steps)
    meta = dict(scenario=scn.name, seed=scn.seed, dt=scn.dt, duration=scn.duration,
                integrator=stepper.integrator, steps=steps, record_every=record_every,
                wall_seconds=time.perf_counter() - wall, neighbour_search=stepper.neighbour_search,
                interrupted=interrupted, events=stepper.events)
    if stepper.comms is not None:
        meta['comms'] = stepper.comms_stats()
    traj = Trajectory(scn.names, t_rec[:recorded], r_rec[:recorded], th_rec[:recorded],
                      u_rec[:recorded], lam_rec[:recorded], lead_rec[:recorded], meta)
    if failed is not None:
        meta['stopped'] = str(failed)
        failed.trajectory = traj
        raise failed
    return traj
