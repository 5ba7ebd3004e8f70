"""The drivers of the world node, one per mode: what the world does in lockstep
(`LockstepDriver`) and in realtime (`RealtimeDriver`); `DRIVERS` maps the parameter ``mode``
to the class and `swarm_world.world_node.WorldNode` holds what every mode shares.

Lockstep: the world holds each step until every agent's state and the commander's decision are
here; it carries out what its barrier decides (`swarm_world.lockstep`), and on a wall-clock
tick starts step 0, drops the agents whose state has not come, repeats the last message or
gives up (`swarm_world.wallclock`).
Realtime: agents publish on their own clocks; the world records each state as it comes, from
the one message per agent process and tick (``/swarm/agent_states``), publishes the clock at
the real-time factor, and checks, views and applies faults on its tick.  The schedule itself
is pure (`swarm_world.realtime`).

A driver takes its mode's parameters (`parameters.MODE_PARAMETERS`), creates its mode's
publishers and subscriptions (`create_endpoints`), ticks with the node's timer (`tick`,
every `tick_period` wall s) and carries out its mode's own actions (`carry_out`).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String

from swarm_core.analysis import metrics as M
from swarm_core.command.plan import check_command
from swarm_core.files import write_atomic
from swarm_ros import protocol as P
from swarm_ros.layouts import (
    AgentStates,
    NaturalAgentStates,
    NaturalDecision,
    NaturalProcessStates,
    ProcessStates,
    RealtimeDecision,
    RobotStates,
    RunClock,
)
from swarm_ros.msg_checks import (
    NewestStates,
    ProcessSenders,
    batch_ok,
    check_agent_states,
    check_decision_time,
    decoded,
    new_sender_tag,
    refused,
)
from swarm_ros.rosutil import ParameterError
from swarm_ros.run_control import EventRefused, FirstSender, forwarded
from swarm_world.lateness import TIMING_FILE, Lateness, behind_line, timing_line
from swarm_world.lockstep import LockstepBarrier, RobotPoseJoin, comms_schedule
from swarm_world.markers import stamp
from swarm_world.natural import NaturalBarrier, check_natural_states, natural_check, natural_newest
from swarm_world.realtime import RealtimeSchedule, SilenceWatch, clock_tick, decision_valid, newest_view
from swarm_world.wallclock import StallWatch, StartWatch


class LockstepDriver:
    """Lockstep: the barrier (`lock`, a `LockstepBarrier`) takes the agent processes' states
    (``/lockstep/agent_states``, and the robot world's poses with ``robot_poses``) and decides
    each step with the scenario's `CommandPlan` (``plan``) and the live commands the commander
    node forwards (``/lockstep/command``); the node carries out what it decides
    (`WorldNode.carry_out`: the clock, the step to the agents).
    The wall clock (`StartWatch`, `StallWatch`) starts the run, drops missing agents, repeats
    the last message of a stalled step or gives up."""

    def __init__(self, node, clock_every, stall_timeout, wait_for_recorder, step_timeout, start_timeout,
                 missing_timeout, step_readers, clock_readers, robot_poses):
        self.node = node
        self.start_timeout = start_timeout
        self.missing_timeout = missing_timeout
        self.robot_poses = robot_poses
        barrier, more = (NaturalBarrier, dict(ground=node.ground)) if node.dim == 3 else (LockstepBarrier, {})
        self.lock = barrier(node.names, node.steps, node.dt, node.faults, node.rec,
                            comms_events=comms_schedule(node.scn.spec.comms, node.dt), clock_every=clock_every,
                            geometry=lambda: (node.target, node.barrier), decide=self.decide, **more)
        self.plan = node.scn.command_plan()
        self.pending = []        # the commander's live commands, for the next decision
        self.commander = FirstSender(P.LOCK_COMMAND)
        self.commander_seq = 0   # the last command message taken (a re-delivered one is older)
        self.commander_ready = False
        self.process_senders = ProcessSenders(node.n)
        self.join = None         # with robot_poses: a `RobotPoseJoin`
        self.robot_sender = FirstSender(P.LOCK_ROBOT_STATES)      # the robot world's tag
        self.start_watch = StartWatch(time.monotonic(), node.n, start_timeout=start_timeout,
                                      relay_want=step_readers, clock_want=clock_readers,
                                      wait_for_recorder=wait_for_recorder,
                                      recorder_wait=P.RECORDER_MATCH_WAIT)
        self.watch = StallWatch(time.monotonic(), missing_timeout=missing_timeout,
                                step_timeout=step_timeout, stall_timeout=stall_timeout)
        self.last_msg = None     # (publisher, serialized message) last sent: repeated when stalled

    def tick_period(self):
        """Wall s between the node's ticks (start, stalls and time-outs)."""
        return 0.05

    def create_endpoints(self):
        """The states of the agent processes in, the states to the commander and the step to the
        agents out, the commander's decisions in; with ``robot_poses`` the robot world's poses."""
        node = self.node
        # one message per agent process and step (protocol: /lockstep/agent_states)
        self.sub_states = node.create_subscription(Float64MultiArray, P.LOCK_AGENT_STATES, self.on_agent_states,
                                                   P.qos_latched(max(100, 4 * node.n)), raw=True)
        self.pub_step = node.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
        # the commander's live commands (transient-local: none is lost to a late match; all kept
        # until taken: a flood of refused ones cannot push one out)
        node.create_subscription(String, P.LOCK_COMMAND, self.on_command, P.qos_kept_latched())
        robots = [nm.strip() for nm in self.robot_poses.split(',') if nm.strip()]
        if robots:          # their poses from the robot world, u from their answers (`RobotPoseJoin`)
            unknown = [nm for nm in robots if nm not in node.row]
            if unknown:
                raise ParameterError(f'parameter robot_poses: no agent {", ".join(unknown)} in the scenario')
            self.join = RobotPoseJoin([node.row[nm] for nm in robots], node.n)
            node.create_subscription(Float64MultiArray, P.LOCK_ROBOT_STATES, self.on_robot_states,
                                     P.qos_latched(), raw=True)

    # ------------------------------------------------------------ inputs
    def on_agent_states(self, raw):
        """The states of one agent process's agents (serialized /lockstep/agent_states)."""
        node = self.node
        if node.dim == 3:           # r, x, y, z and (u, v) (`layouts.NaturalAgentStates`)
            m = decoded(NaturalAgentStates, raw, node.run_id, node.reject, 'state-decode')
            if m is None:
                return
            tag, idx, ks, vals, u = m.tag, m.index, m.step, m.state, m.uv
            why = check_natural_states(idx, vals, node.n, P.LOCK_AGENT_STATES)
        else:
            m = decoded(AgentStates, raw, node.run_id, node.reject, 'state-decode')
            if m is None:
                return
            tag, idx, ks, vals, u = m.tag, m.index, m.step, m.pose, m.u
            why = check_agent_states(idx, vals, node.n)
        if why is None:
            ok, why = self.process_senders.check(idx, tag)
            if not ok.all():
                idx, ks, vals, u = idx[ok], ks[ok], vals[:, ok], u[ok]
        if why is not None:
            node.reject(why.kind, why)
        if idx.size == 0 or why is not None and why.kind != 'second-publisher':
            return
        self.process_senders.accept(idx, tag)
        if self.join is not None:
            idx, ks, vals, u = self.join.from_agents(idx, ks, vals, u)
        elif idx.size == 1:             # a lone agent's answer: no index arrays (`on_state`)
            self.watch.progressed(time.monotonic())
            self.after(self.lock.on_state(int(idx[0]), int(ks[0]), vals[:, 0], u[0] if u.ndim > 1 else float(u[0])))
            return
        self.take_states(idx, ks, vals, u)

    def on_robot_states(self, raw):
        """The robot world's poses of its robots' agents at one step (`RobotPoseJoin`)."""
        node = self.node
        m = decoded(RobotStates, raw, node.run_id, node.reject, 'robot-decode')
        if m is None:
            return
        why = self.robot_sender.check(m.tag)
        if why is not None:
            node.reject(why.kind, why)
            return
        try:
            idx, ks, vals, u = self.join.from_robots(m.n, m.index, m.pose)
        except ValueError as err:
            node.reject('robot-rows', f'{P.LOCK_ROBOT_STATES}: {err}')
            return
        self.take_states(idx, ks, vals, u)

    def take_states(self, idx, ks, vals, u):
        """States (`LockstepBarrier.on_states`) into the barrier, and what it decides done."""
        self.watch.progressed(time.monotonic())
        if idx.size == 0:           # a robot agent's u whose pose has not come (`RobotPoseJoin`)
            return
        self.after(self.lock.on_states(idx, ks, vals, u))

    def after(self, outcome):
        """What the barrier decided on states: (reasons for states of later steps, actions)."""
        late, acts = outcome
        for text in late[:1]:
            self.node.reject('step', text)
        self.node.carry_out(acts)

    def on_command(self, msg):
        """The commander node's message (`run_control.forwarded`): it takes part, or a live
        command (checked again) for the next decision.  Only the run's commander speaks here:
        the first sender tag binds the topic."""
        node = self.node
        try:
            m = forwarded(msg.data, node.run_id)
            cmd = check_command(m['command'], node.n) if m['kind'] == 'command' else None
        except EventRefused as err:
            node.reject(err.kind, err)
            return
        except ValueError as err:
            node.reject('command', f'{P.LOCK_COMMAND}: {err}')
            return
        why = self.commander.check(m['tag'])
        if why is not None:
            node.reject(why.kind, why)
            return
        if m['seq'] <= self.commander_seq:          # a re-delivered one
            return
        self.commander_seq = m['seq']
        if cmd is None:
            self.commander_ready = True
        else:
            self.pending.append(cmd)

    def decide(self, t, pos, cos_t, sin_t, heard):
        """The decision of a step (`LockstepBarrier`): the plan, with the commands pending."""
        commands, self.pending = self.pending, []
        return self.plan.decide(t, pos, cos_t, sin_t, heard=heard, commands=commands)

    def on_event(self, ev):
        """An event of another node: nothing to follow (each decision carries the leaders)."""

    def add_fault(self, fault):
        """A live fault request (`LockstepBarrier.add_fault`): the step it applies at."""
        return self.lock.add_fault(fault)

    # ------------------------------------------------------------ actions
    def carry_out(self, action):
        """One of lockstep's own actions (`swarm_world.lockstep`): publish the clock or the step
        to the agents, or observe a step."""
        node = self.node
        kind = action[0]
        if kind == 'clock':
            node.sim_t = action[1]
            node.pub_clock.publish(P.clock_to_cdr(action[1]))
        elif kind == 'observe':
            # metrics, markers and progress are for the user, not the step: a fault in them is
            # logged and the actions after it (the step itself) still go out
            try:
                self.observe(*action[1:])
            except Exception as err:
                node.reject('observe', f'the metrics of step {action[1]} ({type(err).__name__}: '
                                       f'{str(err)[:120]}); the step goes on')
        elif kind == 'step':
            node.sim_t = action[1].t
            node.lam_now, node.leaders_now = self.lock.lam, self.lock.leaders
            raw = action[1].to_cdr(node.run_id)
            self.pub_step.publish(raw)
            self.last_msg = (self.pub_step, raw)
            self.watch.stepped(time.monotonic())

    def observe(self, k, idx):
        """Step k's checks (collisions, intrusions), progress, metrics and markers, over the
        agents ``idx`` of its table (faults: the agents alive at step k, not those of the step
        begun since: an agent resumed there has no state at k)."""
        node = self.node
        pos = node.rec.r[k, idx]
        t = k * node.dt
        names = lambda: [node.names[i] for i in idx]      # noqa: E731
        md, complaints = natural_check(node.obs, t, pos, names, node.barrier_geom, node.ground) if node.dim == 3 \
            else node.obs.check(t, pos, names, node.barrier_geom)
        for kind, text in complaints:
            node.reject(kind, text)
        el = time.monotonic() - (node.run_wall or node.wall_start)
        line = node.obs.progress(t, pos, md, node.lam_now, rate=k / el if el > 0 else 0)
        if line:
            node.log(line, flush=True)
        if node.view_every and k % node.view_every == 0:
            frames = tuple(f[k, idx] for f in (node.rec.x, node.rec.y, node.rec.z)) if node.dim == 3 else None
            node.publish_view(t, pos, frames if node.dim == 3 else node.rec.theta[k, idx], md, idx)

    # ------------------------------------------------------------ wall clock
    def tick(self):
        """Start once everyone is here (or time out); then drop missing agents, give up on a
        step that does not complete, or repeat the last message of a stalled step."""
        node = self.node
        now = time.monotonic()
        if node.other_run():
            return
        if not node.started:
            clock_readers = node.pub_clock.get_subscription_count()
            go = self.start_watch.decide(
                now, states=bool(self.lock.have.all()), relay_readers=self.pub_step.get_subscription_count(),
                commander_ready=self.commander_ready, clock_readers=clock_readers)
            if go == 'start_without_recorder':
                node.get_logger().warning(f'{P.CLOCK}: {clock_readers} readers matched, not '
                                          f'{self.start_watch.clock_want}, after '
                                          f'{P.RECORDER_MATCH_WAIT:g} s; starting anyway')
            if go in ('start', 'start_without_recorder'):
                node.started = True
                node.run_wall = now
                node.log(f'[world] lockstep: {node.n} agents and the commander discovered in '
                         f'{now - node.wall_start:.1f} s; {node.steps} steps of dt={node.dt}', flush=True)
                self.watch.stepped(now)
                node.carry_out(self.lock.start())
            elif go == 'time_out':
                poses = [node.names[i] for i in self.lock.missing() if self.awaits_robot(i)]
                node.give_up(f'discovery timed out after {self.start_timeout:.0f} s: have states of '
                             f'{int(self.lock.have.sum())}/{node.n} agents, relay readers '
                             f'{self.pub_step.get_subscription_count()}, commander '
                             f'{"ready" if self.commander_ready else "not ready"}'
                             + (f'; no robot pose from the robot world ({P.LOCK_ROBOT_STATES}) for '
                                + ', '.join(poses) if poses else ''))
            return
        what = self.watch.decide(now, complete=self.lock.complete(), can_repeat=self.last_msg is not None)
        if what == 'drop':
            for i in self.lock.missing():
                node.get_logger().warning(f'{self.state_of(i)}: none for step {self.lock.cur} within '
                                          f'{self.missing_timeout:g} s: {node.names[i]} dropped from the roster')
            node.carry_out(self.lock.drop_missing())
        elif what == 'give_up':
            node.give_up(f'step {self.lock.cur} has not completed after {now - self.watch.step_wall:.0f} s '
                         '(waiting for agents): giving up')
        elif what == 'repeat':
            waiting = ', '.join(self.state_of(i) for i in self.lock.missing())
            node.get_logger().warning(f'stalled at step {self.lock.cur} waiting for {waiting}: '
                                      'repeating the last message')
            self.last_msg[0].publish(self.last_msg[1])

    def awaits_robot(self, i) -> bool:
        """Has agent ``i``'s u of the current step come while its robot's pose has not?"""
        return self.join is not None and self.join.awaits_pose(int(i), self.lock.cur)

    def state_of(self, i) -> str:
        """What the world waits for of agent ``i`` in the current step, in words."""
        if self.awaits_robot(i):
            return f"the pose of {self.node.names[i]}'s robot ({P.LOCK_ROBOT_STATES}, from the robot world)"
        return f'the state of {self.node.names[i]}'

    # ------------------------------------------------------------ end
    def rows_done(self):
        """Rows of the trajectory so far: those whose state, λ, leaders and u are all known."""
        return self.lock.rows_done()

    def at_end(self):
        """After the trajectory is written: nothing more in lockstep."""


class RealtimeDriver:
    """Realtime: the newest state of each agent (`heard`, recorded as it comes, with its
    lateness), λ and the leaders as the commander announces them; on each tick the clock at
    the real-time factor, the scheduled radio events and faults (`schedule`, a
    `RealtimeSchedule`), the agents silent for ``missing_timeout`` wall s marked lost
    (`silence`, a `SilenceWatch`) and the view."""

    def __init__(self, node, rtf, future_tolerance, missing_timeout):
        self.node = node
        self.rtf = rtf
        self.future_tolerance = future_tolerance
        self.missing_timeout = missing_timeout
        self.silence = SilenceWatch(node.n, missing_timeout)   # a process killed from outside: lost
        # fixed leaders, then the commander's events
        self.schedule = RealtimeSchedule.of_plan(node.names, node.faults, node.scn.command_plan(), node.dt,
                                                 comms_events=comms_schedule(node.scn.spec.comms, node.dt),
                                                 view_every=node.view_every)
        self.lateness = Lateness(node.n, node.dt, rtf)     # states on time (`lateness`)
        self.heard = NewestStates(node.n, *((12, (2,)) if node.dim == 3 else ()))   # each agent's newest state
        self.next_writer_look, self.clock_writers = 0.0, set()    # `watch_clock_writers`

    def tick_period(self):
        """Wall s between the node's ticks: each publishes /clock (`realtime.clock_tick`)."""
        return clock_tick(self.node.dt, self.rtf)

    def create_endpoints(self):
        """The states of the agent processes and the commander's decisions (λ, leaders) in."""
        node = self.node
        # one message per agent process and tick; not /swarm/states (docs/ros-graph.md)
        self.sub_states = node.create_subscription(Float64MultiArray, P.AGENT_STATES, self.on_states,
                                                   P.qos_latched(max(100, 4 * node.n)), raw=True)
        # the commander's decision of each tick (not /swarm/lambda, where a user's command is for
        # the commander alone; lockstep: in each decision)
        node.create_subscription(Float64MultiArray, P.DECISION, self.on_decision, P.qos_latched(), raw=True)
        # the sim time for the run's own nodes, with the run id and a tag of this world (`run_clock`)
        self.pub_run_clock = node.create_publisher(Float64MultiArray, P.RUN_CLOCK, P.qos_reliable(P.STEP_DEPTH))
        self.clock_tag = new_sender_tag()

    # ------------------------------------------------------------ inputs
    def on_states(self, raw):
        """The states of one agent process (a serialized /swarm/agent_states message), checked
        at once as /swarm/states messages would be one by one (`msg_checks.NewestStates.take`),
        kept as the agents' newest and recorded, with their lateness (against the sim time the
        wall clock says, from the start on)."""
        node = self.node
        m = decoded(NaturalProcessStates if node.dim == 3 else ProcessStates, raw, node.run_id, node.reject,
                    'state-decode')
        if m is None or not batch_ok(m, node.names, None, node.reject):
            return
        ok = self.heard.take(m, node.names, node.sim_t, self.future_tolerance, node.reject)
        ok &= ~node.faults.dead[m.index]          # a killed or lost agent stays out (as in lockstep)
        if not ok.any():
            return
        i, t = m.index[ok], m.t[ok]
        self.silence.heard(i, time.monotonic())
        k = np.rint(t / node.dt).astype(np.int64)                 # protocol.step_of
        if node.started:
            self.lateness.arrive(i, k, t, (time.monotonic() - node.run_wall) * self.rtf)
        node.rec.record_realtime(i, k, m.pose[:, ok].T, m.u[ok], node.lam_now, node.leaders_now)

    @property
    def newest(self):
        """name -> (t, x, y, qz, qw, u) of the agents heard (for inspection)."""
        return self.heard.by_name(self.node.names)

    def on_decision(self, raw):
        """The commander's decision of a tick (serialized /swarm/decision) → the λ and the leader
        flags recorded with the states from now on, if it is a decision of this roster."""
        node = self.node
        d = decoded(NaturalDecision if node.dim == 3 else RealtimeDecision, raw, node.run_id, node.reject, 'decision')
        if d is None or refused(node.reject, check_decision_time(d, node.sim_t, self.future_tolerance)):
            return
        if not decision_valid(d.lam, d.flags, d.steering, node.n):
            node.reject('decision', f'{P.DECISION} of t={d.t:g}: λ={d.lam}, non-finite or wrong size')
            return
        node.lam_now, node.leaders_now = float(d.lam), np.array(d.flags, bool)

    def on_event(self, ev):
        """An event of another node: follow the commander's leader slots."""
        self.schedule.on_event(ev)

    def add_fault(self, fault):
        """A live fault request (`RealtimeSchedule.add_fault`): the step it applies at."""
        return self.schedule.add_fault(fault)

    def carry_out(self, action):
        """The realtime schedule has no actions of its own (only those of every mode)."""

    # ------------------------------------------------------------ tick
    def tick(self):
        """Start once every agent has been heard; then the clock, the radio events due, the view
        and the faults due, and the end at the scenario's duration."""
        node = self.node
        now = time.monotonic()
        if node.other_run():
            return
        if not node.started:
            if not np.isfinite(self.heard.t).all():
                return
            node.started = True
            node.log(f'[world] realtime: {node.n} agents discovered in {now - node.wall_start:.1f} s; '
                     f'clock at rtf {self.rtf}', flush=True)
            now = node.run_wall = time.monotonic()
            node.timer.reset()          # the ticks from the start on: one just after each period boundary
            self.lateness.start()
            self.silence.start(now)
        node.sim_t = (now - node.run_wall) * self.rtf
        node.pub_clock.publish(Clock(clock=stamp(node.sim_t)))
        self.pub_run_clock.publish(RunClock(self.clock_tag, self.rtf, node.sim_t).to_cdr(node.run_id))
        self.watch_clock_writers(now)
        k = P.step_of(node.sim_t, node.dt)
        node.carry_out(self.schedule.comms_due(k))
        self.lose_silent(now)
        if node.done:
            return
        if self.schedule.view_due(k):
            pos, theta = (natural_newest if node.dim == 3 else newest_view)(self.heard, ~node.faults.dead)
            t = k * node.dt
            md = M.min_distance(pos)                # in the plane or in space
            line = node.obs.progress(t, pos, md, node.lam_now)
            if line:
                node.log(line, flush=True)
            node.publish_view(t, pos, theta, md, timing=self.lateness.summary(k))
        acts = self.schedule.faults_due(min(k, node.steps), now)
        for a in acts:
            if a[0] == 'event':
                at = a[1]['step']
            if a[0] == 'signal' and a[1] is not None and a[2] != 'cont':
                self.lateness.excuse(a[1])          # its silence is the fault's, not lateness
            if a[0] == 'signal' and a[1] is not None and a[2] == 'kill':
                node.rec.mark_lost(a[1], at)        # gone from its kill's step, as in lockstep
        node.carry_out(acts)
        if node.sim_t >= node.scn.duration:
            node.finish()

    def watch_clock_writers(self, now):
        """Once a wall second: say once per node (at most 16) that another node writes /clock.
        The nodes of this run do not read it (they follow /swarm/clock); the recorder and tools do."""
        if now < self.next_writer_look or len(self.clock_writers) >= 16:
            return
        self.next_writer_look = now + 1.0
        node = self.node
        own = node.get_fully_qualified_name()
        for w in node.get_publishers_info_by_topic(P.CLOCK):
            name = f'{w.node_namespace.rstrip("/")}/{w.node_name}'
            if name != own and name not in self.clock_writers:
                self.clock_writers.add(name)
                node.get_logger().warning(f'another writer of {P.CLOCK}: {name}; the nodes of this run do not read '
                                          f'it (they follow {P.RUN_CLOCK}), the recorder and the tools do')

    def lose_silent(self, now):
        """The agents (neither dead nor frozen) silent for ``missing_timeout`` wall s are lost
        (`RealtimeSchedule.lose`): a ``lost`` event, out of the view and of the trajectory from
        the step after their newest state, their gaps not lateness."""
        node = self.node
        gone, silent_for = self.silence.silent(now, ~node.faults.dead & ~node.faults.frozen)
        if not gone.size:
            return
        for i in gone:
            node.get_logger().warning(f'no state from {node.names[i]} for {silent_for:.1f} s (missing_timeout '
                                      f'{self.missing_timeout:g} s): {node.names[i]} is lost')
        acts, since = self.schedule.lose(gone, self.heard.t, node.dt, silent_for)
        for i, k_gone in since.items():
            node.rec.mark_lost(i, k_gone)
            self.lateness.excuse(i)
        node.carry_out(acts)

    # ------------------------------------------------------------ end
    def rows_done(self):
        """Rows of the trajectory so far: up to the sim time now."""
        node = self.node
        return min(P.step_of(node.sim_t, node.dt), node.steps) + 1

    def at_end(self):
        """After the trajectory is written (the launcher reads both once the world ends): the
        timing (`lateness`) logged in one line (and one more if the run fell behind), written
        to ``output_dir/timing.json`` for ``swarm run``."""
        node = self.node
        s = self.lateness.summary(min(P.step_of(node.sim_t, node.dt), node.steps))
        node.log(f'[world] {timing_line(s)}', flush=True)
        behind = behind_line(s, self.rtf)
        if behind:
            node.log(f'[world] {behind}', flush=True)
        if node.output_dir:
            write_atomic(Path(node.output_dir) / TIMING_FILE, json.dumps(dict(s, rtf=self.rtf)))
        return s


#: the modes of a world node (parameter ``mode``, `parameters.MODES`) and the class that drives each
DRIVERS = {'lockstep': LockstepDriver, 'realtime': RealtimeDriver}
