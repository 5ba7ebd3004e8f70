"""AgentNode: one agent of the swarm; integrates its own Frenet frame (its topics: docs/ros-graph.md).

Lockstep: reads one packed ``/lockstep/step`` message per step (states of all agents, λ,
leader flags, s_k, target, barrier of that step), computes u with the core law, integrates,
publishes its next state on ``/swarm/states``.
Realtime: a timer at the control rate (1/dt in sim time) uses the newest states of agents
within w (all agents when the law couples globally), read from the agent processes' batches
on ``/swarm/agent_states``, the newest ``/swarm/lambda``, ``/swarm/leaders``, its ``steering``
topic, ``/world/target`` and ``/world/barrier``; it publishes its state on ``/swarm/states``
and, alone, in its own batch.
Bad inputs are rejected with one log line naming them; no NaN ever enters the state.

An agent with a robot (parameter ``robot``: external, mujoco) reads its pose from the robot's
odometry and commands it on ``cmd_vel`` instead of integrating (`swarm_agent.robot_driver`).

`AgentNode` is what every agent node has whatever its mode (name, parameters, its pure
`AgentCore`, the ``/swarm/states`` publisher, the inputs every mode reads, the radio and the
faults); the mode's own work is done by its driver, `LockstepDriver` or `RealtimeDriver`
(``node.driver``; `DRIVERS` maps the parameter ``mode`` to the class).  A driver declares its
parameters, takes the mode's own input (`on_input`), and says how a radio change applies.

In an agent container (``swarm_agents``, `swarm_agent.container_node`) the node is built with
``contained=True``: it keeps its name, parameters, logger, ``steering`` subscription and
``/swarm/states`` publisher, and the container feeds it the inputs its agents share (the step
relay, ``/swarm/agent_states``, λ, leaders, target, barrier, events) from one subscription each.

Communication model (parameter ``comms``: the scenario's ``comms`` section as JSON, '' = a
perfect radio; see swarm_core.faults.radio): the agent applies it on its receive side.  Lockstep: from
each step's table it keeps only what its radio delivers (`AgentCore.comms_control`; equal to
the batch engine bit for bit).  Realtime: each incoming state is lost or delayed by the same
seeded fate function (keyed by the state's step), kept in flight until its delivery time, and
the control uses the newest delivered state of each neighbour dead-reckoned to now, leaving
out neighbours silent for longer than the timeout.  Runtime changes (``swarm drop``,
``swarm partition``) arrive on ``/swarm/events`` and switch the radio path on if it was off.
"""
from __future__ import annotations

import json
import math
import sys

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64

from swarm_agent.agent_core import AgentCore, roster_index
from swarm_agent.drivers import DRIVERS, MODES
from swarm_agent.process_io import shared_inputs
from swarm_agent.robot_driver import ROBOT_DRIVERS, declare_robot
from swarm_core.checks import DT_BOUND, LAMBDA_BOUND, STEERING_BOUND
from swarm_core.faults.radio import CommModel, change_from_event
from swarm_core.laws import LAW_PARAMETERS, LawConfig
from swarm_core.robot_units import ROBOT_KINDS
from swarm_core.scenario.loader import noise_rng
from swarm_ros import protocol as P
from swarm_ros.msg_checks import RejectLog, check_barrier, new_sender_tag
from swarm_ros.rosutil import ParameterError, declare, run_node
from swarm_ros.runinfo import declare_run_id


class AgentNode(Node):
    """What every agent node has, whatever its mode: its name and parameters, its `AgentCore`,
    the ``/swarm/states`` publisher, the inputs every mode reads (λ, steering, leaders, target,
    barrier, /swarm/events: the radio and, contained, faults).  The mode's own work is its
    driver's (`DRIVERS`)."""

    def __init__(self, node_name='agent', *, namespace=None, context=None, parameter_overrides=None,
                 cli_args=None, contained=False, services=True):
        if not services:         # in a big container: no parameter/type-description services, no /rosout
            parameter_overrides = list(parameter_overrides or []) + [
                Parameter('start_type_description_service', value=False)]
        super().__init__(node_name, namespace=namespace, context=context, cli_args=cli_args,
                         parameter_overrides=parameter_overrides, enable_rosout=services,
                         start_parameter_services=services)
        self.contained = contained
        self.sim_clock = self.get_clock()   # a realtime container's agents share its first agent's
        self.halted = None       # contained: 'kill' or 'freeze' (fault events for this agent)
        leader, pose, noise, seed, mode_parameters, comms = self._declare_parameters()
        try:
            self.roster, self.index = roster_index(self.roster, self.agent_name, self.index)
        except ValueError as err:
            raise ParameterError(str(err)) from None
        self.n = len(self.roster)
        self.row = {nm: i for i, nm in enumerate(self.roster)}
        self.core = AgentCore(self.index, self.n, *pose, self.law, self.dt, noise, noise_rng(seed, self.index))
        self.reject = RejectLog(self.get_logger())
        self.radio = self._radio(comms, seed)
        self.radio_on = not self.radio.perfect

        # live inputs (realtime; kept in lockstep for inspection)
        self.lam = 0.0
        self.steering = 0.0
        self.leaders = {self.agent_name} if leader else set()
        self.target = None
        self.barrier = None
        self.step = 0            # the step whose state we hold (lockstep: `core.step`)
        self.t = 0.0
        self.u_history = []      # (step, u) for tests (bounded)

        self.pub = self.create_publisher(Odometry, P.STATES, P.qos_latched(P.STATES_DEPTH))
        # transient-local: the commander's λ and steering in force, never a user's one-shot
        # command (that one is for the commander only; docs/commands.md)
        self.create_subscription(Float64, 'steering', self._on_steering, P.qos_latched(10))
        self.driver = driver_class(self.mode, self.robot)(self, **mode_parameters[self.mode], **self.robot_parameters)
        if self.radio_on:
            self.driver.radio_started()
        if not contained:
            for typ, topic, cb, qos, raw in shared_inputs(self, self.driver.on_input):
                self.create_subscription(typ, topic, cb, qos, raw=raw)
        self.sender_tag = new_sender_tag()     # who we are on /swarm/states (protocol.SENDER_TAG_INDEX)
        self.serialize_state = P.OdometryWriter(self.agent_name, tag=self.sender_tag)
        self.own = None          # (sec, nanosec, x, y, qz, qw, u) last published
        self.driver.start()

    def _declare_parameters(self):
        """Declare every parameter (those of every mode too); the agent's own go on self."""
        ns = self.get_namespace().strip('/')
        d = lambda *a, **k: declare(self, *a, **k)  # noqa: E731
        self.agent_name = d('agent_name', ns or 'agent_0', 'agent name (child_frame_id of its states)')
        self.roster = list(d('agent_names', [''], 'names of all agents in agent-index order (the table order)'))
        self.index = d('agent_index', -1, "this agent's row in agent_names (-1: look the name up)", lo=-1, hi=100000)
        leader = d('leader', False, 'leader (true) or follower until /swarm/leaders says otherwise')
        pose = (d('x', 0.0, 'initial x position'), d('y', 0.0, 'initial y position'),
                d('theta', 0.0, 'initial heading θ (rad)'))
        self.law = self._declare_law()
        self.dt = d('dt', 0.05, 'control period / integration step (sim s)', lo=DT_BOUND.lo, hi=DT_BOUND.hi,
                    read_only=True)
        self.mode = d('mode', 'lockstep', 'lockstep or realtime', choices=MODES)
        noise = (d('noise_position', 0.0, 'uniform noise half-width on x, y per step', lo=0.0, hi=1e6),
                 d('noise_heading', 0.0, 'uniform noise half-width on θ per step', lo=0.0, hi=1e6))
        seed = d('seed', 0, 'scenario seed (noise stream)', lo=0, hi=2**31 - 1)
        mode_parameters = {mode: driver.declare(self) for mode, driver in DRIVERS.items()}
        self.robot = d('robot', 'none', 'none: a kinematic point; external or mujoco: drive a robot through '
                       '/<agent>/cmd_vel from /<agent>/odom (swarm_agent.robot_driver)', choices=ROBOT_KINDS)
        self.robot_parameters = {}
        if self.robot != 'none':
            self.robot_parameters = declare_robot(self)
        comms = d('comms', '', "communication model: the scenario's comms section as JSON ('' = perfect)")
        self.run_id = declare_run_id(self, 'lockstep steps of another run are rejected')
        return leader, pose, noise, seed, mode_parameters, comms

    def _declare_law(self):
        defaults = LawConfig().parameters()          # one place for the defaults: the core's types
        law = {}
        for name, (text, limits) in LAW_PARAMETERS.items():
            if isinstance(limits, tuple) and isinstance(limits[0], str):
                law[name] = declare(self, name, defaults[name], text, choices=limits)
            elif limits is None:
                law[name] = declare(self, name, defaults[name], text)
            else:
                law[name] = declare(self, name, defaults[name], text, lo=limits[0], hi=limits[1])
        return LawConfig.from_parameters(law)

    def _radio(self, comms, seed):
        try:
            cfg = json.loads(comms) if comms.strip() else None
            if cfg is not None and not isinstance(cfg, dict):
                raise ValueError('not a JSON object')
            return CommModel.from_config(cfg, self.roster, self.dt, seed)
        except (ValueError, TypeError, KeyError) as err:
            raise ParameterError(f'parameter comms: {err}') from None

    # ------------------------------------------------------------ output
    def publish_state(self, u=None):
        """Publish the own state of t (pre-serialised: no message object per step), carrying
        ``u`` (default: the u held last)."""
        sec, nsec = P.time_to_stamp(self.t)
        qz, qw = self.core.quaternion
        self.own = (sec, nsec, float(self.core.pos[0, 0]), float(self.core.pos[0, 1]), qz, qw,
                    float(self.core.u_last if u is None else u))
        self.pub.publish(self.serialize_state(*self.own))

    def applied(self, u):
        """Note the control u applied over the step held (`u_history`)."""
        self.u_history.append((self.step, u))
        if len(self.u_history) > 10000:
            del self.u_history[:5000]

    # ------------------------------------------------------------ inputs of every mode
    def _on_lambda(self, msg):
        v = msg.data
        if not LAMBDA_BOUND.ok(v):
            self.reject('lambda', f'{P.LAMBDA}: {LAMBDA_BOUND.error(v)}')
            return
        self.lam = v

    def _on_steering(self, msg):
        v = msg.data
        if not STEERING_BOUND.ok(v):
            self.reject('steer', f'{self.agent_name}: {STEERING_BOUND.error(v)}')
            return
        self.steering = v

    def _on_leaders(self, msg):
        names = [s.strip() for s in msg.data.split(',') if s.strip()]
        unknown = [s for s in names if s not in self.row]
        if unknown:
            self.reject('leaders', f'{P.LEADERS} {msg.data[:80]!r}: unknown agent {unknown[0][:40]!r}')
            return
        self.leaders = set(names)

    def _on_target(self, msg):
        p = (msg.point.x, msg.point.y)
        if not all(math.isfinite(v) for v in p):
            self.reject('target', f'{P.TARGET} {p}: not finite')
            return
        self.target = np.array(p)

    def _on_barrier(self, msg):
        pts = [(q.x, q.y) for q in msg.polygon.points]
        why = check_barrier(pts)
        if why is not None:
            self.reject(why.kind, why)
            return
        self.barrier = np.array(pts, float) if pts else None

    # ------------------------------------------------------------ radio (communication model), faults
    def _on_event(self, msg):
        """Runtime radio changes from /swarm/events (docs/ros-graph.md); in a container
        also the faults of this agent (the world cannot signal a process it shares); a robot
        agent obeys them too (its robot stands from a pause or kill on)."""
        try:
            ev = json.loads(msg.data)
            mine = isinstance(ev, dict) and ev.get('agent') == self.agent_name
            if (self.contained or self.robot != 'none') and mine and ev.get('kind') in ('kill', 'freeze', 'resume'):
                self.fault(ev['kind'])
                return
            change = change_from_event(ev)
        except (ValueError, TypeError) as err:
            self.reject('event', f'{P.EVENTS} event {msg.data[:80]!r}: {str(err)[:120]}')
            return
        if change is None:
            return                    # faults, or scheduled in the scenario (applied from our copy)
        step = self.driver.radio_step()
        try:
            self.radio.apply(change, step)
        except ValueError as err:     # e.g. an unknown agent in a partition
            self.reject('event', f'{P.EVENTS} event: {str(err)[:120]}')
            return
        if not self.radio_on:
            self.radio_on = True
            self.driver.radio_started()
        self.get_logger().info(f'radio: {json.dumps(change)} from step {step}')

    def fault(self, kind):
        """Contained: kill (stop for good), freeze (stop until resume) or resume this agent
        alone, as SIGKILL / SIGSTOP / SIGCONT do to an agent process.  A robot agent: its robot
        stands while halted (`robot_driver`)."""
        if self.halted == 'kill':
            return
        self.halted = None if kind == 'resume' else kind
        if kind == 'kill':
            self.lock_kill()
        self.get_logger().info(f'fault: {kind}' + (' (in-process: the other agents of the container go on)'
                                                   if self.contained else ''))

    def lock_kill(self):
        """Set by the container: stop this agent's lockstep for good."""

    def _now(self):
        return self.sim_clock.now().nanoseconds * 1e-9


def driver_class(mode: str, robot: str):
    """The driver of an agent node in ``mode`` with ``robot`` (none: its own kinematic point;
    else `robot_driver.ROBOT_DRIVERS`, which builds on `drivers`)."""
    if robot == 'none':
        return DRIVERS[mode]
    return ROBOT_DRIVERS.get((mode, robot), ROBOT_DRIVERS[mode])


def main(argv=None):
    return run_node(AgentNode, 'swarm_agent', argv)


if __name__ == '__main__':
    sys.exit(main())
