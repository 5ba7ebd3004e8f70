"""WorldNode: sim time, the lockstep barrier, target and barrier, swarm view and metrics.

See `swarm_world.protocol` for the message flow.  The world loads the same scenario as the
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
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Point32, PointStamped, PolygonStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64, Float64MultiArray, String
from visualization_msgs.msg import Marker, MarkerArray

from swarm_core import metrics as M
from swarm_core.engine import Trajectory
from swarm_core.faults import FAULT_KINDS, Fault, track_slots
from swarm_core.model import yaw_from_quaternion
from swarm_core.scenario import ScenarioError, load

from . import protocol as P
from .checks import check_values
from .rosutil import ParameterError, RejectLog, declare, run_node, steady_clock


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
        self.slots = {}                 # leader slot → agent index, from the last decision
        self.events = []
        self.held = {}                  # frozen agent index → (step, (x, y, qz, qw), u)
        self.freezes = []               # (agent index, k0, k1) for the trajectory
        self.stop_pending = set()       # frozen agents to SIGSTOP once their state is held
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
            self.create_subscription(Float64, P.LAMBDA, self._on_lambda, P.qos_latched(10))  # the commander's
            # the leaders as the commander announces them (lockstep: in each decision)
            self.create_subscription(String, P.LEADERS, self._on_leaders, P.qos_latched())
        if self.mode == 'lockstep':
            self.pub_lock_states = self.create_publisher(Float64MultiArray, P.LOCK_STATES, P.qos_latched())
            self.pub_step = self.create_publisher(Float64MultiArray, P.LOCK_STEP, P.qos_latched())
            self.sub_decision = self.create_subscription(Float64MultiArray, P.LOCK_DECISION, self._on_decision,
                                                         P.qos_latched(), raw=True)

        # recording
        T = self.steps + 1
        self.rec_r = np.full((T, self.n, 2), np.nan)
        self.rec_theta = np.full((T, self.n), np.nan)
        self.rec_u = np.zeros((T, self.n))
        self.rec_lam = np.zeros(T) if self.mode == 'lockstep' else np.full(T, np.nan)
        self.rec_leader = np.zeros((T, self.n), bool)
        self.gids = {}
        self.newest = {}         # name -> (t, x, y, qz, qw) newest accepted
        # lockstep bookkeeping: states of step `cur` (and u_{cur-1} they carry)
        self.cur = 0
        self.buf = np.zeros((4, self.n))
        self.buf_u = np.zeros(self.n)
        self.have = np.zeros(self.n, bool)
        self.fresh = np.zeros(self.n, bool)      # state stamped at the current step (not held)
        self.want = np.zeros(self.n, dtype=np.int64)   # the stamp step wanted from each agent
        self.step_wall = time.monotonic()
        self.states_out = False
        self.decision = None
        self.last_msg = None
        self.last_progress = time.monotonic()
        self.started = False
        self.done = False
        self.failed = None
        self.wall_start = time.monotonic()
        self.run_wall = None
        self.intrusions = 0
        self.collisions = 0
        self.trails = [[] for _ in range(self.n)]
        self.sim_t = 0.0
        self.lam_now = 0.0
        self.leaders_now = np.zeros(self.n, bool)
        self.next_progress = 0.0
        # the scenario's scheduled radio changes (comms.events), published on /swarm/events
        # at their step for the record (agents apply them from their own copy)
        from swarm_core.comms import event_step
        self.pub_events = self.create_publisher(String, P.EVENTS, P.qos_latched(100))
        cspec = self.scn.spec.comms
        self.comms_events = sorted(((event_step(e.at, self.dt), e.model_dump(exclude_none=True))
                                    for e in (cspec.events if cspec else [])), key=lambda se: se[0])
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

    def _stamp(self, t):
        s = Time()
        s.sec, s.nanosec = P.time_to_stamp(t)
        return s

    def publish_geometry(self):
        ts = PointStamped()
        ts.header.frame_id = 'world'
        ts.header.stamp = self._stamp(self.sim_t if hasattr(self, 'sim_t') else 0.0)
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
            self.rt_record(i, t, vals, wz)
            return
        k = P.step_of(t, self.dt)
        u = wz
        if not self.faults.alive[i]:          # faults: dead or frozen
            self.newest[name] = (t, *vals)
            if self.faults.frozen[i] and k == self.faults.frozen_at[i]:
                self.held[i] = (k, vals, u)
                if 0 < k <= self.steps:
                    self.rec_u[k - 1, i] = u
                if i in self.stop_pending:
                    self.stop_pending.discard(i)
                    self.signal_agent(i, signal.SIGSTOP)
            return
        if k != self.want[i]:
            self.reject((name, 'step'), f'state of {name!r} for step {k} while the world is at step {self.cur}')
            return
        self.newest[name] = (t, *vals)
        self.buf[:, i] = vals
        self.buf_u[i] = u
        self.have[i] = True
        self.fresh[i] = k == self.cur
        if k != self.cur and 0 < k <= self.steps:     # a resumed agent's held state
            self.rec_u[k - 1, i] = u
        self.last_progress = time.monotonic()
        self.advance()

    def _on_decision(self, raw):
        n, t, lam, flags, steering = P.unpack_decision(P.cdr_to_float64_array(raw))
        if n != self.cur or self.decision is not None:
            return
        if not (math.isfinite(lam) and 0.0 <= lam <= 1.0) or not np.all(np.isfinite(steering)) \
                or len(flags) != self.n:
            self.reject('decision', f'commander decision for step {n}: λ={lam}, non-finite or wrong size')
            return
        slots, rdv = P.decision_extras(P.cdr_to_float64_array(raw))
        self.decision = (lam, flags.copy(), steering.copy(), rdv)
        self.slots = {int(sl): int(i) for i, sl in enumerate(slots) if sl >= 0}
        self.last_progress = time.monotonic()
        self.advance()

    # ------------------------------------------------------------ lockstep
    def ready(self):
        """Everyone matched: agents' states of step 0 held, relay and commander matched (and,
        with ``wait_for_recorder``, the recorder's /clock reader: a late match would lose the
        first /clock messages, which are volatile)."""
        ok = (self.have.all() and self.pub_step.get_subscription_count() >= self.n
              and self.pub_lock_states.get_subscription_count() >= 1
              and self.sub_decision.handle.get_publisher_count() >= 1)
        if ok and self.wait_for_recorder:
            if self.pub_clock.get_subscription_count() < self.n + 2:       # agents, commander, recorder
                now = time.monotonic()
                if self.recorder_wait_from is None:
                    self.recorder_wait_from = now
                if now - self.recorder_wait_from < P.RECORDER_MATCH_WAIT:
                    return False
                self.get_logger().warning(f'{P.CLOCK}: {self.pub_clock.get_subscription_count()} readers '
                                          f'matched, not {self.n + 2}, after {P.RECORDER_MATCH_WAIT:g} s; '
                                          'starting anyway')
        return ok

    def complete(self):
        """Every agent in the table of the current step has its state here."""
        return bool(np.all(self.have | ~self.faults.alive))

    def advance(self):
        if not self.started or self.done:
            return
        if self.complete() and not self.states_out:
            k = self.cur
            alive = self.faults.alive
            if k > self.steps:                         # the final u_{steps}
                self.rec_u[self.steps, alive] = self.buf_u[alive]
                self.finish()
                return
            x, y, qz, qw = self.buf
            self.rec_r[k, alive, 0], self.rec_r[k, alive, 1] = x[alive], y[alive]
            self.rec_theta[k, alive] = yaw_from_quaternion(qz[alive], qw[alive])
            if k > 0:
                fresh = self.fresh & alive
                self.rec_u[k - 1, fresh] = self.buf_u[fresh]
            self.sim_t = k * self.dt
            if k % self.clock_every == 0 or k == self.steps:
                self.pub_clock.publish(P.clock_to_cdr(self.sim_t))
            raw = P.float64_array_to_cdr(P.pack_states(k, self.sim_t, x, y, qz, qw, alive))
            self.pub_lock_states.publish(raw)
            self.last_msg = (self.pub_lock_states, raw)
            self.states_out = True
            self.observe(k)
        if self.states_out and self.decision is not None:
            k = self.cur
            lam, flags, steering, rdv = self.decision
            alive = self.faults.alive
            self.rec_lam[k], self.rec_leader[k] = lam, flags & alive
            self.lam_now, self.leaders_now = lam, flags & alive
            x, y, qz, qw = self.buf
            data = P.pack_step(k, k * self.dt, lam, flags, steering, x, y, qz, qw, self.target, self.barrier,
                               self.buf_u, alive=alive, rendezvous=rdv)
            self.publish_scheduled_events(k)
            raw = P.float64_array_to_cdr(data)
            self.pub_step.publish(raw)
            self.last_msg = (self.pub_step, raw)
            self.cur += 1
            self.have[:] = False
            self.fresh[:] = False
            self.want[:] = self.cur
            self.states_out = False
            self.decision = None
            self.step_wall = time.monotonic()
            self.begin_step(self.cur)

    # ------------------------------------------------------------ faults
    def begin_step(self, k):
        """Apply the faults of step k (scheduled and live) before its states are awaited."""
        if k > self.steps:
            return
        for ev in self.faults.apply(k, self.slots):
            i = self.row.get(ev['agent'])
            self.emit(ev)                   # first: the launcher reads it when the agent dies
            if ev['kind'] == 'kill':
                self.signal_agent(i, signal.SIGKILL)
                self.stop_pending.discard(i)
                if k > 0:
                    self.rec_u[k - 1:, i] = np.nan
            elif ev['kind'] == 'freeze':
                k1 = int(self.faults.frozen_until[i])
                self.freezes.append((i, int(self.faults.frozen_at[i]), k1))
                held = self.held.get(i)
                if held is not None and held[0] == self.faults.frozen_at[i]:
                    self.signal_agent(i, signal.SIGSTOP)
                else:
                    self.stop_pending.add(i)
            elif ev['kind'] == 'resume':
                self.stop_pending.discard(i)
                self.signal_agent(i, signal.SIGCONT)
                k0 = int(self.faults.frozen_at[i])
                held = self.held.pop(i, None)
                if held is not None and held[0] == k0:
                    self.buf[:, i] = held[1]
                    self.buf_u[i] = held[2]
                    self.have[i] = True
                else:
                    self.want[i] = k0

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
            k = self.cur + 1 if self.mode == 'lockstep' else self.rt_fault_step + 1
            self.faults.add(Fault(0.0, kind, agent, dur, source='live'), not_before=k)
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
        if pid is None:
            return
        try:
            os.kill(int(pid), sig)
        except ProcessLookupError:
            pass

    def drop_missing(self):
        """Lockstep: give up on agents whose state has not come within missing_timeout."""
        missing = np.flatnonzero(self.faults.alive & ~self.have)
        for i in missing:
            self.faults.lose(i)
            if self.cur > 0:
                self.rec_u[self.cur - 1:, i] = np.nan
            self.get_logger().warning(f'{self.names[i]}: no state for step {self.cur} within '
                                      f'{self.missing_timeout:g} s: dropped from the roster')
            self.emit(dict(t=self.cur * self.dt, step=self.cur, kind='lost', agent=self.names[i]))
        self.advance()

    def publish_scheduled_events(self, k):
        while self.comms_events and self.comms_events[0][0] <= k:
            _, e = self.comms_events.pop(0)
            self.pub_events.publish(String(data=P.event_json('comms', k * self.dt, source='scenario', **e)))

    def observe(self, k):
        """Per-step checks (collisions, intrusions), progress, metrics and markers."""
        idx = np.flatnonzero(self.faults.alive)         # faults: only agents in the table
        pos = self.rec_r[k, idx]
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
            self.publish_view(t, pos, self.rec_theta[k, idx], md, idx)

    def publish_view(self, t, pos, theta, md, idx=None):
        """Metrics and markers of agents ``idx`` (default all) at rows pos, theta."""
        idx = np.arange(len(pos)) if idx is None else idx
        c, labels = M.cluster_labels(pos, self.w)
        st = DiagnosticStatus(name='swarm', hardware_id='world', level=DiagnosticStatus.OK,
                              message=f'{c} cluster(s)')
        vals = dict(t=t, clusters=c, polarisation=M.polarisation(theta), min_distance=md, **{'lambda': self.lam_now},
                    leaders=','.join(self.names[i] for i in np.flatnonzero(self.leaders_now)),
                    agents=len(idx),
                    intrusions=self.intrusions, collisions=self.collisions)
        if self.target is not None:
            vals['centroid_target_distance'] = float(np.hypot(*(pos.mean(0) - self.target)))
        st.values = [KeyValue(key=k_, value=str(v)) for k_, v in vals.items()]
        arr = DiagnosticArray(status=[st])
        arr.header.stamp = self._stamp(t)
        self.pub_metrics.publish(arr)
        if self.pub_markers.get_subscription_count() == 0:
            return
        ma = MarkerArray()
        stamp = self._stamp(t)
        palette = [(0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
                   (0.58, 0.4, 0.74), (0.55, 0.34, 0.29)]
        for row, i in enumerate(idx):
            tr = self.trails[i]
            tr.append((pos[row, 0], pos[row, 1]))
            if len(tr) > self.trail_length:
                del tr[0]
            m = Marker(ns='agents', id=i, type=Marker.ARROW, action=Marker.ADD)
            m.header.frame_id, m.header.stamp = 'world', stamp
            m.pose.position.x, m.pose.position.y = float(pos[row, 0]), float(pos[row, 1])
            m.pose.orientation.z, m.pose.orientation.w = math.sin(theta[row] / 2), math.cos(theta[row] / 2)
            m.scale.x, m.scale.y, m.scale.z = 0.8, 0.25, 0.25
            r, g, b = palette[labels[row] % len(palette)]
            m.color.r, m.color.g, m.color.b, m.color.a = (1.0, 0.84, 0.0, 1.0) if self.leaders_now[i] else (r, g, b, 1.0)
            ma.markers.append(m)
            tm = Marker(ns='trails', id=i, type=Marker.LINE_STRIP, action=Marker.ADD)
            tm.header = m.header
            tm.scale.x = 0.05
            tm.color.r, tm.color.g, tm.color.b, tm.color.a = r, g, b, 0.6
            tm.points = [Point(x=float(a), y=float(b_)) for a, b_ in tr]
            ma.markers.append(tm)
        if self.target is not None:
            m = Marker(ns='target', id=0, type=Marker.SPHERE, action=Marker.ADD)
            m.header.frame_id, m.header.stamp = 'world', stamp
            m.pose.position.x, m.pose.position.y = float(self.target[0]), float(self.target[1])
            m.pose.orientation.w = 1.0
            m.scale.x = m.scale.y = m.scale.z = 1.0
            m.color.g, m.color.a = 1.0, 1.0
            ma.markers.append(m)
        if self.barrier is not None:
            m = Marker(ns='barrier', id=0, type=Marker.LINE_STRIP, action=Marker.ADD)
            m.header.frame_id, m.header.stamp = 'world', stamp
            m.scale.x = 0.1
            m.color.r, m.color.a = 1.0, 1.0
            m.points = [Point(x=float(x), y=float(y)) for x, y in list(self.barrier) + [self.barrier[0]]]
            ma.markers.append(m)
        self.pub_markers.publish(ma)

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

    def rt_record(self, i, t, vals, u):
        k = P.step_of(t, self.dt)
        if 0 <= k <= self.steps:
            self.rec_lam[k] = self.lam_now
            self.rec_leader[k] = self.leaders_now
            self.rec_r[k, i] = vals[:2]
            self.rec_theta[k, i] = yaw_from_quaternion(vals[2], vals[3])
            if k > 0:
                self.rec_u[k - 1, i] = u

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
        self.pub_clock.publish(Clock(clock=self._stamp(self.sim_t)))
        k = P.step_of(self.sim_t, self.dt)
        self.publish_scheduled_events(k)
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
                i = self.row.get(ev['agent'])
                self.emit(ev)
                sig = {'kill': signal.SIGKILL, 'freeze': signal.SIGSTOP, 'resume': signal.SIGCONT}.get(ev['kind'])
                if sig is not None:
                    self.signal_agent(i, sig)

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
                self.begin_step(0)
                self.advance()
            elif now - self.wall_start > self.start_timeout:
                self.failed = (f'discovery timed out after {self.start_timeout:.0f} s: have states of '
                               f'{int(self.have.sum())}/{self.n} agents, relay readers {self.pub_step.get_subscription_count()}, '
                               f'commander {"yes" if self.pub_lock_states.get_subscription_count() else "no"}')
                self.get_logger().error(self.failed)
                self.done = True
            return
        if not self.states_out and now - self.step_wall > self.missing_timeout and not self.complete():
            self.drop_missing()
            return
        if now - self.step_wall > max(self.step_timeout, self.missing_timeout + 10 * self.stall_timeout):
            self.failed = (f'step {self.cur} has not completed after {now - self.step_wall:.0f} s '
                           f'({"waiting for the commander" if self.states_out else "waiting for agents"}): giving up')
            self.get_logger().error(self.failed)
            self.done = True
            return
        if self.last_msg is not None and now - self.last_progress > self.stall_timeout:
            pub, msg = self.last_msg
            if self.states_out:
                waiting = "the commander's decision"
            else:
                waiting = 'the states of ' + ', '.join(
                    self.names[i] for i in np.flatnonzero(self.faults.alive & ~self.have))
            self.get_logger().warning(f'stalled at step {self.cur} waiting for {waiting}: repeating the last message')
            pub.publish(msg)
            self.last_progress = now

    def trajectory(self) -> Trajectory:
        T = self.steps + 1
        theta = self.rec_theta.copy()
        r, lam, leader = self.rec_r.copy(), self.rec_lam.copy(), self.rec_leader.copy()
        if self.mode == 'realtime':        # hold each agent's last published state between its stamps
            if not np.isfinite(lam[0]):
                lam[0] = 0.0
            for k in range(1, T):
                miss = ~np.isfinite(theta[k])
                r[k, miss], theta[k, miss] = r[k - 1, miss], theta[k - 1, miss]
                if not np.isfinite(lam[k]):       # no state recorded at step k
                    lam[k], leader[k] = lam[k - 1], leader[k - 1]
        # faults: a frozen agent holds its state of the freeze step
        for i, k0, k1 in self.freezes:
            k_last = min(k1, T)
            src = self.frozen_state(i, k0)
            if src is not None:
                r[k0:k_last, i] = src[0]
                theta[k0:k_last, i] = src[1]
        # headings travel as quaternions (θ mod 2π): unwrap in time, start at the scenario's θ0
        good = np.all(np.isfinite(theta), axis=1)
        if good.all():
            theta = np.unwrap(theta, axis=0)
            theta += np.round((self.scn.theta0 - theta[0]) / (2 * np.pi)) * 2 * np.pi
        else:                              # faults: unwrap each agent over its finite samples
            for i in range(self.n):
                ok = np.isfinite(theta[:, i])
                if ok.any():
                    col = np.unwrap(theta[ok, i])
                    theta[ok, i] = col + np.round((self.scn.theta0[i] - col[0]) / (2 * np.pi)) * 2 * np.pi
        tr = Trajectory(list(self.names), np.arange(T) * self.dt, r, theta, self.rec_u.copy(),
                        lam, leader,
                        meta=dict(scenario=self.scn.name, seed=self.scn.seed, dt=self.dt, duration=self.scn.duration,
                                  steps=self.steps, source='ros', mode=self.mode,
                                  wall_seconds=time.monotonic() - (self.run_wall or self.wall_start),
                                  events=list(self.events)))
        return tr

    def frozen_state(self, i, k0):
        """(position, θ) agent i held while frozen from step k0, if known."""
        if i in self.held and self.held[i][0] == k0:
            x, y, qz, qw = self.held[i][1]
        else:
            k1 = next((b for a, s0, b in self.freezes if a == i and s0 == k0), None)
            if k1 is None or k1 > self.steps or not np.isfinite(self.rec_r[k1, i]).all():
                return None
            return self.rec_r[k1, i].copy(), float(self.rec_theta[k1, i])
        return np.array([x, y]), float(yaw_from_quaternion(qz, qw))

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
        else:       # u of step k - 1 comes with the states of step k
            rows = min(self.cur if self.states_out else self.cur - 1, self.steps + 1)
        if rows < 1:
            return None
        tr = self.trajectory()
        part = Trajectory(tr.names, tr.t[:rows], tr.r[:rows], tr.theta[:rows], tr.u[:rows], tr.lam[:rows],
                          tr.leader[:rows], meta=dict(tr.meta, interrupted=True))
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
