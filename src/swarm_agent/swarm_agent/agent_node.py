"""AgentNode: one agent of the swarm; integrates its own Frenet frame (its topics: docs/ros-graph.md).

Lockstep: reads one packed ``/lockstep/step`` message per step (states of all agents, λ,
leader flags, s_k, target, barrier of that step), computes u with the core law, integrates,
publishes its next state on ``/swarm/states``.
Realtime: a timer at the control rate (1/dt in sim time) uses the newest states of agents
within w (all agents when the law couples globally), read from the agent processes' batches
on ``/swarm/agent_states``, the commander's newest decision on ``/swarm/decision`` (λ, the
leaders, its s_k), ``/world/target`` and ``/world/barrier``; it publishes its state on
``/swarm/states`` and, alone, in its own batch.
No agent reads ``/swarm/lambda`` or its ``steering`` topic: a user's command there is for the
commander alone (docs/commands.md).
Bad inputs are rejected with one log line naming them; no NaN ever enters the state.

An agent with a robot (parameter ``robot``: external, mujoco) reads its pose from the robot's
odometry and commands it on ``cmd_vel`` instead of integrating (`swarm_agent.robot_driver`).

`AgentNode` is what every agent node has whatever its mode (name, parameters, its pure
`AgentCore`, the ``/swarm/states`` publisher, the inputs every mode reads, the radio and the
faults); the mode's own work is done by its driver, `LockstepDriver` or `RealtimeDriver`
(``node.driver``; `DRIVERS` maps the parameter ``mode`` to the class).  A driver declares its
parameters, takes the mode's own input (`on_input`), and says how a radio change applies.

In an agent container (``swarm_agent_container``, `swarm_agent.container_node`) the node is built with
``contained=True``: it keeps its name, parameters, logger and ``/swarm/states`` publisher, and
the container feeds it the inputs its agents share (the step relay, ``/swarm/agent_states``,
the commander's decision, target, barrier, events) from one subscription each.

Communication model (parameter ``comms``: the scenario's ``comms`` section as JSON, '' = a
perfect radio; see swarm_core.radio): the agent applies it on its receive side.  Lockstep: from
each step's table it keeps only what its radio delivers (`AgentCore.comms_control`; in 3D
`NaturalAgentCore.comms_control`; equal to the batch engine bit for bit).  Realtime: each
incoming state is lost or delayed by the same seeded fate function (keyed by the state's step),
kept in flight until its delivery time, and the control uses the newest delivered state of each
neighbour dead-reckoned to now, leaving out neighbours silent for longer than the timeout.
Runtime changes (``swarm drop``, ``swarm partition``) arrive on ``/swarm/events`` and switch the
radio path on if it was off.
"""
from __future__ import annotations

import json
import math
import os
import sys

import numpy as np
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import String

from swarm_agent.agent_core import AgentCore, roster_index
from swarm_agent.drivers import DRIVERS, MODES
from swarm_agent.natural_core import NaturalAgentCore
from swarm_agent.process_io import decision_leaders, shared_inputs
from swarm_agent.robot_driver import ROBOT_DRIVERS, declare_robot
from swarm_core.checks import DT_BOUND, LAMBDA_BOUND, STEERING_BOUND
from swarm_core.command.plan import is_kind, law_with
from swarm_core.laws import (
    DEFAULTS,
    LawError,
    default_law,
    from_flat_parameters,
    law_class,
    names,
    parameter_specs,
)
from swarm_core.laws.registry import law_code_hash
from swarm_core.model.integrate import noise_rng
from swarm_core.radio import CommModel, change_from_event
from swarm_core.reserved import check_law_names
from swarm_core.robot_units import ROBOT_KINDS
from swarm_ros import protocol as P
from swarm_ros.layouts import NaturalDecision, RealtimeDecision
from swarm_ros.msg_checks import (
    RejectLog,
    check_barrier,
    check_decision_time,
    decoded,
    guard_subscriptions,
    new_sender_tag,
    refused,
)
from swarm_ros.rosutil import ParameterError, declare, run_node
from swarm_ros.run_control import event_text, run_event
from swarm_ros.runinfo import declare_run_id

#: values of the parameter ``pair_sums`` (`swarm_core.laws.paper.compiled_sums.run_sums`)
PAIR_SUMS = ('numpy', 'compiled')
#: wall s an agent stopped by a signal waits for its states to be acknowledged (`flush_states`):
#: one heartbeat of the run's DDS profile (0.25 s), within the 1 s a stop may take
ACK_WAIT = 0.3


class AgentNode(Node):
    """What every agent node has, whatever its mode: its name and parameters, its `AgentCore`,
    the ``/swarm/states`` publisher, the inputs every mode reads (target, barrier,
    /swarm/events: the radio and, contained, faults; realtime: the commander's decision).  The mode's own work is its
    driver's (`DRIVERS`)."""

    def __init__(self, node_name='agent', *, namespace=None, context=None, parameter_overrides=None,
                 cli_args=None, contained=False, services=True):
        if not services:         # in a big container: no parameter/type-description services, no /rosout
            parameter_overrides = list(parameter_overrides or []) + [
                Parameter('start_type_description_service', value=False)]
        if contained:            # no /clock reader made only for the container to remove it (see below)
            parameter_overrides = list(parameter_overrides or []) + [Parameter('use_sim_time', value=False)]
        super().__init__(node_name, namespace=namespace, context=context, cli_args=cli_args,
                         parameter_overrides=parameter_overrides, enable_rosout=services,
                         start_parameter_services=services)
        if contained:            # the container sets its agents' clocks (container_node): sim time, no reader
            self._time_source.detach_node()
            self.set_parameters([Parameter('use_sim_time', value=True)])
        self.contained = contained
        self.lean = not services     # no parameter services: no history of /swarm/states either (`unread`)
        self.sim_clock = self.get_clock()   # a realtime container's agents share its first agent's
        self.halted = None       # contained: 'kill' or 'freeze' (fault events for this agent)
        leader, pose, noise, seed, mode_parameters, comms = self._declare_parameters()
        try:
            self.roster, self.index = roster_index(self.roster, self.agent_name, self.index)
        except ValueError as err:
            raise ParameterError(str(err)) from None
        self.n = len(self.roster)
        self.row = {nm: i for i, nm in enumerate(self.roster)}
        if self.dim == 3:       # a 3D run (dim: 3): r and the frame [x y z] (`natural_core`)
            self.core = NaturalAgentCore(self.index, self.n, (pose[0], pose[1], self.z0), self.frame0, self.law,
                                         self.dt, noise, noise_rng(seed, self.index))
        else:
            self.core = AgentCore(self.index, self.n, *pose, self.law, self.dt, noise, noise_rng(seed, self.index))
        if self.pair_sums == 'compiled':
            os.environ.setdefault('NUMBA_NUM_THREADS', '1')     # before numba's import: one thread per process
            self.core.sums_compiled()
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
        self.driver = driver_class(self.mode, self.robot)(self, **mode_parameters[self.mode], **self.robot_parameters)
        if self.radio_on:
            self.driver.radio_started()
        if not contained:
            for typ, topic, cb, qos, raw in shared_inputs(self, self.driver.on_input):
                self.create_subscription(typ, topic, cb, qos, raw=raw)
        self.sender_tag = new_sender_tag()     # who we are on /swarm/states (protocol.SENDER_TAG_INDEX)
        self.serialize_state = P.OdometryWriter(self.agent_name, tag=self.sender_tag)
        self._own = None         # (sec, nanosec, x, y, qz, qw, u) last published (`own`)
        self.own_due = False     # moved in a container's batch, its state not made yet (`own`)
        self.states_held = None  # lockstep: states serialised but not yet sent (`send_held_states`)
        self.pub_events = None   # /swarm/events, made at the first live law change (`publish_event`)
        self.driver.start()
        guard_subscriptions(self, self.reject, passes=(LawError,))    # no message ends the agent
        # live parameters, as in ros2/demos (set_parameters_callback.py) and the commander:
        # pre-set adjusts the request, on-set checks it, post-set applies it
        self.add_pre_set_parameters_callback(self._pre_set)
        self.add_on_set_parameters_callback(self._check_params)
        self.add_post_set_parameters_callback(self._apply_params)

    def _declare_parameters(self):
        """Declare every parameter (those of every mode too); the agent's own go on self."""
        ns = self.get_namespace().strip('/')
        d = lambda *a, **k: declare(self, *a, **k)
        # read once at the start (read_only: `ros2 param set` is refused); the law's parameters
        # but its kind are live, and the realtime driver's (docs/ros-graph.md, "Parameters")
        self.agent_name = d('agent_name', ns or 'agent_0', 'agent name (child_frame_id of its states)', read_only=True)
        self.roster = list(d('agent_names', [''], 'names of all agents in agent-index order (the table order)',
                             read_only=True))
        self.index = d('agent_index', -1, "this agent's row in agent_names (-1: look the name up)", lo=-1, hi=100000,
                       read_only=True)
        leader = d('leader', False, 'leader (true) or follower until the commander decides', read_only=True)
        pose = (d('x', 0.0, 'initial x position', read_only=True), d('y', 0.0, 'initial y position', read_only=True),
                d('theta', 0.0, 'initial heading θ (rad)', read_only=True))
        self._declare_3d(d)
        self.law = self._declare_law()
        self.dt = d('dt', 0.05, 'control period / integration step (sim s)', lo=DT_BOUND.lo, hi=DT_BOUND.hi,
                    read_only=True)
        self.mode = d('mode', 'lockstep', 'lockstep or realtime', choices=MODES, read_only=True)
        noise = (d('noise_position', 0.0, 'uniform noise half-width on x, y per step', lo=0.0, hi=1e6, read_only=True),
                 d('noise_heading', 0.0, 'uniform noise half-width on θ per step', lo=0.0, hi=1e6, read_only=True))
        seed = d('seed', 0, 'scenario seed (noise stream)', lo=0, hi=2**31 - 1, read_only=True)
        self.robot = d('robot', 'none', 'none: a kinematic point; external or mujoco: drive a robot through '
                       '/<agent>/cmd_vel from /<agent>/odom (swarm_agent.robot_driver)', choices=ROBOT_KINDS,
                       read_only=True)
        mode_parameters = {mode: driver.declare(self) for mode, driver in DRIVERS.items()}
        self.robot_parameters = {}
        if self.robot != 'none':
            self.robot_parameters = declare_robot(self)
        comms = d('comms', '', "communication model: the scenario's comms section as JSON ('' = perfect; "
                  'changes during a run: swarm drop, swarm partition)', read_only=True)
        self.pair_sums = d('pair_sums', 'numpy', "how the law sums pairs: numpy, or compiled (numba, and in lockstep "
                           "the usual step in one compiled call; `swarm run --compiled` chooses per run as `swarm "
                           "simulate` does, so both compute the same bits)",
                           choices=PAIR_SUMS, read_only=True)
        self.run_id = declare_run_id(self, 'lockstep steps of another run are rejected')
        return leader, pose, noise, seed, mode_parameters, comms

    def _declare_3d(self, d):
        """``dim`` (2, or 3: a 3D run), and in 3D the initial ``z`` and ``frame`` (x, y, z of the
        initial frame, 9 numbers, orthonormal and right-handed)."""
        self.dim = d('dim', 2, 'dimensions: 2 (planar) or 3 (r and the frame [x y z]; docs/model.md)', lo=2, hi=3,
                     read_only=True)
        self.z0 = d('z', 0.0, '3D: initial z position', read_only=True)
        self.frame0 = list(d('frame', [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], '3D: initial frame x, y, z '
                             '(9 numbers, orthonormal, right-handed)', read_only=True))
        ground = d('ground', '', "3D, realtime: the floor's height h (the barrier's ground; '' = none)", read_only=True)
        try:
            self.ground = float(ground) if ground.strip() else None
        except ValueError:
            raise ParameterError(f'parameter ground: {ground!r} is not a number') from None
        if self.dim == 3:
            f = np.asarray(self.frame0, float)
            if f.size != 9 or not np.all(np.isfinite(f)) or not np.allclose(f.reshape(3, 3) @ f.reshape(3, 3).T,
                                                                             np.eye(3), atol=1e-9) \
                    or np.linalg.det(f.reshape(3, 3)) < 0:
                raise ParameterError('parameter frame: 9 finite numbers x, y, z of an orthonormal right-handed frame')

    def _declare_law(self):
        """The law's parameters: its kind (``law``; a blend's ``from.law``, ``to.law`` too), then
        every parameter of that law with its range and description (`laws.parameter_specs`)."""
        values = {}

        def kinds(prefix=''):
            values[prefix + 'law'] = declare(
                self, prefix + 'law', DEFAULTS['law'], f'control law{" (" + prefix[:-1] + ")" if prefix else ""}: '
                f'{", ".join(names())}, or a user\'s FILE.py:Class or module:Class (docs/laws.md)', read_only=True)
            for part in law_class(values[prefix + 'law']).parts:      # a blend's from and to
                kinds(f'{prefix}{part}.')
        try:
            kinds()
            template = default_law(values)
            check_law_names(template)       # (a scenario refuses it too, `swarm_core.reserved`)
            for name, (default, text, limits) in parameter_specs(template).items():
                if name.endswith('law') and name in values:
                    continue
                if isinstance(limits, tuple) and isinstance(limits[0], str):
                    values[name] = declare(self, name, default, text, choices=limits)
                elif limits is None:
                    values[name] = declare(self, name, default, text)
                else:
                    values[name] = declare(self, name, default, text, lo=limits[0], hi=limits[1])
            self.law_values = values
            law = from_flat_parameters(values)
            self.law_hash = law_code_hash(law.mapping())      # the file as this process imported it
            return law
        except LawError as err:
            raise ParameterError(f'parameter law: {err}') from None

    def _radio(self, comms, seed):
        try:
            cfg = json.loads(comms) if comms.strip() else None
            if cfg is not None and not isinstance(cfg, dict):
                raise ValueError('not a JSON object')
            return CommModel.from_config(cfg, self.roster, self.dt, seed)
        except (ValueError, TypeError, KeyError) as err:
            raise ParameterError(f'parameter comms: {err}') from None

    # ------------------------------------------------------------ live parameters
    def _live_law(self, name):
        return name in self.law_values and not is_kind(name)

    def _pre_set(self, params):
        """``ros2 param set /agent_0/agent alpha 1`` sends an integer: make it the declared double."""
        return [Parameter(p.name, value=float(p.value))
                if p.type_ == Parameter.Type.INTEGER and self.has_parameter(p.name)
                and isinstance(self.get_parameter(p.name).value, float) else p for p in params]

    def _check_params(self, params):
        """Refuse what cannot take effect: the clock (chosen at the start), a law change its
        law does not accept (`law_with`), and one whose law raises on the inputs of the agent's
        last u (`AgentCore.trial`: the set is refused with the law's one line and the run goes
        on); read-only parameters and values out of range rclpy refuses itself."""
        changes = {p.name: p.value for p in params if self._live_law(p.name)}
        for p in params:
            if p.name == 'use_sim_time':
                return SetParametersResult(successful=False, reason="use_sim_time: the agent's clock is chosen at "
                                           'the start (restart the agent to change it)')
        if changes:
            try:
                why = self.core.trial(law_with(self.law, changes))
            except ValueError as err:
                why = str(err)
            if why is not None:
                self.reject('law-set', f'law parameters {", ".join(f"{k}={v!r}" for k, v in changes.items())}: '
                            f'{why}')
                return SetParametersResult(successful=False, reason=why)
        return SetParametersResult(successful=True)

    def _apply_params(self, params):
        """A law change takes effect at the agent's next step: in lockstep the step it holds
        (its next u), announced on /swarm/events as a ``command`` event (the world writes it to
        events.jsonl; ``swarm simulate --replay`` applies it at that step); in realtime at the
        next control period; the event carries a user's law file's hash (``law_hash``).  The
        realtime driver's parameters take effect at its next tick, logged in one line and
        announced as a ``parameter`` event (with the values they replace, ``was``)."""
        changes = {p.name: p.value for p in params if self._live_law(p.name)}
        driver = {p.name: p.value for p in params if p.name in self.driver.live_parameters}
        lockstep = self.mode == 'lockstep'
        step = self.core.step if lockstep else P.step_of(self._now(), self.dt)
        t = step * self.dt if lockstep else self._now()
        if driver:                   # realtime: from the next tick; said and recorded (a peer may set them)
            was = {k: getattr(self.driver, k) for k in driver}
            for k, v in driver.items():
                setattr(self.driver, k, v)
            self.publish_event(dict(t=t, kind='parameter', agent=self.agent_name, parameters=driver, was=was,
                                    step=step))
            self.get_logger().info('realtime: ' + ', '.join(f'{k} {was[k]!r} -> {v!r}' for k, v in driver.items())
                                   + f' from step {step}')
        if not changes:
            return
        self.law = self.core.law = law_with(self.law, changes)
        self.law_values.update(changes)
        ev = dict(t=t, kind='command', command='law', agent=self.agent_name, parameters=changes, step=step)
        if self.law_hash:            # a user's law: which file's code runs (`laws.registry.law_code_hash`)
            ev['law_hash'] = self.law_hash
        self.publish_event(ev)
        self.get_logger().info(f'law: {", ".join(f"{k}={v!r}" for k, v in changes.items())} from step {step}')

    def publish_event(self, ev):
        """One event of this agent on /swarm/events (its writer is made at the first: one DDS
        endpoint less per agent in a run that never changes a law; transient-local, so the
        world's reader gets it once matched)."""
        if self.pub_events is None:
            self.pub_events = self.create_publisher(String, P.EVENTS, P.qos_latched(100))
        self.pub_events.publish(String(data=event_text(dict(ev, node='agent'), self.run_id)))

    # ------------------------------------------------------------ output
    @property
    def own(self):
        """(sec, nanosec, x, y, qz, qw, u): the state this agent published last, or holds
        (a container's batch moved it without a reader of /swarm/states: made when asked)."""
        if self.own_due:
            self.own_due = False
            self._own = self._state_now()
        return self._own

    @own.setter
    def own(self, value):
        self._own, self.own_due = value, False

    def _state_now(self, u=None):
        sec, nsec = P.time_to_stamp(self.t)
        if self.dim == 3:      # (sec, nanosec, x, y, qz, qw, u, z, qx, qy, v): the planar tuple, then 3D's
            qx, qy, qz, qw = self.core.quaternion
            b, j = self.core.states, self.core.slot
            return (sec, nsec, float(b.pos[j, 0]), float(b.pos[j, 1]), qz, qw, float(b.u[j] if u is None else u),
                    float(b.pos[j, 2]), qx, qy, float(b.v[j]))
        qz, qw = self.core.quaternion
        b, j = self.core.states, self.core.slot
        return (sec, nsec, float(b.pos[j, 0]), float(b.pos[j, 1]), qz, qw, float(b.u[j] if u is None else u))

    def publish_state(self, u=None):
        """Publish the own state of t (pre-serialised: no message object per step), carrying
        ``u`` (default: the u held last).  Lockstep, past the first `P.STATES_DEPTH` steps, a
        state no reader is matched for is not sent (`unread`)."""
        self.own = self._state_now(u)
        if self.unread():
            return
        o = self.own
        raw = self.serialize_state(*o) if self.dim == 2 else \
            self.serialize_state.full(o[0], o[1], (o[2], o[3], o[7]), (o[8], o[9], o[4], o[5]), o[6], o[10])
        if self.states_held is None:
            self.pub.publish(raw)
        else:                    # the process answers the world first (`process_io.step_message`)
            self.states_held.append(raw)

    def unread(self) -> bool:
        """Lockstep: nobody would get this state (no reader of /swarm/states matched, the step
        past the writer's history of the start; a lean node of a big container keeps no
        history for late readers); the world reads /lockstep/agent_states.  Serialising and
        writing it would be work for nothing, for each agent of a container each step
        (docs/ros-graph.md, "/swarm/states")."""
        return self.mode == 'lockstep' and (self.step >= P.STATES_DEPTH or self.lean) and \
            self.pub.get_subscription_count() == 0

    def send_held_states(self):
        """Publish the states `publish_state` held, and hold no more."""
        held, self.states_held = self.states_held, None
        for raw in held or ():
            self.pub.publish(raw)

    def flush_states(self):
        """On SIGINT / SIGTERM: wait up to `ACK_WAIT` s for the reliable readers of
        /swarm/states (a recorder) to acknowledge every state sent, so that one lost datagram
        is resent on the next heartbeat rather than dropped with the process."""
        self.pub.wait_for_all_acked(Duration(seconds=ACK_WAIT))

    def applied(self, u):
        """Note the control u applied over the step held (`u_history`)."""
        self.u_history.append((self.step, u))
        if len(self.u_history) > 10000:
            del self.u_history[:5000]

    # ------------------------------------------------------------ inputs of every mode
    def _on_decision(self, raw):
        """Realtime: the commander's decision of a tick (serialized ``/swarm/decision``); one
        stamped more than ``future_tolerance`` ahead of this clock is refused (a peer's)."""
        d = decoded(NaturalDecision if self.dim == 3 else RealtimeDecision, raw, self.run_id, self.reject, 'decision')
        if d is not None and not refused(self.reject, check_decision_time(d, self._now(),
                                                                          self.driver.future_tolerance)):
            self.take_decision(d)

    def take_decision(self, d, leaders=None):
        """λ, the leaders and this agent's s_k of decision ``d`` (a `RealtimeDecision`; a
        container decodes it once and gives each agent the ``leaders`` set, `decision_leaders`),
        each checked on its own: a bad value is refused with one line and the rest is taken."""
        if len(d.flags) != self.n:
            self.reject('decision-n', f'{P.DECISION} with {len(d.flags)} agents (the roster has {self.n})')
            return
        if LAMBDA_BOUND.ok(d.lam):
            self.lam = float(d.lam)
        else:
            self.reject('lambda', f'{P.DECISION}: {LAMBDA_BOUND.error(d.lam)}')
        s = float(d.steering[self.index]) if self.dim == 2 else tuple(map(float, d.steering[self.index]))
        bad = [v for v in (s if self.dim == 3 else (s,)) if not STEERING_BOUND.ok(v)]    # 3D: (s_u, s_v)
        if not bad:
            self.steering = s
        else:
            self.reject('steer', f'{P.DECISION} for {self.agent_name}: {STEERING_BOUND.error(bad[0])}')
        self.leaders = decision_leaders(d, self.roster, self.leaders) if leaders is None else leaders

    def _on_target(self, msg):
        p = (msg.point.x, msg.point.y) if self.dim == 2 else (msg.point.x, msg.point.y, msg.point.z)
        if not all(math.isfinite(v) for v in p):
            self.reject('target', f'{P.TARGET} {p}: not finite')
            return
        self.target = np.array(p)

    def _on_barrier(self, msg):
        pts = [(q.x, q.y) if self.dim == 2 else (q.x, q.y, q.z) for q in msg.polygon.points]
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
            ev = run_event(msg.data, self.run_id)        # only events of this run act (docs/security.md)
            mine = isinstance(ev, dict) and ev.get('agent') == self.agent_name
            if (self.contained or self.robot != 'none') and mine and ev.get('kind') in ('kill', 'freeze', 'resume'):
                self.fault(ev['kind'])
                return
            change = change_from_event(ev)
        except (ValueError, TypeError) as err:
            self.reject(getattr(err, 'kind', 'event'), f'{P.EVENTS} event {msg.data[:80]!r}: {str(err)[:120]}')
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
    # a law that failed: one line; a stop: the states sent are acknowledged first
    return run_node(AgentNode, 'swarm_agent', argv, fatal=(LawError,), on_stop=AgentNode.flush_states)


if __name__ == '__main__':
    sys.exit(main())
