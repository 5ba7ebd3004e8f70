"""WorldNode: sim time, the lockstep barrier, target and barrier, swarm view and metrics.

`WorldNode` is what every world node has whatever its mode (parameters, the scenario and its
faults, the record, target and barrier, the clock, view and event publishers, the run's
announcement, events, signals and files); the mode's own work is done by its driver,
`LockstepDriver` or `RealtimeDriver` (``node.driver``; `drivers.DRIVERS` maps the parameter
``mode`` to the class).  The logic lives in pure modules: `lockstep` (the barrier), `realtime`
(the realtime schedule), `wallclock` (start, stalls, time-outs), `observe` (checks,
progress), `parsing` (the text inputs), `markers` (messages) and
`swarm_core.engine.trajectory` (the record).  The world writes ``trajectory.npz`` to
``output_dir`` at the end and every event to ``events_file``.
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
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from swarm_core.analysis import metrics as M
from swarm_core.engine.trajectory import Trajectory, TrajectoryRecorder
from swarm_core.files import open_regular
from swarm_core.model.natural import quaternion_from_frame
from swarm_core.robot_units import ROBOT_KINDS
from swarm_ros import protocol as P
from swarm_ros import runinfo
from swarm_ros.msg_checks import RejectLog, guard_subscriptions, may_signal, reason
from swarm_ros.rosutil import ParameterError, declare, run_node, steady_clock
from swarm_ros.run_control import EventRefused, event_text, run_event
from swarm_ros.runinfo import RunWatch, declare_run_id, give_way, older_runs, parse_robots_text, run_json
from swarm_ros.scenario_params import declare_scenario
from swarm_world.drivers import DRIVERS
from swarm_world.lateness import TIMING_FILE
from swarm_world.markers import Trails, geometry_messages, markers_every, markers_message, metrics_message, view_values
from swarm_world.natural import NaturalRecorder, natural_view
from swarm_world.observe import Observer
from swarm_world.parameters import MODE_PARAMETERS, WORLD
from swarm_world.parsing import fault_request, format_points, parse_geometry, parse_point, parse_points

SIGNALS = {'kill': signal.SIGKILL, 'stop': signal.SIGSTOP, 'cont': signal.SIGCONT}


class WorldNode(Node):
    """What every world node has, whatever its mode: its parameters, the scenario and its
    faults, the record (`rec`) and the checks (`obs`), target and barrier, the clock, view and
    event publishers, the run's announcement, the events, signals and files.  The mode's own
    work is its driver's (`drivers.DRIVERS`)."""

    def __init__(self, node_name='world', *, namespace=None, context=None, parameter_overrides=None,
                 cli_args=None, log=print):
        super().__init__(node_name, namespace=namespace, context=context, cli_args=cli_args,
                         parameter_overrides=parameter_overrides)
        self.log = log
        mode_parameters = self._declare_parameters()
        # faults (swarm_core.faults.agents): the same timeline as the batch engine
        self.faults = self.scn.fault_timeline()
        self.events = []
        self.pids = None
        self._open_events_file()
        self.add_on_set_parameters_callback(self._on_params)
        self.reject = RejectLog(self.get_logger())
        self.rec = NaturalRecorder(self.names, self.steps, self.dt, self.mode == 'realtime') if self.dim == 3 else \
            TrajectoryRecorder(self.names, self.steps, self.dt, self.scn.theta0, realtime=self.mode == 'realtime')
        self.obs = Observer(self.collision_distance, self.w, self.progress_every)
        self.driver = DRIVERS[self.mode](self, **mode_parameters)
        self._create_endpoints()
        self.started = False
        self.done = False
        self.failed = None
        self.wall_start = time.monotonic()
        # before its first step the world listens this long (wall s) for another run on the
        # domain: its own agents may be discovered in 0.2 s, an older run's announcement later
        try:
            self.announce_settle = runinfo.discovery_settle()
        except ValueError as err:
            raise ParameterError(str(err)) from None
        self.run_wall = None
        self.trails = Trails(self.n, self.trail_length)
        self.views = -1          # views published (markers: every `markers_every`)
        self.sim_t = 0.0
        self.lam_now = 0.0
        self.leaders_now = np.zeros(self.n, bool)
        self.pub_events = self.create_publisher(String, P.EVENTS, P.qos_latched(100))
        self.publish_geometry()
        self.timer = self.create_timer(self.driver.tick_period(), self._on_timer, clock=steady_clock())
        guard_subscriptions(self, self.reject)      # no message ends the world

    def _declare_parameters(self):
        """The world's parameters (`parameters.WORLD`: those every mode shares kept as
        attributes), the run id, the scenario (`declare_scenario`) and its movable target and
        barrier; returns the mode's own parameters (`parameters.MODE_PARAMETERS`) for its driver."""
        d = lambda *a, **k: declare(self, *a, **k)
        values = {nm: d(nm, default, text, **lim) for nm, (default, text, lim) in WORLD.items()}
        own = {nm for names in MODE_PARAMETERS.values() for nm in names}
        for nm, value in values.items():
            if nm not in own:
                setattr(self, nm, value)
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
        self.dim = self.scn.dim
        self.ground = self.scn.ground if self.dim == 3 else None
        xy = 'x,y' if self.dim == 2 else 'x,y,z'
        try:
            self.target = parse_point(d('target', format_points(self.target), f'target "{xy}" ("" = none); movable'),
                                      self.dim)
            self.barrier = parse_points(d('barrier', format_points(self.barrier),
                                          f'barrier hull "{xy};{xy};..." ("" = none); movable'), self.dim)
        except ValueError as err:
            raise ParameterError(f'parameter target/barrier: {err}') from None
        self.barrier_geom = M.Barrier(self.barrier) if self.barrier is not None else None
        return {nm: values[nm] for nm in MODE_PARAMETERS[self.mode]}

    def _open_events_file(self):
        """``events_file`` (default ``output_dir/events.jsonl``) made empty; for a user's law its
        first line is a ``law`` event with the law file's hash (`Scenario.law_hash`)."""
        if not self.events_file and self.output_dir:
            self.events_file = str(Path(self.output_dir) / 'events.jsonl')
        if self.events_file:
            Path(self.events_file).parent.mkdir(parents=True, exist_ok=True)
            open_regular(self.events_file, 'w').close()      # never through a planted link
            if self.scn.law_hash:     # a user's law: its file's hash as this run imported it
                self.write_event(dict(t=0.0, kind='law', law=self.scn.law.kind, law_hash=self.scn.law_hash))
        if self.output_dir:
            (Path(self.output_dir) / TIMING_FILE).unlink(missing_ok=True)     # an older run's

    def _create_endpoints(self):
        """Publishers and subscriptions (protocol: names and QoS), the mode's by its driver;
        announces the run on /swarm/run."""
        self.pub_clock = self.create_publisher(Clock, P.CLOCK, P.qos_reliable(P.STEP_DEPTH))
        self.pub_target = self.create_publisher(PointStamped, P.TARGET, P.qos_latched())
        self.pub_barrier = self.create_publisher(PolygonStamped, P.BARRIER, P.qos_latched())
        self.pub_markers = self.create_publisher(MarkerArray, P.MARKERS, 5)
        self.pub_metrics = self.create_publisher(DiagnosticArray, P.METRICS, 10)
        self.create_subscription(String, P.EVENTS, self._on_event, P.qos_latched(100))
        self.create_subscription(String, P.FAULT_REQUEST, self._on_fault_request, P.qos_latched(10))
        remote = [nm for nm in self.remote_agents.split(',') if nm]
        try:
            robots = parse_robots_text(self.remote_robots, remote, ROBOT_KINDS[1:])
        except ValueError as err:
            raise ParameterError(f'parameter remote_robots: {err}') from None
        self.driver.create_endpoints()
        # the run's identity; other runs on this domain are heard here (and refused before the start)
        self.pub_run = self.create_publisher(String, P.RUN, P.qos_latched())
        self.since = time.time()
        self.pub_run.publish(String(data=run_json(self.run_id, self.scn.name, self.mode, self.names, self.since,
                                                  self.scn.content_hash, remote, robots, self.scn.dim,
                                                  ground=self.ground)))
        self.runs = RunWatch(self, log=self.get_logger().warning)
        self.second_world_at = None     # when a second /world node was first seen (no announcement yet)

    # ------------------------------------------------------------ geometry
    def _on_params(self, params):
        values = {p.name: p.value for p in params if p.name in ('target', 'barrier')}
        try:
            new_t, new_b = parse_geometry(values, self.target, self.barrier, self.dim)
        except (ValueError, TypeError) as err:
            self.get_logger().warning(f'rejected parameter: {err}')
            return SetParametersResult(successful=False, reason=str(err))
        if values:
            self.target, self.barrier = new_t, new_b
            self.barrier_geom = M.Barrier(self.barrier) if self.barrier is not None and len(self.barrier) >= 3 else None
            self.publish_geometry()
            shown = format_points(self.barrier) or None
            self.get_logger().info(f'world geometry: target={self.target}, barrier={shown}')
        return SetParametersResult(successful=True)

    def publish_geometry(self):
        target, barrier = geometry_messages(self.sim_t if hasattr(self, 'sim_t') else 0.0, self.target, self.barrier)
        if target is not None:
            self.pub_target.publish(target)
        self.pub_barrier.publish(barrier)

    # ------------------------------------------------------------ another run
    def other_run(self):
        """Refuse to start (one error line, exit 1) rather than mix with an older run
        (runinfo.give_way); once started, go on whatever is announced."""
        worlds = 1 if self.started else sum(
            1 for nm, ns in self.get_node_names_and_namespaces() if nm == 'world' and ns == '/')
        if not self.started and time.monotonic() - self.wall_start < self.announce_settle:
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

    # ------------------------------------------------------------ actions
    def carry_out(self, actions):
        """Carry out, in order, what the mode's logic decided (the actions of
        `swarm_world.lockstep`, which the realtime schedule uses too): those of every mode
        here, the mode's own by its driver (`carry_out`)."""
        for a in actions:
            kind = a[0]
            if kind == 'comms':
                self.pub_events.publish(String(data=P.event_json('comms', a[1] * self.dt, source='scenario',
                                                                 run_id=self.run_id, **a[2])))
            elif kind == 'event':
                self.publish_event(a[1])
            elif kind == 'signal':
                self.signal_agent(a[1], SIGNALS[a[2]])
            elif kind == 'finish':
                self.finish()
            elif kind == 'fail':
                self.give_up(a[1])
            else:
                self.driver.carry_out(a)

    # ------------------------------------------------------------ events, faults
    def publish_event(self, ev):
        """A world event (a fault carried out, an agent lost): kept in `events`, logged,
        published on /swarm/events and written to the events file."""
        ev = dict(ev, node='world')
        self.events.append(ev)
        what = ' '.join(str(ev[k]) for k in ('command', 'agent', 'value', 'ramp', 'leaders') if k in ev)
        self.log(f'[world] event t={ev["t"]:.2f}: {ev["kind"]} {what}'.rstrip(), flush=True)
        self.pub_events.publish(String(data=event_text(ev, self.run_id)))
        self.write_event(ev)

    def write_event(self, ev):
        if self.events_file:
            with open_regular(self.events_file, 'a') as f:
                f.write(json.dumps(ev) + '\n')

    def _on_event(self, msg):
        """Another node's event of this run: recorded (without its run id); others counted."""
        try:
            ev = run_event(msg.data, self.run_id)
        except EventRefused as err:
            self.reject(err.kind, err)
            return
        if ev.get('node') != 'world':
            self.events.append(ev)
            self.write_event(ev)
            self.driver.on_event(ev)

    def _on_fault_request(self, msg):
        try:
            f = fault_request(msg.data)
            k = self.driver.add_fault(f)
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
    def publish_view(self, t, pos, theta, md, idx=None, timing=None):
        """Metrics and markers of agents ``idx`` (default all) at rows pos, theta; realtime:
        with the ``timing`` so far (`Lateness.summary`).  A 3D run's ``theta`` is the frames
        (x, y, z), (m, 3) each: its markers carry z and the frames' quaternions."""
        idx = np.arange(len(pos)) if idx is None else idx
        leaders = [self.names[i] for i in np.flatnonzero(self.leaders_now)]
        if self.dim == 3:
            c, labels = M.cluster_labels_3d(pos, self.w)
            vals = natural_view(t, pos, theta[0], self.w, md, self.lam_now, leaders, self.target,
                                intrusions=self.obs.intrusions, collisions=self.obs.collisions, cutoff_radius=self.w,
                                **(timing or {}))
            theta = np.stack(quaternion_from_frame(*theta), axis=1)
        else:
            c, labels = M.cluster_labels(pos, self.w)
            vals = view_values(t, pos, theta, c, md, self.lam_now, leaders, self.target,     # cutoff: what
                               intrusions=self.obs.intrusions, collisions=self.obs.collisions,    # `swarm report`
                               cutoff_radius=self.w, **(timing or {}))                            # counts by
        self.pub_metrics.publish(metrics_message(t, vals))
        self.views += 1
        if self.views % markers_every(self.n) or self.pub_markers.get_subscription_count() == 0:
            return
        self.pub_markers.publish(markers_message(t, pos, theta, labels, idx, self.leaders_now, self.trails,
                                                 self.target, self.barrier))

    # ------------------------------------------------------------ timer, end
    def _on_timer(self):
        if not self.done:
            self.driver.tick()

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
        self.driver.at_end()

    def save_partial(self):
        """Stopped (Ctrl-C / SIGTERM) before the end: write the steps completed so far to
        ``output_dir`` (as ``swarm simulate`` keeps the computed part of an interrupted run).
        Lockstep: the rows whose state, λ, leaders and u are all known; realtime: up to now."""
        if not self.output_dir or not self.started or self.done:
            return None
        rows = self.driver.rows_done()
        if rows < 1:
            return None
        part = self.trajectory().head(rows)
        out = Path(self.output_dir)
        out.mkdir(parents=True, exist_ok=True)
        path = part.save(out / 'trajectory.npz')
        self.log(f'[world] stopped at t={part.t[-1]:g}: saved t = 0..{part.t[-1]:g} ({rows} samples) '
                 f'to {path}', flush=True)
        self.driver.at_end()
        return path


def main(argv=None):
    return run_node(WorldNode, 'swarm_world', argv, done=lambda node: node.done,
                    on_stop=lambda node: node.save_partial(),
                    exit_code=lambda node: 0 if (node.done and node.failed is None)
                    else (1 if node.failed else 130))


if __name__ == '__main__':
    sys.exit(main())
