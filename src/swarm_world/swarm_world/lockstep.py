"""The world's lockstep barrier, without ROS: which states a step needs, when it is complete,
and what the world sends then.

One step n (the cycle in docs/ros-graph.md):

1. `on_states` takes the agents' states of t_n (one agent process's at once); once every
   agent in the table has sent one (`complete`), the barrier records the step and asks the
   node to send ``/clock``;
2. it decides λ, the leaders and s_k of step n on that table at once (``decide``: the
   scenario's `CommandPlan`, with the live commands the commander node forwarded), records
   them and asks the node to send ONE ``/lockstep/step`` message to every agent;
3. `begin_step` applies the faults of step n + 1 (scheduled and live) before its states are
   awaited.

Every method returns a list of actions for the node, in order:

- ``('clock', t)``: publish ``/clock``;
- ``('observe', k, rows)``: step k's states of the agents ``rows`` (those in its table) are
  recorded (metrics, markers, progress);
- ``('comms', k, event)``: publish a scheduled radio event (a dict) at step k on ``/swarm/events``;
- ``('step', msg)``: publish the step (a `swarm_ros.layouts.Step`);
- ``('event', ev)``: a world event or one of the plan's (log it, publish it, write it to the events file);
- ``('signal', i, what)``: signal agent i's process, ``what`` in ``kill``/``stop``/``cont``;
- ``('finish',)``: the last u is known; the run is over;
- ``('fail', why)``: no agent is left (every one lost or killed): the run cannot go on.

The node carries them out (`WorldNode.carry_out`, the clock, states, step and observe actions by
its `LockstepDriver`), which also keeps the wall clock (stalls, time-outs); the node keeps the
messages and the files.  The decision of a step is made here, on the table the step message
carries, not by a round trip to the commander node: two DDS hops per step instead of four
(docs/ros-graph.md).
"""
from __future__ import annotations

import numpy as np

from swarm_core.faults.agents import event_names
from swarm_core.model.frenet import frame_from_quaternion
from swarm_core.radio import event_step
from swarm_ros.layouts import Step


def comms_schedule(comms, dt):
    """A scenario's radio events (its ``comms`` spec or None) as (step, event dict), by step."""
    return sorted(((event_step(e.at, dt), e.model_dump(exclude_none=True))
                   for e in (comms.events if comms else [])), key=lambda se: se[0])


#: no states (rows, steps, values, u)
_NO_STATES = (np.zeros(0, np.intp), np.zeros(0, np.int64), np.zeros((4, 0)), np.zeros(0))


class RobotPoseJoin:
    """Lockstep with robots of the MuJoCo world: the state of t_k of an agent at ``rows`` comes
    in two parts, its pose from the robot world (``/lockstep/robot_states``) and the u it
    carries from the agent's own answer (whose pose is not taken); once both parts of one step
    are here, the state goes to the barrier (`LockstepBarrier.on_states`) as any other.  Each
    part waits for its twin; a part older than a state handed on is dropped, and at most
    `KEPT` parts are kept per agent (a dead agent's robot is still reported)."""

    KEPT = 1000

    def __init__(self, rows, n: int):
        self.mask = np.zeros(n, dtype=bool)
        self.mask[np.asarray(list(rows), dtype=np.intp)] = True
        self.poses = {int(i): {} for i in np.flatnonzero(self.mask)}     # row -> {step: (4,) pose}
        self.us = {int(i): {} for i in np.flatnonzero(self.mask)}        # row -> {step: u}

    def from_agents(self, rows, ks, vals, us):
        """One agent process's answer (as `LockstepBarrier.on_states` takes it): the states of
        its other agents as they are, then those whose pose was already here."""
        rows = np.asarray(rows, np.intp)
        mine = self.mask[rows]
        if not mine.any():
            return rows, ks, vals, us
        ks, us = np.asarray(ks), np.asarray(us)
        done = [self._put(self.us, self.poses, i, k, u)
                for i, k, u in zip(rows[mine].tolist(), ks[mine].tolist(), us[mine].tolist())]
        r, k, v, u = self._joined([d for d in done if d is not None])
        if mine.all():
            return r, k, v, u
        other = ~mine
        return (np.concatenate([rows[other], r]), np.concatenate([ks[other].astype(np.int64), k]),
                np.concatenate([np.asarray(vals)[:, other], v], axis=1), np.concatenate([us[other], u]))

    def from_robots(self, n: int, rows, pose):
        """The robot world's report of step ``n`` (``pose`` (4, K) at ``rows``): the states now
        complete.  Rows that are not robots here: ValueError naming them."""
        rows = np.asarray(rows, np.intp)
        if rows.size and (rows.max() >= self.mask.size or not self.mask[rows].all()):
            raise ValueError(f'poses of agent rows {sorted(set(rows.tolist()) - set(self.poses))}, which are '
                             'not on robots of the MuJoCo world here (world parameter robot_poses)')
        pose = np.asarray(pose, dtype=float)
        done = [self._put(self.poses, self.us, int(i), int(n), pose[:, j]) for j, i in enumerate(rows.tolist())]
        return self._joined([d for d in done if d is not None])

    def awaits_pose(self, i: int, k: int) -> bool:
        """Has agent ``i``'s u of step ``k`` come while its robot's pose has not?"""
        return i in self.us and k in self.us[i] and k not in self.poses[i]

    def _put(self, mine, twin, i, k, value):
        """Keep one part; (row, step) if its twin is here."""
        kept = mine[i]
        kept[k] = value
        if len(kept) > self.KEPT:
            del kept[min(kept)]
        return (i, k) if k in twin[i] else None

    def _joined(self, done):
        """rows, steps, values (4, K) and u of the states ``done`` ((row, step)), their parts
        and every older one dropped."""
        if not done:
            return _NO_STATES
        vals, us = np.zeros((4, len(done))), np.zeros(len(done))
        for j, (i, k) in enumerate(done):
            vals[:, j], us[j] = self.poses[i].pop(k), self.us[i].pop(k)
            for kept in (self.poses[i], self.us[i]):
                for old in [s for s in kept if s < k]:
                    del kept[old]
        return (np.array([i for i, _ in done], np.intp), np.array([k for _, k in done], np.int64), vals, us)


class LockstepBarrier:
    """The lockstep state of a world: step ``cur`` and the states, u and decision it holds.

    ``faults`` is the scenario's `swarm_core.faults.agents.FaultTimeline`, ``recorder`` a
    `swarm_core.engine.trajectory.TrajectoryRecorder`; ``comms_events`` is a list of (step, event)
    sorted by step; ``geometry()`` returns the (target, barrier) to put in each step;
    ``decide(t, pos, cos_t, sin_t, heard)`` returns the decision of a step (a
    `swarm_core.command.plan.Decided`: `CommandPlan.decide` with the pending live commands)."""

    def __init__(self, names, steps, dt, faults, recorder, *, decide, comms_events=(), clock_every=1,
                 geometry=lambda: (None, None)):
        self.names = list(names)
        self.n = len(self.names)
        self.row = {nm: i for i, nm in enumerate(self.names)}
        self.steps = steps
        self.dt = dt
        self.faults = faults
        self.rec = recorder
        self.comms_events = list(comms_events)
        self.clock_every = clock_every
        self.geometry = geometry
        self.decide = decide
        self.cur = 0
        self.buf = np.zeros((4, self.n))          # x, y, qz, qw of step cur
        self.buf_u = np.zeros(self.n)             # u_{cur-1} the states carry
        self.have = np.zeros(self.n, bool)
        self.fresh = np.zeros(self.n, bool)       # stamped at the current step (not held)
        self.want = np.zeros(self.n, dtype=np.int64)   # the stamp step wanted from each agent
        self.slots = {}                           # leader slot → agent index (last decision)
        self.stop_pending = set()                 # frozen agents to stop once their state is held
        self.started = False
        self.done = False
        self.lam = 0.0
        self.leaders = np.zeros(self.n, bool)

    # ------------------------------------------------------------------ inputs
    def on_states(self, rows, ks, vals, us):
        """The states of the agents ``rows`` of one agent process (its
        ``/lockstep/agent_states``: steps ``ks``, values (x, y, qz, qw) as (4, K), and u (K,):
        a state stamped at step k carries u_{k-1}), with ONE check of the step's completion.
        States of a step the world already holds (a repeat) are ignored; a dead or frozen
        agent's state is kept only if it is the state of its freeze step.  Returns (reasons
        for the states of later steps, actions)."""
        rows = np.asarray(rows, np.intp)
        ks = np.asarray(ks, np.int64)
        alive = self.faults.alive[rows]
        want = self.want[rows]
        take = alive & (ks == want)
        every = take.all()
        r, k, v, u = (rows, ks, vals, us) if every else (rows[take], ks[take], vals[:, take], us[take])
        self.buf[:, r] = v
        self.buf_u[r] = u
        self.have[r] = True
        fresh = k == self.cur
        self.fresh[r] = fresh
        if not fresh.all():                                 # resumed agents' held states
            held = ~fresh & (k > 0) & (k <= self.steps)
            self.rec.u[k[held] - 1, r[held]] = u[held]
        acts, why = [], []
        if not every:
            for j in np.flatnonzero(~alive):               # dead or frozen: their own rules
                acts += self._take(int(rows[j]), int(ks[j]), vals[:, j], us[j] if us.ndim > 1 else float(us[j]))[1]
            for j in np.flatnonzero(alive & ~take & (ks > want)):
                why.append(f'state of {self.names[rows[j]]!r} for step {ks[j]} while the world is at step {self.cur}')
        return why, acts + (self.advance() if r.size else [])

    def on_state(self, i, k, vals, u):
        """`on_states` for the state of ONE agent ``i`` (a lone agent's answer: step ``k``,
        values (4,), u), without index arrays when it is the state the world waits for
        (alive, of the wanted step); any other goes through `on_states`."""
        if not (self.faults.alive[i] and k == self.want[i]):
            return self.on_states(np.array([i]), np.array([k]), vals[:, None], np.array([u]))
        self._take(i, k, vals, u)                          # alive, wanted: taken, no actions
        return [], self.advance()

    def _take(self, i, k, vals, u):
        """One agent's state, without the completion check: (reason it was not taken or None,
        actions)."""
        if not self.faults.alive[i]:
            acts = []
            if self.faults.frozen[i] and k == self.faults.frozen_at[i]:
                self.rec.hold(i, k, vals, u)
                if i in self.stop_pending:
                    self.stop_pending.discard(i)
                    acts.append(('signal', i, 'stop'))
            return None, acts
        if k != self.want[i]:
            return f'state of {self.names[i]!r} for step {k} while the world is at step {self.cur}', []
        self.buf[:, i] = vals
        self.buf_u[i] = u
        self.have[i] = True
        self.fresh[i] = k == self.cur
        if k != self.cur and 0 < k <= self.steps:     # a resumed agent's held state
            self.rec.u[k - 1, i] = u
        return None, []

    # ------------------------------------------------------------------ the cycle
    def start(self):
        """Everyone is matched: apply step 0's faults and go."""
        self.started = True
        return self.begin_step(0) + self.advance()

    def complete(self):
        """Every agent in the table of the current step has its state here."""
        return bool(self.have.all() or (self.have | ~self.faults.alive).all())

    def missing(self):
        """Indices of the agents in the table whose state of the current step has not come."""
        return np.flatnonzero(self.faults.alive & ~self.have)

    def advance(self):
        if not self.started or self.done or not self.complete():
            return []
        acts = []
        alive = self.faults.alive
        k = self.cur
        if k > self.steps:                         # the final u_{steps}
            self.rec.record_u(self.steps, alive, self.buf_u)
            self.done = True
            return [('finish',)]
        self.rec.record_states(k, alive, *self.buf)
        if k > 0:
            self.rec.record_u(k - 1, self.fresh & alive, self.buf_u)
        t = k * self.dt
        if k % self.clock_every == 0 or k == self.steps:
            acts.append(('clock', t))
        acts.append(('observe', k, np.flatnonzero(alive)))     # the table of step k: not the next's
        d = self._decide(t, alive)
        acts += [('event', ev) for ev in self.plan_events(d.events, k)]
        has = np.flatnonzero(np.asarray(d.slots) >= 0)          # the leaders' slots (few), not every agent
        self.slots = dict(zip(np.asarray(d.slots)[has].tolist(), has.tolist()))
        self.lam, self.leaders = d.lam, d.flags & alive
        self.rec.record_decision(k, d.lam, self.leaders)
        data = self.message(k, t, d, alive)
        while self.comms_events and self.comms_events[0][0] <= k:
            acts.append(('comms', k, self.comms_events.pop(0)[1]))
        acts.append(('step', data))
        self.cur += 1
        self.have[:] = False
        self.fresh[:] = False
        self.want[:] = self.cur
        acts += self.begin_step(self.cur)
        if self.deserted():
            return acts + self._fail('every agent is killed or lost')
        return acts + self.advance()             # nobody to wait for (all frozen): the step goes on

    def message(self, k, t, d, alive):
        """The step message of step k at time t with decision ``d`` (a `Step`)."""
        target, barrier = self.geometry()
        return Step(k, t, d.lam, d.flags, d.steering, *self.buf.copy(), self.buf_u.copy(), alive.copy(),
                    target, barrier, d.rendezvous)

    def _decide(self, t, alive):
        """The plan's decision at t on the table held: the positions, the frames the agents
        compute from the quaternions they sent, and the agents heard (the alive mask)."""
        x, y, qz, qw = self.buf
        cos_t, sin_t = frame_from_quaternion(qz, qw)
        return self.decide(t, np.stack([x, y], axis=1), cos_t, sin_t, alive.copy())

    def plan_events(self, events, k):
        """The plan's events of step k as the world publishes them: agent names, and the step
        of each live command (what ``swarm simulate --replay`` applies again)."""
        out = []
        for ev in events:
            ev = event_names(ev, self.names)
            if ev['kind'] == 'command':
                ev['step'] = k
            out.append(ev)
        return out

    def deserted(self):
        """No agent will ever answer again: every one killed or lost (a frozen one comes back)."""
        return bool(self.faults.dead.all()) and self.cur <= self.steps

    def _fail(self, why):
        self.done = True
        return [('fail', f'step {self.cur}: {why}: no agent is left, the run ends here')]

    # ------------------------------------------------------------------ faults
    def begin_step(self, k):
        """Apply the faults of step k (scheduled and live) before its states are awaited."""
        if k > self.steps:
            return []
        acts = []
        for ev in self.faults.apply(k, self.slots):
            i = self.row.get(ev['agent'])
            acts.append(('event', ev))          # first: the launcher reads it when the agent dies
            if ev['kind'] == 'kill':
                acts.append(('signal', i, 'kill'))
                self.stop_pending.discard(i)
                self.rec.mark_lost(i, k)
            elif ev['kind'] == 'freeze':
                self.rec.freeze(i, self.faults.frozen_at[i], self.faults.frozen_until[i])
                held = self.rec.held.get(i)
                if held is not None and held[0] == self.faults.frozen_at[i]:
                    acts.append(('signal', i, 'stop'))
                else:
                    self.stop_pending.add(i)
            elif ev['kind'] == 'resume':
                self.stop_pending.discard(i)
                acts.append(('signal', i, 'cont'))
                k0 = int(self.faults.frozen_at[i])
                held = self.rec.held.pop(i, None)
                if held is not None and held[0] == k0:
                    self.buf[:, i] = held[1]
                    self.buf_u[i] = held[2]
                    self.have[i] = True
                else:
                    self.want[i] = k0
        return acts

    def drop_missing(self):
        """Give up on the agents whose state has not come: they are lost (event ``lost``)."""
        acts, gone = [], self.missing()
        for i in gone:
            self.faults.mark_lost(i)
            self.rec.mark_lost(i, self.cur)
            acts.append(('event', dict(t=self.cur * self.dt, step=self.cur, kind='lost', agent=self.names[i])))
        if self.deserted():
            return acts + self._fail(f'no state from {", ".join(self.names[i] for i in gone)} (dropped): every '
                                     'agent is lost or killed')
        return acts + self.advance()

    def add_fault(self, fault):
        """A live fault request: applied at the next step (the current one is under way)."""
        k = self.cur + 1
        self.faults.add(fault, not_before=k)
        return k

    def rows_done(self):
        """Rows whose state, λ, leaders and u are all known (u_{k-1} comes with step k, or is
        unknown once every agent is gone at step k)."""
        return min(self.cur if self.deserted() else self.cur - 1, self.steps + 1)
