"""WorldNode: sim time, the lockstep barrier, target and barrier, swarm view and metrics.

The node holds parameters, publishers, subscriptions, timers, signals and files (its realtime
inputs and tick in `realtime_node`); the logic lives in pure modules: `lockstep` (the barrier), `realtime` (the realtime schedule),
`wallclock` (start, stalls, time-outs), `observe` (checks, progress), `inputs` (parsing),
`markers` (messages) and `swarm_core.trajectory` (the record).  The world writes
``trajectory.npz`` to ``output_dir`` at the end and every event to ``events_file``.
Target and barrier are movable: ``ros2 param set /world target "400,0"``.  Faults: the
scenario's at their steps, live ones (``/swarm/fault_request``) at the next step, with
SIGKILL / SIGSTOP / SIGCONT by the pids in ``pid_file``.  See docs/ros-graph.md and docs/faults.md.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PolygonStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64, Float64MultiArray, String
from visualization_msgs.msg import MarkerArray

from swarm_core import metrics as M
from swarm_core.atomic import open_regular
from swarm_core.robot_units import ROBOT_KINDS
from swarm_core.trajectory import Trajectory, TrajectoryRecorder

from swarm_ros import protocol as P
from swarm_ros.layouts import AgentStates, Decision, RobotStates
from swarm_ros.msg_checks import (NewestStates, ProcessSenders, RejectLog, check_agent_states, decoded, may_signal,
                                  reason)
from swarm_ros.rosutil import ParameterError, declare, run_node, steady_clock
from swarm_ros.runinfo import RunWatch, declare_run_id, give_way, older_runs, parse_robots_text, run_json
from swarm_ros.scenario_params import declare_scenario

from .inputs import fault_request, format_points, parse_geometry, parse_point, parse_points
from .lockstep import LockstepBarrier, RobotPoseJoin, comms_schedule, decision_valid
from .lateness import TIMING_FILE, Lateness
from .markers import Trails, geometry_messages, markers_every, markers_message, metrics_message, view_values
from .observe import Observer
from .parameters import WORLD
from .realtime import RealtimeSchedule, clock_tick
from .realtime_node import RealtimeWorld
from .wallclock import StallWatch, StartWatch


SIGNALS = {'kill': signal.SIGKILL, 'stop': signal.SIGSTOP, 'cont': signal.SIGCONT}


#: before its first step the world listens this long (wall s) for another run on the domain:
#: its own agents may be discovered in 0.2 s, an older run's announcement can come later
ANNOUNCE_SETTLE = 2.0


class WorldNode(RealtimeWorld, Node):
    def __init__(self, node_name='world', *, namespace=None, context=None, parameter_overrides=None,
                 cli_args=None, log=print):
        super().__init__(node_name, namespace=namespace, context=context, cli_args=cli_args,
                         parameter_overrides=parameter_overrides)
        self.log = log
        self._declare_parameters()
        # faults (swarm_core.faults): the same timeline as the batch engine
        self.faults = self.scn.fault_timeline()
        self.events = []
        self.pids = None
        self._open_events_file()
        self.add_on_set_parameters_callback(self._on_params)
        self.reject = RejectLog(self.get_logger())
        self._create_endpoints()
        self._create_logic()
        self.last_msg = None
        self.started = False
        self.done = False
        self.failed = None
        self.wall_start = time.monotonic()
        self.run_wall = None
        self.trails = Trails(self.n, self.trail_length)
        self.views = -1          # views published (markers: every `markers_every`)
        self.sim_t = 0.0
        self.lam_now = 0.0
        self.leaders_now = np.zeros(self.n, bool)
        self.pub_events = self.create_publisher(String, P.EVENTS, P.qos_latched(100))
        self.publish_geometry()
        self.timer = self.create_timer(0.05 if self.mode == 'lockstep' else clock_tick(self.dt, self.rtf),
                                       self._on_timer, clock=steady_clock())

    def _declare_parameters(self):
        """The world's parameters (`parameters.WORLD`, kept as attributes), the run id, the
        scenario (`declare_scenario`) and its movable target and barrier."""
        d = lambda *a, **k: declare(self, *a, **k)  # noqa: E731
        for nm, (default, text, lim) in WORLD.items():
            setattr(self, nm, d(nm, default, text, **lim))
        self.run_id = declare_run_id(self, 'carried on the lockstep messages, announced on /swarm/run; '
                                     'an older run on the domain makes the world give way')
        self.scn = declare_scenario(self)
        self.names = list(self.scn.names)
        self.n = len(self.names)
        self.row = {nm: i for i, nm in enumerate(self.names)}
        self.dt = self.scn.dt
        self.steps = self.scn.steps
        self.w = self.scn.law.cutoff_radius
        self.target = self.scn.target
        self.barrier = self.scn.barrier
        try:
            self.target = parse_point(d('target', format_points(self.target), 'target "x,y" ("" = none); movable'))
            self.barrier = parse_points(d('barrier', format_points(self.barrier),
                                          'barrier hull "x,y;x,y;..." ("" = none); movable'))
        except ValueError as err:
            raise ParameterError(f'parameter target/barrier: {err}') from None
        self.barrier_geom = M.Barrier(self.barrier) if self.barrier is not None else None

    def _open_events_file(self):
        """``events_file`` (default ``output_dir/events.jsonl``) made empty."""
        if not self.events_file and self.output_dir:
            self.events_file = str(Path(self.output_dir) / 'events.jsonl')
        if self.events_file:
            Path(self.events_file).parent.mkdir(parents=True, exist_ok=True)
            open_regular(self.events_file, 'w').close()      # never through a planted link
        if self.output_dir:
            (Path(self.output_dir) / TIMING_FILE).unlink(missing_ok=True)     # an older run's

    def _create_endpoints(self):
        """Publishers and subscriptions (protocol: names and QoS); announces the run on /swarm/run."""
        self.pub_clock = self.create_publisher(Clock, P.CLOCK, P.qos_reliable(P.STEP_DEPTH))
        self.pub_target = self.create_publisher(PointStamped, P.TARGET, P.qos_latched())
        self.pub_barrier = self.create_publisher(PolygonStamped, P.BARRIER, P.qos_latched())
        self.pub_markers = self.create_publisher(MarkerArray, P.MARKERS, 5)
        self.pub_metrics = self.create_publisher(DiagnosticArray, P.METRICS, 10)
        self.create_subscription(String, P.EVENTS, self._on_event, P.qos_latched(100))
        self.create_subscription(String, P.FAULT_REQUEST, self._on_fault_request, P.qos_latched(10))
        if self.mode == 'realtime':
            # one message per agent process and tick; not /swarm/states (docs/ros-graph.md)
            self.sub_states = self.create_subscription(Float64MultiArray, P.AGENT_STATES, self._on_state,
                                                       P.qos_latched(max(100, 4 * self.n)), raw=True)
        else:       # one message per agent process and step (protocol: /lockstep/agent_states)
            self.sub_states = self.create_subscription(Float64MultiArray, P.LOCK_AGENT_STATES, self._on_agent_states,
                                                       P.qos_latched(max(100, 4 * self.n)), raw=True)
            self.process_senders = ProcessSenders(self.n)
        # the run's identity; other runs on this domain are heard here (and refused before the start)
        self.pub_run = self.create_publisher(String, P.RUN, P.qos_latched())
        self.since = time.time()
        remote = [nm for nm in self.remote_agents.split(',') if nm]
        try:
            robots = parse_robots_text(self.remote_robots, remote, ROBOT_KINDS[1:])
        except ValueError as err:
            raise ParameterError(f'parameter remote_robots: {err}') from None
        self.pub_run.publish(String(data=run_json(self.run_id, self.scn.name, self.mode, self.names, self.since,
                                                  self.scn.content_hash, remote, robots)))
        self.runs = RunWatch(self, log=self.get_logger().warning)
        self.second_world_at = None     # when a second /world node was first seen (no announcement yet)
        if self.mode == 'realtime':
            self.create_subscription(Float64, P.LAMBDA, self._on_lambda, P.qos_latched(10))  # the commander's
            # the leaders as the commander announces them (lockstep: in each decision)
            self.create_subscription(String, P.LEADERS, self._on_leaders, P.qos_latched())
        if self.mode == 'lockstep':
            self.pub_lock_states = self.create_publisher(Float64MultiArray, P.LOCK_STATES, P.qos_latched())
            self.pub_step = self.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
            self.sub_decision = self.create_subscription(Float64MultiArray, P.LOCK_DECISION, self._on_decision,
                                                         P.qos_latched(), raw=True)
            self.join = None
            robots = [nm.strip() for nm in self.robot_poses.split(',') if nm.strip()]
            if robots:          # their poses from the robot world, u from their answers (`RobotPoseJoin`)
                unknown = [nm for nm in robots if nm not in self.row]
                if unknown:
                    raise ParameterError(f'parameter robot_poses: no agent {", ".join(unknown)} in the scenario')
                self.join = RobotPoseJoin([self.row[nm] for nm in robots], self.n)
                self.create_subscription(Float64MultiArray, P.LOCK_ROBOT_STATES, self._on_robot_states,
                                         P.qos_latched(), raw=True)

    def _create_logic(self):
        """The lockstep barrier or the realtime schedule, the record, the checks and the
        wall-clock watches (pure modules)."""
        comms_events = comms_schedule(self.scn.spec.comms, self.dt)
        self.rec = TrajectoryRecorder(self.names, self.steps, self.dt, self.scn.theta0,
                                      realtime=self.mode == 'realtime')
        self.lock = LockstepBarrier(self.names, self.steps, self.dt, self.faults, self.rec,
                                    comms_events=comms_events, clock_every=self.clock_every,
                                    geometry=lambda: (self.target, self.barrier))
        # realtime: fixed leaders, then the commander's events
        self.rt = RealtimeSchedule(self.names, self.faults, self.scn.command_plan().slots, comms_events,
                                   self.view_every)
        self.obs = Observer(self.collision_distance, self.w, self.progress_every)
        self.lateness = Lateness(self.n, self.dt, self.rtf)     # realtime: states on time (`lateness`)
        self.heard = NewestStates(self.n)     # realtime: each agent's newest accepted state
        self.start_watch = StartWatch(time.monotonic(), self.n, start_timeout=self.start_timeout,
                                      relay_want=self.step_readers, clock_want=self.clock_readers,
                                      wait_for_recorder=self.wait_for_recorder,
                                      recorder_wait=P.RECORDER_MATCH_WAIT)
        self.watch = StallWatch(time.monotonic(), missing_timeout=self.missing_timeout,
                                step_timeout=self.step_timeout, stall_timeout=self.stall_timeout)

    # ------------------------------------------------------------ geometry
    def _on_params(self, params):
        values = {p.name: p.value for p in params if p.name in ('target', 'barrier')}
        try:
            new_t, new_b = parse_geometry(values, self.target, self.barrier)
        except (ValueError, TypeError) as err:
            self.get_logger().warning(f'rejected parameter: {err}')
            return SetParametersResult(successful=False, reason=str(err))
        if values:
            self.target, self.barrier = new_t, new_b
            self.barrier_geom = M.Barrier(self.barrier) if self.barrier is not None and len(self.barrier) >= 3 else None
            self.publish_geometry()
            self.get_logger().info(f'world geometry: target={self.target}, barrier={format_points(self.barrier) or None}')
        return SetParametersResult(successful=True)

    def publish_geometry(self):
        target, barrier = geometry_messages(self.sim_t if hasattr(self, 'sim_t') else 0.0, self.target, self.barrier)
        if target is not None:
            self.pub_target.publish(target)
        self.pub_barrier.publish(barrier)

    # ------------------------------------------------------------ inputs
    def _on_agent_states(self, raw):
        """Lockstep: the states of one agent process's agents (serialized /lockstep/agent_states)."""
        m = decoded(AgentStates, raw, self.run_id, self.reject, 'state-decode')
        if m is None:
            return
        tag, idx, ks, vals, u = m.tag, m.index, m.step, m.pose, m.u
        why = check_agent_states(idx, vals, self.n)
        if why is None:
            ok, why = self.process_senders.check(idx, tag)
            if not ok.all():
                idx, ks, vals, u = idx[ok], ks[ok], vals[:, ok], u[ok]
        if why is not None:
            self.reject(why.kind, why)
        if idx.size == 0 or why is not None and why.kind != 'second-publisher':
            return
        self.process_senders.accept(idx, tag)
        if self.join is not None:
            idx, ks, vals, u = self.join.from_agents(idx, ks, vals, u)
        self.take_states(idx, ks, vals, u)

    def _on_robot_states(self, raw):
        """Lockstep: the robot world's poses of its robots' agents at one step (`RobotPoseJoin`)."""
        m = decoded(RobotStates, raw, self.run_id, self.reject, 'robot-decode')
        if m is None:
            return
        try:
            idx, ks, vals, u = self.join.from_robots(m.n, m.index, m.pose)
        except ValueError as err:
            self.reject('robot-rows', f'{P.LOCK_ROBOT_STATES}: {err}')
            return
        self.take_states(idx, ks, vals, u)

    def take_states(self, idx, ks, vals, u):
        """States (`LockstepBarrier.on_states`) into the barrier, and what it decides done."""
        self.watch.progressed(time.monotonic())
        if idx.size == 0:           # a robot agent's u whose pose has not come (`RobotPoseJoin`)
            return
        late, acts = self.lock.on_states(idx, ks, vals, u)
        for text in late[:1]:
            self.reject('step', text)
        self.act(acts)

    def _on_decision(self, raw):
        d = decoded(Decision, raw, self.run_id, self.reject, 'decision')
        if d is None or d.n != self.lock.cur or self.lock.decision is not None:
            return
        if not decision_valid(d.lam, d.flags, d.steering, self.n):
            self.reject('decision', f'commander decision for step {d.n}: λ={d.lam}, non-finite or wrong size')
            return
        self.watch.progressed(time.monotonic())
        self.act(self.lock.on_decision(d.n, d.lam, d.flags, d.steering, d.slots, d.rendezvous))

    # ------------------------------------------------------------ lockstep
    def other_run(self):
        """Refuse to start (one error line, exit 1) rather than mix with an older run
        (runinfo.give_way); once started, go on whatever is announced."""
        worlds = 1 if self.started else sum(
            1 for nm, ns in self.get_node_names_and_namespaces() if nm == 'world' and ns == '/')
        if not self.started and time.monotonic() - self.wall_start < ANNOUNCE_SETTLE:
            return True     # give discovery a moment to bring an older run's announcement
        if worlds > 1 and not older_runs(self.runs.runs, self.run_id, self.since):
            # a second world seen before its /swarm/run: hold the start a moment to hear which run
            now = time.monotonic()
            self.second_world_at = self.second_world_at or now
            if now - self.second_world_at < 3.0:
                return True
        self.failed = give_way(self.runs.runs, self.run_id, self.since, worlds, self.started,
                               os.environ.get('ROS_DOMAIN_ID', '0'))
        if self.failed is None:
            return False
        self.get_logger().error(self.failed)
        self.done = True
        return True

    def act(self, actions):
        """Carry out what the lockstep barrier decided (swarm_world.lockstep), in order."""
        for a in actions:
            kind = a[0]
            if kind == 'clock':
                self.sim_t = a[1]
                self.pub_clock.publish(P.clock_to_cdr(a[1]))
            elif kind == 'states':
                self.sim_t = a[1].t
                raw = a[1].to_cdr(self.run_id)
                self.pub_lock_states.publish(raw)
                self.last_msg = (self.pub_lock_states, raw)
            elif kind == 'observe':
                self.observe(a[1])
            elif kind == 'comms':
                self.pub_events.publish(String(data=P.event_json('comms', a[1] * self.dt, source='scenario', **a[2])))
            elif kind == 'step':
                self.lam_now, self.leaders_now = self.lock.lam, self.lock.leaders
                raw = a[1].to_cdr(self.run_id)
                self.pub_step.publish(raw)
                self.last_msg = (self.pub_step, raw)
                self.watch.stepped(time.monotonic())
            elif kind == 'event':
                self.emit(a[1])
            elif kind == 'signal':
                self.signal_agent(a[1], SIGNALS[a[2]])
            elif kind == 'finish':
                self.finish()
            elif kind == 'fail':
                self.give_up(a[1])

    # ------------------------------------------------------------ events, faults
    def emit(self, ev):
        ev = dict(ev, node='world')
        self.events.append(ev)
        self.log(f'[world] event t={ev["t"]:.2f}: {ev["kind"]} {ev.get("agent", "")}', flush=True)
        self.pub_events.publish(String(data=json.dumps(ev)))
        self.write_event(ev)

    def write_event(self, ev):
        if self.events_file:
            with open_regular(self.events_file, 'a') as f:
                f.write(json.dumps(ev) + '\n')

    def _on_event(self, msg):
        try:
            ev = json.loads(msg.data)
        except ValueError:
            self.reject('event-json', f'{P.EVENTS}: not JSON: {msg.data[:80]!r}')
            return
        if isinstance(ev, dict) and ev.get('node') != 'world':
            self.events.append(ev)
            self.write_event(ev)
            if self.mode == 'realtime':
                self.rt.on_event(ev)

    def _on_fault_request(self, msg):
        try:
            f = fault_request(msg.data)
            k = (self.lock if self.mode == 'lockstep' else self.rt).add_fault(f)
        except (ValueError, KeyError, TypeError) as err:
            self.reject('fault-request', f'{P.FAULT_REQUEST} {msg.data[:80]!r}: {err}')
            return
        self.get_logger().info(f'fault request: {f.kind} {f.agent}'
                               + (f' for {f.duration:g} s' if f.kind == 'freeze' else '') + f' at step {k}')

    def signal_agent(self, i, sig):
        """Send ``sig`` to agent i's process (pid from ``pid_file``), if there is one."""
        if i is None or not self.pid_file:
            return
        if self.pids is None:
            try:
                self.pids = json.loads(Path(self.pid_file).read_text())
            except (OSError, ValueError) as err:
                self.get_logger().warning(f'pid_file {self.pid_file}: {err}; faults only leave agents out')
                self.pids = {}
        pid = self.pids.get(self.names[i])
        if pid is None or list(self.pids.values()).count(pid) > 1:
            return                    # a container holds this agent: it obeys /swarm/events itself
        # only a live child of our launcher running that agent's node (never any pid in a file)
        refused = may_signal(pid, self.names[i], os.getppid())
        if refused is not None:
            self.reject('signal', reason('signal', f'{signal.Signals(sig).name} to {self.names[i]}: {refused}'))
            return
        try:
            os.kill(int(pid), sig)
        except ProcessLookupError:
            pass

    # ------------------------------------------------------------ view
    def observe(self, k):
        """Lockstep: step k's checks (collisions, intrusions), progress, metrics and markers."""
        idx = np.flatnonzero(self.faults.alive)         # faults: only agents in the table
        pos = self.rec.r[k, idx]
        t = k * self.dt
        md, complaints = self.obs.check(t, pos, [self.names[i] for i in idx], self.barrier_geom)
        for kind, text in complaints:
            self.reject(kind, text)
        el = time.monotonic() - (self.run_wall or self.wall_start)
        line = self.obs.progress(t, pos, md, self.lam_now, rate=k / el if el > 0 else 0)
        if line:
            self.log(line, flush=True)
        if self.view_every and k % self.view_every == 0:
            self.publish_view(t, pos, self.rec.theta[k, idx], md, idx)

    def publish_view(self, t, pos, theta, md, idx=None, timing=None):
        """Metrics and markers of agents ``idx`` (default all) at rows pos, theta; realtime:
        with the ``timing`` so far (`Lateness.summary`)."""
        idx = np.arange(len(pos)) if idx is None else idx
        c, labels = M.cluster_labels(pos, self.w)
        leaders = [self.names[i] for i in np.flatnonzero(self.leaders_now)]
        vals = view_values(t, pos, theta, c, md, self.lam_now, leaders, self.target,
                           intrusions=self.obs.intrusions, collisions=self.obs.collisions,
                           cutoff_radius=self.w, **(timing or {}))   # cutoff: what `swarm report` counts clusters by
        self.pub_metrics.publish(metrics_message(t, vals))
        self.views += 1
        if self.views % markers_every(self.n) or self.pub_markers.get_subscription_count() == 0:
            return
        self.pub_markers.publish(markers_message(t, pos, theta, labels, idx, self.leaders_now, self.trails,
                                                 self.target, self.barrier))

    # ------------------------------------------------------------ timer, end
    def _on_timer(self):
        if self.done:
            return
        if self.mode == 'realtime':
            self.rt_tick()
            return
        now = time.monotonic()
        if self.other_run():
            return
        if not self.started:
            clock_readers = self.pub_clock.get_subscription_count()
            go = self.start_watch.decide(
                now, states=bool(self.lock.have.all()), relay_readers=self.pub_step.get_subscription_count(),
                commander_readers=self.pub_lock_states.get_subscription_count(),
                decision_writers=self.sub_decision.handle.get_publisher_count(), clock_readers=clock_readers)
            if go == 'start_without_recorder':
                self.get_logger().warning(f'{P.CLOCK}: {clock_readers} readers matched, not {self.start_watch.clock_want}, after '
                                          f'{P.RECORDER_MATCH_WAIT:g} s; starting anyway')
            if go in ('start', 'start_without_recorder'):
                self.started = True
                self.run_wall = now
                self.log(f'[world] lockstep: {self.n} agents and the commander discovered in '
                         f'{now - self.wall_start:.1f} s; {self.steps} steps of dt={self.dt}', flush=True)
                self.watch.stepped(now)
                self.act(self.lock.start())
            elif go == 'time_out':
                poses = [self.names[i] for i in self.lock.missing() if self.awaits_robot(i)]
                self.give_up(f'discovery timed out after {self.start_timeout:.0f} s: have states of '
                             f'{int(self.lock.have.sum())}/{self.n} agents, relay readers '
                             f'{self.pub_step.get_subscription_count()}, commander '
                             f'{"yes" if self.pub_lock_states.get_subscription_count() else "no"}'
                             + (f'; no robot pose from the robot world ({P.LOCK_ROBOT_STATES}) for '
                                + ', '.join(poses) if poses else ''))
            return
        what = self.watch.decide(now, states_out=self.lock.states_out, complete=self.lock.complete(),
                                 can_repeat=self.last_msg is not None)
        if what == 'drop':
            for i in self.lock.missing():
                self.get_logger().warning(f'{self.state_of(i)}: none for step {self.lock.cur} within '
                                          f'{self.missing_timeout:g} s: {self.names[i]} dropped from the roster')
            self.act(self.lock.drop_missing())
        elif what == 'give_up':
            self.give_up(f'step {self.lock.cur} has not completed after {now - self.watch.step_wall:.0f} s '
                         f'(waiting for {"the commander" if self.lock.states_out else "agents"}): giving up')
        elif what == 'repeat':
            waiting = ("the commander's decision" if self.lock.states_out else
                       ', '.join(self.state_of(i) for i in self.lock.missing()))
            self.get_logger().warning(f'stalled at step {self.lock.cur} waiting for {waiting}: repeating the last message')
            self.last_msg[0].publish(self.last_msg[1])

    def awaits_robot(self, i) -> bool:
        """Lockstep: has agent ``i``'s u of the current step come while its robot's pose has not?"""
        return self.join is not None and self.join.awaits_pose(int(i), self.lock.cur)

    def state_of(self, i) -> str:
        """What the world waits for of agent ``i`` in the current step, in words."""
        if self.awaits_robot(i):
            return f"the pose of {self.names[i]}'s robot ({P.LOCK_ROBOT_STATES}, from the robot world)"
        return f'the state of {self.names[i]}'

    def give_up(self, why):
        """End the run with an error (exit 1), keeping the steps completed so far."""
        self.failed = why
        self.get_logger().error(why)
        self.save_partial()
        self.done = True

    def trajectory(self) -> Trajectory:
        return self.rec.trajectory(meta=dict(
            scenario=self.scn.name, seed=self.scn.seed, dt=self.dt, duration=self.scn.duration,
            steps=self.steps, source='ros', mode=self.mode,
            wall_seconds=time.monotonic() - (self.run_wall or self.wall_start), events=list(self.events)))

    def finish(self):
        self.done = True
        wall = time.monotonic() - (self.run_wall or self.wall_start)
        self.log(f'[world] finished t={self.scn.duration:g} ({self.steps} steps) in {wall:.1f} s '
                 f'({self.steps / wall if wall > 0 else 0:.0f} steps/s); collisions={self.obs.collisions} '
                 f'intrusions={self.obs.intrusions}', flush=True)
        if self.output_dir:
            out = Path(self.output_dir)
            out.mkdir(parents=True, exist_ok=True)
            self.trajectory().save(out / 'trajectory.npz')
        if self.mode == 'realtime':
            self.rt_timing()           # after the trajectory: the launcher reads both once the world ends

    def save_partial(self):
        """Stopped (Ctrl-C / SIGTERM) before the end: write the steps completed so far to
        ``output_dir`` (as ``swarm simulate`` keeps the computed part of an interrupted run).
        Lockstep: the rows whose state, λ, leaders and u are all known; realtime: up to now."""
        if not self.output_dir or not self.started or self.done:
            return None
        if self.mode == 'realtime':
            rows = min(P.step_of(self.sim_t, self.dt), self.steps) + 1
        else:
            rows = self.lock.rows_done()
        if rows < 1:
            return None
        part = self.trajectory().head(rows)
        out = Path(self.output_dir)
        out.mkdir(parents=True, exist_ok=True)
        path = part.save(out / 'trajectory.npz')
        self.log(f'[world] stopped at t={part.t[-1]:g}: saved t = 0..{part.t[-1]:g} ({rows} samples) to {path}', flush=True)
        if self.mode == 'realtime':
            self.rt_timing()
        return path

def main(argv=None):
    return run_node(WorldNode, 'swarm_world', argv, done=lambda node: node.done,
                    on_stop=lambda node: node.save_partial(),
                    exit_code=lambda node: 0 if (node.done and node.failed is None)
                    else (1 if node.failed else 130))


if __name__ == '__main__':
    sys.exit(main())
