"""WorldNode: sim time, the lockstep barrier, target and barrier, swarm view and metrics.

See `swarm_ros.protocol` for the message flow.  The world loads the same scenario as the
other nodes (for the roster, duration, target and barrier), records what the agents publish
and, at the end, writes ``trajectory.npz`` (the batch engine's format) to ``output_dir``.
Target and barrier can be moved during a run: ``ros2 param set /world target "400,0"``,
``ros2 param set /world barrier "x,y;x,y;…"`` (empty string: none).

Faults (swarm_core.faults; protocol.py for the layout): the world runs the scenario's
`FaultTimeline` at exactly the scheduled steps and applies live requests from
``/swarm/fault_request`` (``swarm kill`` / ``swarm pause``) at its next step.  It sends the
agent's process SIGKILL (kill), SIGSTOP (freeze: once it holds the agent's state of the freeze
step) and SIGCONT (resume), by the pid in ``pid_file`` (written by ``swarm run --processes``;
no file: the agent is only left out of the table, which it obeys).  An agent whose state does
not come within ``missing_timeout`` wall seconds is dropped from the roster (event ``lost``)
and the run goes on.  Every event is published on ``/swarm/events`` and appended (with the
commander's events) to ``events_file`` (JSON lines).
"""
from __future__ import annotations

import json
import math
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point32, PointStamped, PolygonStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64, Float64MultiArray, String
from visualization_msgs.msg import MarkerArray

from swarm_core import metrics as M
from swarm_core.faults import FAULT_KINDS, Fault, track_slots
from swarm_core.frenet import yaw_from_quaternion
from swarm_core.scenario import ScenarioError, load
from swarm_core.trajectory import Trajectory, TrajectoryRecorder

from swarm_ros import protocol as P
from swarm_ros.msg_checks import check_values
from .lockstep import LockstepBarrier
from .markers import Trails, markers_message, metrics_message, stamp, view_values
from swarm_ros.rosutil import ParameterError, RejectLog, declare, run_node, steady_clock


SIGNALS = {'kill': signal.SIGKILL, 'stop': signal.SIGSTOP, 'cont': signal.SIGCONT}


def parse_point(text):
    text = text.strip()
    if not text:
        return None
    vals = [float(v) for v in text.split(',')]
    if len(vals) != 2 or not all(math.isfinite(v) for v in vals):
        raise ValueError(f'{text!r} is not "x,y" with finite numbers')
    return np.array(vals)


def parse_points(text):
    text = text.strip()
    if not text:
        return None
    pts = [parse_point(p) for p in text.split(';') if p.strip()]
    return np.array(pts) if pts else None


def format_points(pts):
    return '' if pts is None else ';'.join(f'{float(x)!r},{float(y)!r}' for x, y in np.atleast_2d(pts))


class WorldNode(Node):
    def __init__(self, node_name='world', *, namespace=None, context=None, parameter_overrides=None,
                 cli_args=None, log=print):
        super().__init__(node_name, namespace=namespace, context=context, cli_args=cli_args,
                         parameter_overrides=parameter_overrides)
        d = lambda *a, **k: declare(self, *a, **k)  # noqa: E731
        self.log = log
        scenario = d('scenario', 'homotopy_global', 'scenario name or YAML path')
        seed = d('seed', -1, "seed (-1: the scenario's)", lo=-1, hi=2**31 - 1)
        duration = d('duration', 0.0, "run length in sim s (0: the scenario's)", lo=0.0, hi=1e9)
        dt = d('dt', 0.0, "step (0: the scenario's)", lo=0.0, hi=10.0)
        self.mode = d('mode', 'lockstep', 'lockstep or realtime', choices=('lockstep', 'realtime'))
        self.rtf = d('rtf', 1.0, 'realtime: sim seconds per wall second', lo=1e-3, hi=1e4)
        self.output_dir = d('output_dir', '', 'where to write trajectory.npz at the end ("": nowhere)')
        self.progress_every = d('progress_every', 50.0, 'progress line every this many sim s (0: none)', lo=0.0, hi=1e9)
        self.view_every = d('view_every', 20, 'markers and metrics every this many steps (0: never)', lo=0, hi=10**9)
        self.clock_every = d('clock_every', 1, 'lockstep: publish /clock every this many steps (every node '
                             'receives each one; lockstep inputs carry their own time)', lo=1, hi=10**9)
        self.stall_timeout = d('stall_timeout', 2.0, 'lockstep: repeat the last message after this many wall s', lo=0.1, hi=1e6)
        self.wait_for_recorder = d('wait_for_recorder', False, 'lockstep: start step 0 only once /clock has '
                                   'one reader more than the agents and the commander (a recorder; '
                                   f'at most {P.RECORDER_MATCH_WAIT:g} s)')
        self.recorder_wait_from = None  # when everyone but the recorder was matched (wall s)
        self.step_timeout = d('step_timeout', 120.0, 'lockstep: give up (exit 1) if one step has not completed '
                              'after this many wall s', lo=1.0, hi=1e9)
        self.start_timeout = d('start_timeout', 180.0, 'give up if not everyone is discovered in this many wall s', lo=1.0, hi=1e6)
        self.collision_distance = d('collision_distance', 0.01, 'pairs closer than this count as a collision', lo=0.0, hi=1e6)
        self.missing_timeout = d('missing_timeout', 10.0, 'lockstep: drop an agent whose state has not come after this many wall s',
                                 lo=0.1, hi=1e6)
        self.step_readers = d('step_readers', 0, 'lockstep: readers of the step relay to wait for '
                              '(one per agent process; 0: one per agent)', lo=0, hi=100000)
        self.clock_readers = d('clock_readers', 0, 'with wait_for_recorder: /clock readers to wait for '
                               '(0: agents + commander + recorder)', lo=0, hi=100000)
        self.pid_file = d('pid_file', '', 'JSON {agent: pid} of the agent processes, for kill/pause ("": none)')
        self.events_file = d('events_file', '', 'append every event here as JSON lines ("": output_dir/events.jsonl)')
        self.trail_length = d('trail_length', 200, 'trail points per agent in the markers', lo=0, hi=100000)
        try:
            self.scn = load(scenario, seed=None if seed < 0 else seed,
                            duration=duration or None, dt=dt or None)
        except ScenarioError as err:
            raise ParameterError(f'parameter scenario: {err}') from None
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
        # faults (swarm_core.faults): the same timeline as the batch engine
        self.faults = self.scn.fault_timeline()
        self.events = []
        self.pids = None
        self.rt_fault_step = -1
        self.rt_slots = dict(self.scn.command_plan().slots)   # realtime: fixed leaders; then the commander's events
        if not self.events_file and self.output_dir:
            self.events_file = str(Path(self.output_dir) / 'events.jsonl')
        if self.events_file:
            Path(self.events_file).parent.mkdir(parents=True, exist_ok=True)
            Path(self.events_file).write_text('')
        self.add_on_set_parameters_callback(self._on_params)
        self.reject = RejectLog(self.get_logger())

        self.pub_clock = self.create_publisher(Clock, P.CLOCK, P.qos_reliable(P.STEP_DEPTH))
        self.pub_target = self.create_publisher(PointStamped, P.TARGET, P.qos_latched())
        self.pub_barrier = self.create_publisher(PolygonStamped, P.BARRIER, P.qos_latched())
        self.pub_markers = self.create_publisher(MarkerArray, P.MARKERS, 5)
        self.pub_metrics = self.create_publisher(DiagnosticArray, P.METRICS, 10)
        self.create_subscription(String, P.EVENTS, self._on_event, P.qos_latched(100))
        self.create_subscription(String, P.FAULT_REQUEST, self._on_fault_request, P.qos_latched(10))
        self.sub_states = self.create_subscription(Odometry, P.STATES, self._on_state,
                                                   P.qos_latched(max(100, 4 * self.n)), raw=True)
        if self.mode == 'realtime':
            self.create_subscription(Float64, P.LAMBDA, self._on_lambda, P.qos_reliable())
            # the leaders as the commander announces them (lockstep: in each decision)
            self.create_subscription(String, P.LEADERS, self._on_leaders, P.qos_latched())
        if self.mode == 'lockstep':
            self.pub_lock_states = self.create_publisher(Float64MultiArray, P.LOCK_STATES, P.qos_latched())
            self.pub_step = self.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
            self.sub_decision = self.create_subscription(Float64MultiArray, P.LOCK_DECISION, self._on_decision,
                                                         P.qos_latched(), raw=True)

        # the lockstep barrier and the record (swarm_world.lockstep, swarm_core.trajectory)
        from swarm_core.comms import event_step
        cspec = self.scn.spec.comms
        comms_events = sorted(((event_step(e.at, self.dt), e.model_dump(exclude_none=True))
                               for e in (cspec.events if cspec else [])), key=lambda se: se[0])
        self.rec = TrajectoryRecorder(self.names, self.steps, self.dt, self.scn.theta0,
                                      realtime=self.mode == 'realtime')
        self.lock = LockstepBarrier(self.names, self.steps, self.dt, self.faults, self.rec,
                                    comms_events=comms_events, clock_every=self.clock_every,
                                    geometry=lambda: (self.target, self.barrier))
        self.rt_comms = list(comms_events)      # realtime: published when the clock passes them
        self.newest = {}         # name -> (t, x, y, qz, qw) newest accepted
        self.step_wall = time.monotonic()
        self.last_msg = None
        self.last_progress = time.monotonic()
        self.started = False
        self.done = False
        self.failed = None
        self.wall_start = time.monotonic()
        self.run_wall = None
        self.intrusions = 0
        self.collisions = 0
        self.trails = Trails(self.n, self.trail_length)
        self.sim_t = 0.0
        self.lam_now = 0.0
        self.leaders_now = np.zeros(self.n, bool)
        self.next_progress = 0.0
        self.pub_events = self.create_publisher(String, P.EVENTS, P.qos_latched(100))
        self.publish_geometry()
        self.timer = self.create_timer(0.05 if self.mode == 'lockstep' else 0.01, self._on_timer,
                                       clock=steady_clock())

    # ------------------------------------------------------------ geometry
    def _on_params(self, params):
        try:
            new_t, new_b = self.target, self.barrier
            for p in params:
                if p.name == 'target':
                    new_t = parse_point(p.value)
                elif p.name == 'barrier':
                    new_b = parse_points(p.value)
        except (ValueError, TypeError) as err:
            self.get_logger().warning(f'rejected parameter: {err}')
            return SetParametersResult(successful=False, reason=str(err))
        if any(p.name in ('target', 'barrier') for p in params):
            self.target, self.barrier = new_t, new_b
            self.barrier_geom = M.Barrier(self.barrier) if self.barrier is not None and len(self.barrier) >= 3 else None
            self.publish_geometry()
            self.get_logger().info(f'world geometry: target={self.target}, barrier={format_points(self.barrier) or None}')
        return SetParametersResult(successful=True)

    def publish_geometry(self):
        ts = PointStamped()
        ts.header.frame_id = 'world'
        ts.header.stamp = stamp(self.sim_t if hasattr(self, 'sim_t') else 0.0)
        if self.target is not None:
            ts.point.x, ts.point.y = float(self.target[0]), float(self.target[1])
            self.pub_target.publish(ts)
        bs = PolygonStamped()
        bs.header = ts.header
        if self.barrier is not None:
            bs.polygon.points = [Point32(x=float(x), y=float(y)) for x, y in self.barrier]
        self.pub_barrier.publish(bs)

    # ------------------------------------------------------------ inputs
    def _on_state(self, raw):
        """A serialized /swarm/states message (decoded without building an Odometry)."""
        try:
            name, sec, nsec, pose, wz = P.cdr_to_odometry(raw)
        except Exception as err:
            self.reject('state-decode', f'{P.STATES} message that does not decode: {err}')
            return
        t = sec + nsec * 1e-9
        reason = check_values(name, t, pose, wz, self.row, self.newest)
        if reason is not None:
            if reason != 'repeat':
                self.reject((name, reason.split(':')[0]), reason)
            return
        i = self.row[name]
        vals = (pose[0], pose[1], pose[4], pose[5])
        if self.mode == 'realtime':
            self.newest[name] = (t, *vals)
            self.rec.record_realtime(i, P.step_of(t, self.dt), vals, wz, self.lam_now, self.leaders_now)
            return
        reason, acts = self.lock.on_state(i, P.step_of(t, self.dt), vals, wz)
        if reason is not None:
            self.reject((name, 'step'), reason)
            return
        self.newest[name] = (t, *vals)
        self.last_progress = time.monotonic()
        self.act(acts)

    def _on_decision(self, raw):
        data = P.cdr_to_float64_array(raw)
        n, t, lam, flags, steering = P.unpack_decision(data)
        if n != self.lock.cur or self.lock.decision is not None:
            return
        if not (math.isfinite(lam) and 0.0 <= lam <= 1.0) or not np.all(np.isfinite(steering)) \
                or len(flags) != self.n:
            self.reject('decision', f'commander decision for step {n}: λ={lam}, non-finite or wrong size')
            return
        slots, rdv = P.decision_extras(data)
        self.last_progress = time.monotonic()
        self.act(self.lock.on_decision(n, lam, flags, steering, slots, rdv))

    # ------------------------------------------------------------ lockstep
    def ready(self):
        """Everyone matched: agents' states of step 0 held, relay and commander matched (and,
        with ``wait_for_recorder``, the recorder's /clock reader: a late match would lose the
        first /clock messages, which are volatile)."""
        ok = (self.lock.have.all() and self.pub_step.get_subscription_count() >= (self.step_readers or self.n)
              and self.pub_lock_states.get_subscription_count() >= 1
              and self.sub_decision.handle.get_publisher_count() >= 1)
        if ok and self.wait_for_recorder:
            want = self.clock_readers or self.n + 2                      # agents, commander, recorder
            if self.pub_clock.get_subscription_count() < want:
                now = time.monotonic()
                if self.recorder_wait_from is None:
                    self.recorder_wait_from = now
                if now - self.recorder_wait_from < P.RECORDER_MATCH_WAIT:
                    return False
                self.get_logger().warning(f'{P.CLOCK}: {self.pub_clock.get_subscription_count()} readers '
                                          f'matched, not {want}, after {P.RECORDER_MATCH_WAIT:g} s; '
                                          'starting anyway')
        return ok

    def act(self, actions):
        """Carry out what the lockstep barrier decided (swarm_world.lockstep), in order."""
        for a in actions:
            kind = a[0]
            if kind == 'clock':
                self.sim_t = a[1]
                self.pub_clock.publish(P.clock_to_cdr(a[1]))
            elif kind == 'states':
                self.sim_t = float(a[1][1])
                raw = P.float64_array_to_cdr(a[1])
                self.pub_lock_states.publish(raw)
                self.last_msg = (self.pub_lock_states, raw)
            elif kind == 'observe':
                self.observe(a[1])
            elif kind == 'comms':
                self.pub_events.publish(String(data=P.event_json('comms', a[1] * self.dt, source='scenario', **a[2])))
            elif kind == 'step':
                self.lam_now, self.leaders_now = self.lock.lam, self.lock.leaders
                raw = P.float64_array_to_cdr(a[1])
                self.pub_step.publish(raw)
                self.last_msg = (self.pub_step, raw)
                self.step_wall = time.monotonic()
            elif kind == 'event':
                self.emit(a[1])
            elif kind == 'signal':
                self.signal_agent(a[1], SIGNALS[a[2]])
            elif kind == 'finish':
                self.finish()

    # ------------------------------------------------------------ events, faults
    def emit(self, ev):
        ev = dict(ev, node='world')
        self.events.append(ev)
        self.log(f'[world] event t={ev["t"]:.2f}: {ev["kind"]} {ev.get("agent", "")}', flush=True)
        self.pub_events.publish(String(data=json.dumps(ev)))
        self.write_event(ev)

    def write_event(self, ev):
        if self.events_file:
            with open(self.events_file, 'a') as f:
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
                track_slots(self.rt_slots, ev, self.row)

    def _on_fault_request(self, msg):
        try:
            req = json.loads(msg.data)
            kind, agent = req['kind'], req['agent']
            dur = float(req.get('for', 0.0))
            if kind not in FAULT_KINDS:
                raise ValueError(f'kind must be one of {FAULT_KINDS}')
            if kind == 'freeze' and not (math.isfinite(dur) and dur > 0):
                raise ValueError(f'freeze needs "for" > 0 seconds, got {dur!r}')
            fault = Fault(0.0, kind, agent, dur, source='live')
            if self.mode == 'lockstep':
                k = self.lock.add_fault(fault)
            else:
                k = self.rt_fault_step + 1
                self.faults.add(fault, not_before=k)
        except (ValueError, KeyError, TypeError) as err:
            self.reject(('fault-request', msg.data[:40]), f'{P.FAULT_REQUEST} {msg.data[:80]!r}: {err}')
            return
        self.get_logger().info(f'fault request: {kind} {agent}' + (f' for {dur:g} s' if kind == 'freeze' else '')
                               + f' at step {k}')

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
        try:
            os.kill(int(pid), sig)
        except ProcessLookupError:
            pass

    def drop_missing(self):
        """Lockstep: give up on agents whose state has not come within missing_timeout."""
        for i in self.lock.missing():
            self.get_logger().warning(f'{self.names[i]}: no state for step {self.lock.cur} within '
                                      f'{self.missing_timeout:g} s: dropped from the roster')
        self.act(self.lock.drop_missing())

    # ------------------------------------------------------------ view
    def observe(self, k):
        """Per-step checks (collisions, intrusions), progress, metrics and markers."""
        idx = np.flatnonzero(self.faults.alive)         # faults: only agents in the table
        pos = self.rec.r[k, idx]
        md = M.min_distance(pos)
        if md < self.collision_distance:
            self.collisions += 1
            self.reject(('collision', k // 2000), f'nothing: collision at t={k * self.dt:.2f} (min distance {md:.4f})')
        if self.barrier_geom is not None:
            inside = self.barrier_geom.inside(pos)
            if inside.any():
                self.intrusions += int(inside.sum())
                self.reject(('intrusion', k // 2000), f'nothing: barrier intrusion at t={k * self.dt:.2f} by '
                            + ', '.join(self.names[idx[i]] for i in np.flatnonzero(inside)))
        t = k * self.dt
        if self.progress_every > 0 and t >= self.next_progress:
            self.next_progress = t + self.progress_every
            c, _ = M.cluster_labels(pos, self.w)
            el = time.monotonic() - (self.run_wall or self.wall_start)
            self.log(f'[world] t={t:8.2f}  clusters={c}  λ={self.lam_now:.3f}  min_dist={md:.3f}  '
                     f'({k / el if el > 0 else 0:.0f} steps/s)', flush=True)
        if self.view_every and k % self.view_every == 0:
            self.publish_view(t, pos, self.rec.theta[k, idx], md, idx)

    def publish_view(self, t, pos, theta, md, idx=None):
        """Metrics and markers of agents ``idx`` (default all) at rows pos, theta."""
        idx = np.arange(len(pos)) if idx is None else idx
        c, labels = M.cluster_labels(pos, self.w)
        leaders = [self.names[i] for i in np.flatnonzero(self.leaders_now)]
        vals = view_values(t, pos, theta, c, md, self.lam_now, leaders, self.target,
                           intrusions=self.intrusions, collisions=self.collisions,
                           cutoff_radius=self.w)       # what `swarm report` needs to count clusters
        self.pub_metrics.publish(metrics_message(t, vals))
        if self.pub_markers.get_subscription_count() == 0:
            return
        self.pub_markers.publish(markers_message(t, pos, theta, labels, idx, self.leaders_now, self.trails,
                                                 self.target, self.barrier))

    # ------------------------------------------------------------ realtime
    def _on_lambda(self, msg):
        if math.isfinite(msg.data) and 0.0 <= msg.data <= 1.0:
            self.lam_now = msg.data

    def _on_leaders(self, msg):
        """Realtime: /swarm/leaders (comma-separated names) → the leader flags recorded."""
        names = [nm.strip() for nm in msg.data.split(',') if nm.strip()]
        unknown = [nm for nm in names if nm not in self.row]
        if unknown:
            self.reject(('leaders', tuple(unknown)), f'{P.LEADERS}: unknown agent(s) {", ".join(unknown)}')
        flags = np.zeros(self.n, bool)
        flags[[self.row[nm] for nm in names if nm in self.row]] = True
        self.leaders_now = flags

    def rt_tick(self):
        now = time.monotonic()
        if not self.started:
            if len(self.newest) == self.n:
                self.started, self.run_wall = True, now
                self.log(f'[world] realtime: {self.n} agents discovered in {now - self.wall_start:.1f} s; '
                         f'clock at rtf {self.rtf}', flush=True)
            else:
                return
        self.sim_t = (now - self.run_wall) * self.rtf
        self.pub_clock.publish(Clock(clock=stamp(self.sim_t)))
        k = P.step_of(self.sim_t, self.dt)
        while self.rt_comms and self.rt_comms[0][0] <= k:
            _, e = self.rt_comms.pop(0)
            self.pub_events.publish(String(data=P.event_json('comms', k * self.dt, source='scenario', **e)))
        if self.view_every and (k // self.view_every) != getattr(self, '_rt_view', -1):
            self._rt_view = k // self.view_every
            have = [nm for nm in self.names if nm in self.newest]
            pos = np.array([self.newest[nm][1:3] for nm in have])
            th = np.array([yaw_from_quaternion(*self.newest[nm][3:5]) for nm in have])
            self.observe_rt(k, pos, th)
        self.rt_faults(min(k, self.steps))
        if self.sim_t >= self.scn.duration:
            self.finish()

    def rt_faults(self, k):
        """Realtime: the faults of every step up to k, signals at once ('leader:i' resolved with
        the slots the commander's events announced)."""
        while self.rt_fault_step < k:
            self.rt_fault_step += 1
            for ev in self.faults.apply(self.rt_fault_step, dict(self.rt_slots)):
                self.emit(ev)
                sig = {'kill': signal.SIGKILL, 'freeze': signal.SIGSTOP, 'resume': signal.SIGCONT}.get(ev['kind'])
                if sig is not None:
                    self.signal_agent(self.row.get(ev['agent']), sig)

    def observe_rt(self, k, pos, theta):
        t = k * self.dt
        md = M.min_distance(pos)
        if self.progress_every > 0 and t >= self.next_progress:
            self.next_progress = t + self.progress_every
            c, _ = M.cluster_labels(pos, self.w)
            self.log(f'[world] t={t:8.2f}  clusters={c}  λ={self.lam_now:.3f}  min_dist={md:.3f}', flush=True)
        self.publish_view(t, pos, theta, md)

    # ------------------------------------------------------------ timer, end
    def _on_timer(self):
        if self.done:
            return
        if self.mode == 'realtime':
            self.rt_tick()
            return
        now = time.monotonic()
        if not self.started:
            if self.ready():
                self.started = True
                self.run_wall = now
                self.log(f'[world] lockstep: {self.n} agents and the commander discovered in '
                         f'{now - self.wall_start:.1f} s; {self.steps} steps of dt={self.dt}', flush=True)
                self.step_wall = now
                self.act(self.lock.start())
            elif now - self.wall_start > self.start_timeout:
                self.failed = (f'discovery timed out after {self.start_timeout:.0f} s: have states of '
                               f'{int(self.lock.have.sum())}/{self.n} agents, relay readers '
                               f'{self.pub_step.get_subscription_count()}, commander '
                               f'{"yes" if self.pub_lock_states.get_subscription_count() else "no"}')
                self.get_logger().error(self.failed)
                self.done = True
            return
        if not self.lock.states_out and now - self.step_wall > self.missing_timeout and not self.lock.complete():
            self.drop_missing()
            return
        if now - self.step_wall > max(self.step_timeout, self.missing_timeout + 10 * self.stall_timeout):
            self.failed = (f'step {self.lock.cur} has not completed after {now - self.step_wall:.0f} s '
                           f'({"waiting for the commander" if self.lock.states_out else "waiting for agents"}): giving up')
            self.get_logger().error(self.failed)
            self.done = True
            return
        if self.last_msg is not None and now - self.last_progress > self.stall_timeout:
            pub, msg = self.last_msg
            if self.lock.states_out:
                waiting = "the commander's decision"
            else:
                waiting = 'the states of ' + ', '.join(self.names[i] for i in self.lock.missing())
            self.get_logger().warning(f'stalled at step {self.lock.cur} waiting for {waiting}: repeating the last message')
            pub.publish(msg)
            self.last_progress = now

    def trajectory(self) -> Trajectory:
        return self.rec.trajectory(meta=dict(
            scenario=self.scn.name, seed=self.scn.seed, dt=self.dt, duration=self.scn.duration,
            steps=self.steps, source='ros', mode=self.mode,
            wall_seconds=time.monotonic() - (self.run_wall or self.wall_start), events=list(self.events)))

    def finish(self):
        self.done = True
        wall = time.monotonic() - (self.run_wall or self.wall_start)
        self.log(f'[world] finished t={self.scn.duration:g} ({self.steps} steps) in {wall:.1f} s '
                 f'({self.steps / wall if wall > 0 else 0:.0f} steps/s); collisions={self.collisions} '
                 f'intrusions={self.intrusions}', flush=True)
        if self.output_dir:
            out = Path(self.output_dir)
            out.mkdir(parents=True, exist_ok=True)
            self.trajectory().save(out / 'trajectory.npz')

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
        return path

def main(argv=None):
    return run_node(WorldNode, 'swarm_world', argv, done=lambda node: node.done,
                    on_stop=lambda node: node.save_partial(),
                    exit_code=lambda node: 0 if (node.done and node.failed is None)
                    else (1 if node.failed else 130))


if __name__ == '__main__':
    sys.exit(main())
