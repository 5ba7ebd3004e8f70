"""AgentNode: one agent of the swarm; integrates its own Frenet frame (see swarm_ros.protocol).

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
perfect radio; see swarm_core.comms): the agent applies it on its receive side.  Lockstep: from
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

from swarm_core.comms import CommModel, StreamRadio, change_from_event
from swarm_core.inputs import DT_BOUND, LAMBDA_BOUND, STEERING_BOUND
from swarm_core.laws import LAW_PARAMETERS, LawConfig
from swarm_core.robot_units import ROBOT_KINDS
from swarm_core.scenario import noise_rng
from swarm_ros import protocol as P
from swarm_ros.msg_checks import (FUTURE_TOLERANCE, RejectLog, Senders, batch_states, check_barrier, check_values,
                                  new_sender_tag, refused)
from swarm_ros.rosutil import ParameterError, declare, run_node, when_matched
from swarm_ros.runinfo import declare_run_id

from .agent_core import AgentCore, known_table, roster_index
from .container_core import ContainerCore
from .process_io import (CLOCKS, AgentStatesWriter, LeaderMask, decode_batch, own_echo, realtime_tick,
                         shared_inputs, step_message, step_time)
from .realtime_core import Continued, HeardStates


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
            from .robot_driver import declare_robot
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
        """Runtime radio changes from /swarm/events (see swarm_ros.protocol); in a container
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


class LockstepDriver:
    """Lockstep: one ``/lockstep/step`` message per step (alone: its own subscription and a
    `ContainerCore` of one; contained: the container decides for all its agents and calls
    `lockstep_outcome`)."""

    @staticmethod
    def declare(node):
        """This mode's parameters (every agent node declares those of every mode)."""
        return dict(
            state_subscribers=declare(
                node, 'state_subscribers', 0, 'lockstep: publish the first state only once this many readers '
                'of /swarm/states have matched (1 = the recorder; the world reads /lockstep/agent_states)',
                lo=0, hi=100000),
            lockstep_clock=declare(
                node, 'lockstep_clock', 'step', 'lockstep: sim time from each step message (step: no /clock '
                "reader) or from /clock (topic); in a container its host node's parameter applies",
                choices=CLOCKS))

    def __init__(self, node, state_subscribers, lockstep_clock):
        self.node = node
        self.state_subscribers = state_subscribers
        self.lockstep_clock = lockstep_clock
        self.lock = None if node.contained else ContainerCore([node.core])
        self.batch = None

    def start(self):
        """Alone: a container of one for the world (contained: the container starts it)."""
        if self.node.contained:
            return
        if self.lockstep_clock == 'step':
            self.node._time_source.detach_node()      # the step messages carry the time: no /clock reader
        self.batch = AgentStatesWriter(self.node)
        self.start_lockstep(lambda agent: self.batch.publish([agent]))

    def start_lockstep(self, on_first):
        """Publish the first state, then call ``on_first(node)`` (the process sends it to the
        world on /lockstep/agent_states).  With ``state_subscribers`` > 0 only once that many
        readers of /swarm/states matched: a recorder matched late would miss the first states
        (the writer keeps 100), and the world starts step 0 only when it holds every first state."""
        node = self.node

        def first():
            node.publish_state()
            on_first(node)
        if self.state_subscribers > 0:
            when_matched(node, lambda: node.pub.get_subscription_count() >= self.state_subscribers,
                         first, P.RECORDER_MATCH_WAIT,
                         f'{P.STATES}: fewer than {self.state_subscribers} readers matched')
        else:
            first()

    def on_input(self, raw):
        """Alone: one ``/lockstep/step`` message."""
        s = step_message(raw, self.lock, [self.node], self.node.reject, self.batch)
        if s is not None and self.lockstep_clock == 'step':
            step_time([self.node], s)

    def lockstep_outcome(self, kind, detail, s):
        """Carry out one `ContainerCore.on_step` decision for this agent."""
        node = self.node
        if kind == 'moved':
            node.lam = s.lam
            node.step = s.n
            node.applied(detail)
            node.step = node.core.step
            node.t = node.step * node.dt
            node.publish_state()
        elif kind == 'repeat':       # a repeat (stall recovery): say our answer again
            node.publish_state()
        elif kind == 'silent':
            # faults: dead or frozen at this step: neither move nor speak (a frozen agent
            # resumes at the first step that lists it alive, with the state it holds)
            node.get_logger().info(f'not in the table from step {detail} on (killed or frozen)')
        elif kind == 'back':         # back after a freeze (maybe stopped before it saw one)
            node.get_logger().info(f'back in the table at step {s.n} (was frozen at step {detail})')
        elif kind == 'reject':
            node.reject(*detail)

    def radio_step(self):
        """The step from which a radio change applies: the step held."""
        return self.node.step

    def radio_started(self):
        """The radio is not perfect (any more): receive each step's table through it."""
        self.node.core.attach_comms(self.node.radio)


class RealtimeDriver:
    """Realtime: a timer at the control rate; neighbour states from the agent processes'
    batches on ``/swarm/agent_states`` (through the radio model if there is one), λ and the
    rest as they arrive.  Alone the agent is a container of one (`process_io.realtime_tick`,
    its own batch of one state per tick); contained, the container's one timer drives it, the
    container sends the batch and the states it heard perfectly are the container's
    (`HeardStates`)."""

    @staticmethod
    def declare(node):
        """This mode's parameters (every agent node declares those of every mode)."""
        return dict(
            stale_after=declare(node, 'stale_after', 2.0, 'realtime: ignore neighbour states older than this '
                                '(sim s)', lo=0.0, hi=1e9),
            catch_up_limit=declare(
                node, 'catch_up_limit', 4, 'realtime: most control periods the agent integrates (u held) after '
                'its process was stopped (SIGSTOP ... SIGCONT); a late tick of a running process integrates '
                'every period that passed', lo=1, hi=10**6),
            future_tolerance=declare(
                node, 'future_tolerance', FUTURE_TOLERANCE, 'realtime: reject neighbour states stamped more '
                'than this many sim s ahead of this clock', lo=0.0, hi=1e9))

    def __init__(self, node, stale_after, catch_up_limit, future_tolerance):
        self.node = node
        self.stale_after = stale_after
        self.catch_up_limit = catch_up_limit
        self.future_tolerance = future_tolerance
        self.senders = Senders()     # radio model: each neighbour name bound to its first publisher
        self.heard = HeardStates(node.roster)   # alone, perfect radio: newest states (contained: the container's)
        self.heard.own[node.index] = True
        self.radio_heard = {}        # radio model: name -> newest state heard (before the radio)
        self.stream = StreamRadio(node.radio, node.index)
        self.timer = None
        self.lock = None
        self.batch = None            # alone: its process's /swarm/agent_states writer
        self.process_tag = None      # the sender tag of its process's batches (contained: set by the container)

    def start(self):
        node = self.node
        if not node.contained:
            self.lock = ContainerCore([node.core])
            self.batch = AgentStatesWriter(node, realtime=True)
            self.process_tag = self.batch.tag
            leaders, continued = LeaderMask(node.roster), Continued()
            self.timer = node.create_timer(
                node.dt, lambda: realtime_tick([node], self.lock, self.heard, leaders, self.batch, continued))
        node.publish_state()
        self.heard.hear(node.agent_name, (node.t, *node.own[2:]))
        if self.batch is not None:
            self.batch.publish([node])

    def radio_step(self):
        """The step from which a radio change applies: that of the sim time now."""
        return P.step_of(self.node._now(), self.node.dt)

    def radio_started(self):
        """Nothing to switch: `on_input` routes states through the radio from now on."""

    def on_input(self, raw):
        """One agent process's states on ``/swarm/agent_states`` (serialized)."""
        node = self.node
        m = decode_batch(raw, node.run_id, node.roster, self.process_tag, node.reject)
        if m is None:
            return
        if node.radio_on:
            for state in batch_states(m, node.roster):
                self.hear_radio(state)
        else:
            self.heard.take(m, node.roster, node._now(), self.future_tolerance, node.reject)

    def hear_radio(self, state):
        """A decoded state (`decode_batch`) through this agent's radio model."""
        node = self.node
        name, t, pose, wz, tag = state
        if own_echo(name, tag, {node.agent_name: self.process_tag}, node.reject):
            return
        if refused(node.reject, check_values(name, t, pose, wz, node.row, self.radio_heard, node._now(),
                                             self.future_tolerance) or self.senders.check(name, tag)):
            return
        self.senders.accept(name, tag)
        vals = (t, pose[0], pose[1], pose[4], pose[5], wz)
        self.radio_heard[name] = vals
        self.stream.hear(node.row[name], vals, node.core.pos[0])

    def table(self, now, heard=None):
        """(own row, states (m, 4) of x, y, qz, qw, leader flags) of the agents known at ``now``
        (perfect radio: from ``heard``, a `HeardStates`, default this driver's)."""
        node, core = self.node, self.node.core
        heard = self.heard if heard is None else heard
        own = (core.pos[0, 0], core.pos[0, 1], *core.quaternion)
        if not node.radio_on:
            return known_table(node.roster, node.agent_name, own, heard.newest, node.leaders, now, self.stale_after)
        rows, states = self.stream.table(now, own)     # what the radio delivered (`comms.StreamRadio`)
        flags = np.array([node.roster[j] in node.leaders for j in rows])
        return int(np.searchsorted(rows, node.index)), states, flags

    def control(self, now, heard):
        """u of this agent alone at ``now`` (a radio model, or not in a shared table)."""
        node = self.node
        own, rows, flags = self.table(now, heard)
        return node.core.control(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], node.lam, flags, node.steering,
                                 node.target, node.barrier, row=own)


#: the modes of an agent node (parameter ``mode``) and the class that drives each
DRIVERS = {'lockstep': LockstepDriver, 'realtime': RealtimeDriver}
MODES = tuple(DRIVERS)


def driver_class(mode: str, robot: str):
    """The driver of an agent node in ``mode`` with ``robot`` (none: its own kinematic point;
    else `robot_driver.ROBOT_DRIVERS`, which builds on the classes above)."""
    if robot == 'none':
        return DRIVERS[mode]
    from .robot_driver import ROBOT_DRIVERS
    return ROBOT_DRIVERS.get((mode, robot), ROBOT_DRIVERS[mode])


def main(argv=None):
    return run_node(AgentNode, 'swarm_agent', argv)


if __name__ == '__main__':
    sys.exit(main())
