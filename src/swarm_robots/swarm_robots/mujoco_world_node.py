"""The robots of a run on one MuJoCo physics world (node ``robots``, one per run).

It owns a differential-drive robot for each agent in ``robots`` (`swarm_robots.physics`), reads
each robot's ``/<agent>/cmd_vel`` (geometry_msgs/TwistStamped, or Twist with the scenario's
``cmd_type: Twist``, realtime only) and publishes ``/<agent>/odom`` and ``/<agent>/ground_truth``
(nav_msgs/Odometry).  Lockstep: the physics advances one step once every robot of an alive agent
has sent its command for the step (`timing.RobotsLockstep`, the alive mask from
``/lockstep/step``; commands are kept until taken, so a flood of refused ones only delays
them, and an agent sends its command again when the world repeats a stalled step); then the
robots' poses of the new step go to the world on ``/lockstep/robot_states``
(`layouts.RobotStates`, read from the odometry as the agents would read it:
`world_setup.OdometryPoses`), and odometry goes out only while someone reads it.  A step that
goes on without a robot's command (``hold_timeout``) is recorded: the run is then no longer
deterministic (``commands_missed`` in robots.json and metrics.json).
Realtime: the physics follows the sim clock (/clock), odometry at 50 Hz.
A robot takes only its own agent's commands: of this run, from the first sender tag taken for it
(`swarm_ros.run_control.CommandSenders`; a ``Twist`` names no sender); the reports carry the
robot world's own tag; bytes that are not a command are counted (docs/security.md).
Robot-robot contacts and the time at the velocity limits go to ``/robots/metrics`` and, at the
end, to ``robots.json`` in ``output_dir`` (metrics.json's ``summary.robots``).  docs/robots.md.
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray, String

from swarm_core.files import write_atomic
from swarm_core.robot_units import odometry_quaternion
from swarm_robots.physics import RobotWorld
from swarm_robots.timing import RealtimePacer, RobotsLockstep, advance_to, robot_summary
from swarm_robots.world_setup import (
    SUMMARY_FILE,
    OdometryPoses,
    chosen_rows,
    robot_description,
    robots_section,
    start_poses,
    turn_limit_clock,
)
from swarm_ros import protocol as P
from swarm_ros.layouts import RobotStates, Step
from swarm_ros.msg_checks import RejectLog, decoded, guard_subscriptions, new_sender_tag
from swarm_ros.rosutil import ParameterError, declare, require_sim_clock, run_node, steady_clock
from swarm_ros.run_clock import follow_run_clock
from swarm_ros.run_control import CommandSenders, EventRefused, decode_command, run_event
from swarm_ros.runinfo import declare_run_id
from swarm_ros.scenario_params import declare_scenario

METRICS_TOPIC = '/robots/metrics'
#: lockstep: wall s without progress after which the newest odometry is published again (an
#: agent that subscribed late, a lost sample)
REPEAT_AFTER = 0.5
#: realtime: wall s between physics ticks
TICK = 0.01
#: realtime: the most robot s of physics one tick runs (a clock far ahead is caught up over
#: several ticks, each a few ms per robot: SIGINT and the other callbacks are never held up)
TICK_ADVANCE_MAX = 1.0


def odom_topic(agent: str) -> str:
    return f'/{agent}/odom'


def ground_truth_topic(agent: str) -> str:
    return f'/{agent}/ground_truth'


def cmd_vel_topic(agent: str) -> str:
    return f'/{agent}/cmd_vel'


def serialized_odometry(writer, sec: int, nanosec: int, row) -> bytes:
    """nav_msgs/Odometry bytes (`swarm_ros.protocol.OdometryWriter`: its frames) of a row x, y,
    yaw, v, omega (m, rad, body twist): rclpy's conversion of an Odometry message object costs
    ten times more, and the robot world publishes two per robot and step."""
    x, y, yaw, v, omega = (float(c) for c in row)
    return writer(sec, nanosec, x, y, *odometry_quaternion(yaw), omega, v)


class RobotsNode(Node):
    def __init__(self, node_name='robots', *, namespace=None, context=None, parameter_overrides=None,
                 cli_args=None):
        super().__init__(node_name, namespace=namespace, context=context, cli_args=cli_args,
                         parameter_overrides=parameter_overrides)
        self._declare_parameters()
        self.reject = RejectLog(self.get_logger())
        desc = self._description()
        self.world = turn_limit_clock(self._make_world(desc), self.sec, desc)
        self.t_odom = 0.0                       # sim time of the newest odometry published
        self.readers, self.readers_at = ([], []), -math.inf     # robots whose odometry, ground truth is read
        self.last_sent = time.monotonic()       # wall s of the newest odometry published
        self.pub_odom, self.pub_truth = [], []
        self.tag = new_sender_tag()             # on /lockstep/robot_states (the world binds it)
        self.missed = {}                        # lockstep: agent -> steps that went on without its command
        self.senders = CommandSenders(self.run_id, [cmd_vel_topic(nm) for nm in self.agents])
        own = self.sec.frame == 'odom'
        self.odom_writers = [P.OdometryWriter(f'{nm}/base_link', f'{nm}/odom' if own else 'world')
                             for nm in self.agents]
        self.truth_writers = [P.OdometryWriter(f'{nm}/base_link', 'world') for nm in self.agents]
        for k, nm in enumerate(self.agents):
            self.pub_odom.append(self.create_publisher(Odometry, odom_topic(nm), P.qos_reliable(10)))
            self.pub_truth.append(self.create_publisher(Odometry, ground_truth_topic(nm), P.qos_reliable(10)))
            stamped = self.sec.cmd_type == 'TwistStamped'
            # lockstep: every command kept until taken, so a flood of refused ones cannot push it out
            self.create_subscription(TwistStamped if stamped else Twist, cmd_vel_topic(nm),
                                     self._command_callback(k, stamped),
                                     P.qos_kept_latched() if self.mode == 'lockstep' else P.qos_cmd_vel(False),
                                     raw=True)
        self.pub_metrics = self.create_publisher(DiagnosticArray, METRICS_TOPIC, 10)
        self.create_timer(1.0, self.publish_metrics, clock=steady_clock())
        if self.mode == 'lockstep':
            self.hold = RobotsLockstep(self.world, self.rows, self.scn.dt, self.scale)
            self.poses = OdometryPoses(self.world, self.scn, self.rows, self.units, self.sec.frame)
            self.pub_report = self.create_publisher(Float64MultiArray, P.LOCK_ROBOT_STATES, P.qos_latched())
            self.create_subscription(Float64MultiArray, P.LOCK_STEP, self._on_step, P.qos_latched(), raw=True)
            self.create_subscription(String, P.EVENTS, self._on_event, P.qos_latched(100))
            self.create_timer(REPEAT_AFTER / 2, self._repeat, clock=steady_clock())
            self.publish_odometry(0.0)
            self.report = RobotStates(0, self.tag, self.rows, self.poses.first).to_cdr(self.run_id)
            self.pub_report.publish(self.report)
        else:
            self.pacer, self.asked = RealtimePacer(self.scale), 0.0
            if self.run_id:             # the run's clock alone, not /clock (`swarm_ros.run_clock`)
                follow_run_clock(self, self.run_id, self.reject)
            self.create_timer(TICK, self._tick, clock=steady_clock())
        self.get_logger().info(
            f'{len(self.agents)} robots ({self.mode}): L = {self.sec.length_scale:g} m, v0 = '
            f'{self.sec.cruise_speed:g} m/s, {self.scale:g} robot s per model s')
        guard_subscriptions(self, self.reject)      # no message ends the robot world

    def _declare_parameters(self):
        d = lambda *a, **k: declare(self, *a, **k)
        self.mode = d('mode', 'lockstep', 'lockstep or realtime', choices=('lockstep', 'realtime'))
        chosen = d('robots', '', "the agents with a robot, comma-separated ('': every agent)")
        self.output_dir = d('output_dir', '', f'where to write {SUMMARY_FILE} at the end ("": nowhere)')
        self.hold_timeout = d('hold_timeout', 5.0, 'lockstep: wall s to wait for the commands of a step the world '
                              'has sent before the robots of agents that did not answer are left out of it '
                              '(swarm run: half the world\'s missing_timeout)', lo=0.1, hi=1e6)
        self.run_id = declare_run_id(self, 'lockstep step messages of another run are refused')
        self.scn = declare_scenario(self)
        if self.mode == 'realtime':
            require_sim_clock(self, 'realtime robots follow the sim clock (/clock) from 0')
        try:
            self.sec = robots_section(self.scn)
        except ValueError as err:
            raise ParameterError(f'parameter scenario: {err}') from None
        try:
            self.rows = chosen_rows(self.scn.names, [c.strip() for c in chosen.split(',') if c.strip()])
        except ValueError as err:
            raise ParameterError(f'parameter robots: {err}') from None
        if self.mode == 'lockstep' and self.sec.cmd_type != 'TwistStamped':
            raise ParameterError('lockstep robots need stamped commands (cmd_type TwistStamped): '
                                 'a Twist says not which step it is for')
        self.agents = [self.scn.names[i] for i in self.rows]
        self.units = self.sec.units()
        self.scale = self.units.seconds_per_model_unit

    def _description(self):
        """The robot description the scenario names (default: TurtleBot3 Burger)."""
        try:
            return robot_description(self.sec)
        except (OSError, ValueError) as err:
            raise ParameterError(f'scenario robots.description {self.sec.description}: {err}') from None

    def _make_world(self, desc):
        return RobotWorld(desc, start_poses(self.scn, self.rows, self.units))

    # ------------------------------------------------------------ inputs
    def _command_callback(self, k, stamped):
        def on_command(raw):          # serialized (`protocol.cdr_to_twist`): no message object per command
            try:
                sec, nsec, v, omega, frame = decode_command(raw, stamped)
            except ValueError as err:
                self.reject('cmd-decode', f'{cmd_vel_topic(self.agents[k])}: {err}')
                return
            why = self.senders.check(k, frame) if stamped else None     # a Twist names no sender
            if why is not None:
                self.reject(why.kind, why)
                return
            if not (math.isfinite(v) and math.isfinite(omega)):
                self.reject('cmd-non-finite', f'{cmd_vel_topic(self.agents[k])}: non-finite command')
                return
            if self.mode == 'realtime':
                self.world.command(k, v, omega)
            elif not self.hold.on_command(k, P.stamp_seconds(sec, nsec), v, omega):
                self.reject('cmd-stale', f'{cmd_vel_topic(self.agents[k])}: command stamped for no step '
                            f'awaited (held step {self.hold.n})')
            else:
                self._advance()
        return on_command

    def _on_step(self, raw):
        m = decoded(Step, raw, self.run_id, self.reject, 'step-decode')
        if m is None:
            return
        if len(m.alive) != len(self.scn.names):
            self.reject('step-roster', f'{P.LOCK_STEP}: {len(m.alive)} agents, the roster has {len(self.scn.names)}')
            return
        self.hold.on_step(m.n, m.alive, time.monotonic())
        self._advance()

    def _on_event(self, msg):
        """Lockstep: a kill of a robot's agent (/swarm/events, of this run): its command is not
        awaited."""
        try:
            ev = run_event(msg.data, self.run_id)
        except EventRefused as err:
            self.reject(err.kind, err)
            return
        if ev.get('kind') == 'kill' and ev.get('agent') in self.agents:
            self.hold.stop_awaiting(self.agents.index(ev['agent']))
            self._advance()

    # ------------------------------------------------------------ physics and outputs
    def _advance(self):
        """Lockstep: each step whose commands are all here: the physics, the robots' poses of
        the next step to the world, the odometry."""
        while self.hold.ready():
            t = self.hold.advance()
            self.report = RobotStates(self.hold.n, self.tag, self.rows, self.poses.table()).to_cdr(self.run_id)
            self.pub_report.publish(self.report)
            self.publish_odometry(t)

    def _repeat(self):
        """Lockstep: no odometry for `REPEAT_AFTER` wall s: the newest again; ``hold_timeout``
        after the held step's message came: the step goes on without the robots whose commands
        did not come (the repeats do not put that off)."""
        now = time.monotonic()
        if self.hold.overdue(now, self.hold_timeout):
            missing = self.hold.release()
            if missing:
                for k in missing:
                    self.missed.setdefault(self.agents[k], []).append(self.hold.n)
                self.get_logger().warning(
                    f'step {self.hold.n}: no command from {", ".join(self.agents[k] for k in missing)} '
                    f'{self.hold_timeout:g} s after the step came; their robots get none this step: '
                    'the run is no longer deterministic (robots.json, metrics.json)')
                self._advance()
                return
        if now - self.last_sent >= REPEAT_AFTER:
            self.pub_report.publish(self.report)
            self.publish_odometry(self.t_odom)

    def _tick(self):
        """Realtime: the physics up to the sim clock's robot time, odometry when due."""
        self.asked = advance_to(self.world, self.asked, self.pacer.target(self.get_clock().now().nanoseconds * 1e-9),
                                TICK_ADVANCE_MAX)
        if self.pacer.odom_due(self.world.time, time.monotonic()):
            self.publish_odometry(self.units.model_time(self.world.time))

    def publish_odometry(self, t: float):
        """Each robot's odometry (its own ``odom`` frame, or the common ``world`` frame) and
        ground truth, stamped sim time ``t``.  Ground truth only while someone reads it (a
        recorder, a view; the agents never do), and in lockstep the odometry too (the agents
        take their poses from the world's table), looked at every `REPEAT_AFTER` s: both are
        volatile, so a reader that matches later has missed little it could have had."""
        self.t_odom, self.last_sent = t, time.monotonic()
        if self.last_sent >= self.readers_at + REPEAT_AFTER:     # who reads: looked at twice a second
            always = self.mode == 'realtime'
            self.readers = ([k for k, pub in enumerate(self.pub_odom) if always or pub.get_subscription_count()],
                            [k for k, pub in enumerate(self.pub_truth) if pub.get_subscription_count()])
            self.readers_at = self.last_sent
        to_odom, to_truth = self.readers
        if not (to_odom or to_truth):
            return
        sec, nsec = P.time_to_stamp(t)
        truth = self.world.ground_truth()
        odom = self.world.odometry() if self.sec.frame == 'odom' and to_odom else truth
        for k in to_odom:
            self.pub_odom[k].publish(serialized_odometry(self.odom_writers[k], sec, nsec, odom[k]))
        for k in to_truth:
            self.pub_truth[k].publish(serialized_odometry(self.truth_writers[k], sec, nsec, truth[k]))

    def summary(self) -> dict:
        w = self.world
        return robot_summary(self.agents, w.contacts, w.seconds, w.saturated_time, self.scale, self.missed)

    def publish_metrics(self):
        s = self.summary()
        values = [('contacts', s['contacts']), ('turn_limit_seconds_total', s['turn_limit_seconds_total']),
                  ('limit_seconds_total', s['limit_seconds_total']), ('robot_time', self.world.time)]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [DiagnosticStatus(name='robots', message=f'{len(self.agents)} robots',
                                       values=[KeyValue(key=k, value=f'{v:g}') for k, v in values])]
        self.pub_metrics.publish(arr)

    def finish(self):
        """The run's robot summary into ``output_dir`` (`SUMMARY_FILE`)."""
        if self.output_dir:
            try:
                write_atomic(Path(self.output_dir) / SUMMARY_FILE, json.dumps(self.summary()))
            except OSError as err:
                self.get_logger().error(f'cannot write {SUMMARY_FILE} to {self.output_dir}: {err}')


def main(argv=None):
    return run_node(RobotsNode, 'swarm_robots', argv, on_stop=lambda node: node.finish())


if __name__ == '__main__':
    sys.exit(main())
