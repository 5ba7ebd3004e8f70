"""AgentNode: one agent of the swarm; integrates its own Frenet frame (see swarm_ros.protocol).

Lockstep: reads one packed ``/lockstep/step`` message per step (states of all agents, λ,
leader flags, s_k, target, barrier of that step), computes u with the core law, integrates,
publishes its next state on ``/swarm/states``.
Realtime: a timer at the control rate (1/dt in sim time) uses the newest states on
``/swarm/states`` of agents within w (all agents when the law couples globally), the newest
``/swarm/lambda``, ``/swarm/leaders``, its ``steering`` topic, ``/world/target`` and
``/world/barrier``.
Bad inputs are rejected with one log line naming them; no NaN ever enters the state.

In an agent container (``swarm_agents``, `swarm_agent.container_node`) the node is built with
``contained=True``: it keeps its name, parameters, logger, ``steering`` subscription and
``/swarm/states`` publisher, and the container feeds it the inputs its agents share (the step
relay, ``/swarm/states``, λ, leaders, target, barrier, events) from one subscription each.

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
from swarm_core.laws import LAW_PARAMETERS, LawConfig
from swarm_core.scenario import noise_rng
from swarm_ros import protocol as P
from swarm_ros.msg_checks import (FUTURE_TOLERANCE, RejectLog, Senders, check_barrier, check_state, new_sender_tag,
                                  refused)
from swarm_ros.rosutil import ParameterError, declare, run_node, when_matched
from swarm_ros.runinfo import declare_run_id

from .agent_core import AgentCore, catch_up
from .container_core import ContainerCore
from .process_io import CLOCKS, AgentStatesWriter, shared_inputs, step_message, step_time

MODES = ('lockstep', 'realtime')


class AgentNode(Node):
    def __init__(self, node_name='agent', *, namespace=None, context=None, parameter_overrides=None,
                 cli_args=None, contained=False, services=True):
        if not services:         # in a big container: no parameter/type-description services, no /rosout
            parameter_overrides = list(parameter_overrides or []) + [
                Parameter('start_type_description_service', value=False)]
        super().__init__(node_name, namespace=namespace, context=context, cli_args=cli_args,
                         parameter_overrides=parameter_overrides, enable_rosout=services,
                         start_parameter_services=services)
        self.contained = contained
        self.halted = None       # contained: 'kill' or 'freeze' (fault events for this agent)
        ns = self.get_namespace().strip('/')
        d = lambda *a, **k: declare(self, *a, **k)  # noqa: E731
        self.agent_name = d('agent_name', ns or 'agent_0', 'agent name (child_frame_id of its states)')
        self.roster = list(d('agent_names', [''], 'names of all agents in agent-index order (the table order)'))
        self.index = d('agent_index', -1, "this agent's row in agent_names (-1: look the name up)", lo=-1, hi=100000)
        leader = d('leader', False, 'leader (true) or follower until /swarm/leaders says otherwise')
        x = d('x', 0.0, 'initial x position')
        y = d('y', 0.0, 'initial y position')
        theta = d('theta', 0.0, 'initial heading θ (rad)')
        defaults = LawConfig().parameters()          # one place for the defaults: the core's types
        law = {}
        for name, (text, limits) in LAW_PARAMETERS.items():
            if isinstance(limits, tuple) and isinstance(limits[0], str):
                law[name] = d(name, defaults[name], text, choices=limits)
            elif limits is None:
                law[name] = d(name, defaults[name], text)
            else:
                law[name] = d(name, defaults[name], text, lo=limits[0], hi=limits[1])
        self.law = LawConfig.from_parameters(law)
        self.dt = d('dt', 0.05, 'control period / integration step (sim s)', lo=1e-6, hi=10.0)
        self.mode = d('mode', 'lockstep', 'lockstep or realtime', choices=MODES)
        noise = (d('noise_position', 0.0, 'uniform noise half-width on x, y per step', lo=0.0, hi=1e6),
                 d('noise_heading', 0.0, 'uniform noise half-width on θ per step', lo=0.0, hi=1e6))
        seed = d('seed', 0, 'scenario seed (noise stream)', lo=0, hi=2**31 - 1)
        self.state_subscribers = d('state_subscribers', 0, 'lockstep: publish the first state only once this '
                                   'many readers of /swarm/states have matched (1 = the recorder; the world '
                                   'reads /lockstep/agent_states)', lo=0, hi=100000)
        self.stale_after = d('stale_after', 2.0, 'realtime: ignore neighbour states older than this (sim s)',
                             lo=0.0, hi=1e9)
        self.catch_up_limit = d('catch_up_limit', 4, 'realtime: most control periods one timer call '
                                'integrates when the sim clock jumped (u held); a longer gap (a stopped '
                                'or starved process) moves the agent this many', lo=1, hi=10**6)
        self.lockstep_clock = d('lockstep_clock', 'step', 'lockstep: sim time from each step message (step: '
                                'no /clock reader) or from /clock (topic); in a container its host '
                                "node's parameter applies", choices=CLOCKS)
        comms = d('comms', '', "communication model: the scenario's comms section as JSON ('' = perfect)")
        self.run_id = declare_run_id(self, 'lockstep steps of another run are rejected')
        self.future_tolerance = d('future_tolerance', FUTURE_TOLERANCE, 'realtime: reject neighbour states '
                                  'stamped more than this many sim s ahead of this clock', lo=0.0, hi=1e9)
        if self.roster == ['']:
            self.roster = [self.agent_name]
        if len(set(self.roster)) != len(self.roster):
            raise ParameterError('parameter agent_names: names must be unique')
        if self.agent_name not in self.roster:
            raise ParameterError(f'parameter agent_name: {self.agent_name!r} is not in agent_names')
        if self.index < 0:
            self.index = self.roster.index(self.agent_name)
        elif self.index >= len(self.roster) or self.roster[self.index] != self.agent_name:
            raise ParameterError(f'parameter agent_index: {self.index} does not name {self.agent_name!r} in agent_names')
        self.n = len(self.roster)
        self.row = {nm: i for i, nm in enumerate(self.roster)}
        rng = noise_rng(seed, self.index)
        self.core = AgentCore(self.index, self.n, x, y, theta, self.law, self.dt, noise, rng)
        self.reject = RejectLog(self.get_logger())
        self.senders = Senders()     # realtime: each neighbour name bound to its first publisher
        try:
            cfg = json.loads(comms) if comms.strip() else None
            if cfg is not None and not isinstance(cfg, dict):
                raise ValueError('not a JSON object')
            self.radio = CommModel.from_config(cfg, self.roster, self.dt, seed)
        except (ValueError, TypeError, KeyError) as err:
            raise ParameterError(f'parameter comms: {err}') from None
        self.radio_on = not self.radio.perfect
        if self.radio_on:
            self.core.attach_comms(self.radio)
        self.heard = {}          # realtime radio: name -> newest state heard (before the radio)
        self.stream = StreamRadio(self.radio, self.index)

        # live inputs (realtime; kept in lockstep for inspection)
        self.lam = 0.0
        self.steering = 0.0
        self.leaders = {self.agent_name} if leader else set()
        self.target = None
        self.barrier = None
        self.neigh = {}          # name -> (t, x, y, qz, qw)
        self.step = 0            # the step whose state we hold (lockstep: `core.step`)
        self.t = 0.0
        self.u_history = []      # (step, u) for tests (bounded)

        self.pub = self.create_publisher(Odometry, P.STATES, P.qos_latched(P.STATES_DEPTH))
        # transient-local: the commander's λ and steering in force, never a user's one-shot
        # command (that one is for the commander only; docs/commands.md)
        self.create_subscription(Float64, 'steering', self._on_steering, P.qos_latched(10))
        if not contained:
            for typ, topic, cb, qos, raw in shared_inputs(self):
                self.create_subscription(typ, topic, cb, qos, raw=raw)
            self.lock = ContainerCore([self.core])
        self.sender_tag = new_sender_tag()     # who we are on /swarm/states (protocol.SENDER_TAG_INDEX)
        self.serialize_state = P.OdometryWriter(self.agent_name, tag=self.sender_tag)
        self.own = None          # (sec, nanosec, x, y, qz, qw, u) last published
        if self.mode == 'realtime':
            self.timer = self.create_timer(self.dt, self._on_tick)
            self.publish_state()
        elif not contained:          # a lone agent: a container of one for the world
            if self.lockstep_clock == 'step':
                self._time_source.detach_node()      # the step messages carry the time: no /clock reader
            self.batch = AgentStatesWriter(self)
            self.start_lockstep(lambda agent: self.batch.publish([agent]))

    def start_lockstep(self, on_first):
        """Publish the first state, then call ``on_first(self)`` (the process sends it to the
        world on /lockstep/agent_states).  With ``state_subscribers`` > 0 only once that many
        readers of /swarm/states matched: a recorder matched late would miss the first states
        (the writer keeps 100), and the world starts step 0 only when it holds every first state."""
        def first():
            self.publish_state()
            on_first(self)
        if self.state_subscribers > 0:
            when_matched(self, lambda: self.pub.get_subscription_count() >= self.state_subscribers,
                         first, P.RECORDER_MATCH_WAIT,
                         f'{P.STATES}: fewer than {self.state_subscribers} readers matched')
        else:
            first()

    # ------------------------------------------------------------ output
    def publish_state(self):
        """Publish the own state of t (pre-serialised: no message object per step)."""
        sec, nsec = P.time_to_stamp(self.t)
        qz, qw = self.core.quaternion
        self.own = (sec, nsec, float(self.core.pos[0, 0]), float(self.core.pos[0, 1]), qz, qw,
                    float(self.core.u_last))
        self.pub.publish(self.serialize_state(*self.own))

    def _apply(self, u):
        u = self.core.advance(u)
        self._applied(u)

    def _applied(self, u):
        self.u_history.append((self.step, u))
        if len(self.u_history) > 10000:
            del self.u_history[:5000]

    @property
    def silent(self):
        """Lockstep: not in the table (frozen, or killed)."""
        return self.core.silent

    # ------------------------------------------------------------ lockstep
    def _on_step(self, raw):
        s = step_message(raw, self.lock, [self], self)
        if s is not None and self.lockstep_clock == 'step':
            step_time([self], s)

    def lockstep_outcome(self, kind, detail, s):
        """Carry out one `ContainerCore.on_step` decision for this agent."""
        if kind == 'moved':
            self.lam = s.lam
            self.step = s.n
            self._applied(detail)
            self.step = self.core.step
            self.t = self.step * self.dt
            self.publish_state()
        elif kind == 'repeat':       # a repeat (stall recovery): say our answer again
            self.publish_state()
        elif kind == 'silent':
            # faults: dead or frozen at this step: neither move nor speak (a frozen agent
            # resumes at the first step that lists it alive, with the state it holds)
            self.get_logger().info(f'not in the table from step {detail} on (killed or frozen)')
        elif kind == 'back':         # back after a freeze (maybe stopped before it saw one)
            self.get_logger().info(f'back in the table at step {s.n} (was frozen at step {detail})')
        elif kind == 'reject':
            self.reject(*detail)

    # ------------------------------------------------------------ realtime inputs
    def _on_lambda(self, msg):
        v = msg.data
        if not (math.isfinite(v) and 0.0 <= v <= 1.0):
            self.reject('lambda', f'λ={v!r} on {P.LAMBDA}: must be finite and in [0, 1]')
            return
        self.lam = v

    def _on_steering(self, msg):
        v = msg.data
        if not math.isfinite(v):
            self.reject('steer', f'steering s={v!r} for {self.agent_name}: not finite')
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

    # ------------------------------------------------------------ radio (communication model)
    def _on_event(self, msg):
        """Runtime radio changes from /swarm/events (see swarm_ros.protocol); in a container
        also the faults of this agent (the world cannot signal a process it shares)."""
        try:
            ev = json.loads(msg.data)
            if self.contained and isinstance(ev, dict) and ev.get('agent') == self.agent_name \
                    and ev.get('kind') in ('kill', 'freeze', 'resume'):
                self.fault(ev['kind'])
                return
            change = change_from_event(ev)
        except (ValueError, TypeError) as err:
            self.reject('event', f'{P.EVENTS} event {msg.data[:80]!r}: {str(err)[:120]}')
            return
        if change is None:
            return                    # faults, or scheduled in the scenario (applied from our copy)
        step = self.step if self.mode == 'lockstep' else P.step_of(self._now(), self.dt)
        try:
            self.radio.apply(change, step)
        except ValueError as err:     # e.g. an unknown agent in a partition
            self.reject('event', f'{P.EVENTS} event: {str(err)[:120]}')
            return
        if not self.radio_on:
            self.radio_on = True
            if self.mode == 'lockstep':
                self.core.attach_comms(self.radio)
        self.get_logger().info(f'radio: {json.dumps(change)} from step {step}')

    def fault(self, kind):
        """Contained: kill (stop for good), freeze (stop until resume) or resume this agent
        alone, as SIGKILL / SIGSTOP / SIGCONT do to an agent process."""
        if self.halted == 'kill':
            return
        self.halted = None if kind == 'resume' else kind
        if kind == 'kill':
            self.lock_kill()
        self.get_logger().info(f'fault: {kind} (in-process: the other agents of the container go on)')

    def lock_kill(self):
        """Set by the container: stop this agent's lockstep for good."""

    def _now(self):
        return self.get_clock().now().nanoseconds * 1e-9

    def radio_table(self, now):
        """Like `table`, from what the radio delivered (`comms.StreamRadio`)."""
        rows, states = self.stream.table(now, (self.core.pos[0, 0], self.core.pos[0, 1], *self.core.quaternion))
        flags = np.array([self.roster[j] in self.leaders for j in rows])
        return int(np.searchsorted(rows, self.index)), states, flags

    def _on_state(self, msg):
        name = msg.child_frame_id
        if name == self.agent_name:
            if msg.pose.covariance[P.SENDER_TAG_INDEX] != self.sender_tag:
                self.reject('dup-self', f'state claiming to be {name!r} (this agent) from another publisher: '
                            'duplicate agent name')
            return
        tag = msg.pose.covariance[P.SENDER_TAG_INDEX]
        if refused(self.reject, check_state(msg, self.row, self.heard if self.radio_on else self.neigh, self._now(),
                                            self.future_tolerance) or self.senders.check(name, tag)):
            return
        self.senders.accept(name, tag)
        p = msg.pose.pose
        vals = (P.stamp_to_time(msg.header.stamp), p.position.x, p.position.y,
                p.orientation.z, p.orientation.w, msg.twist.twist.angular.z)
        if self.radio_on:
            self.heard[name] = vals
            self.stream.hear(self.row[name], vals, self.core.pos[0])
        else:
            self.neigh[name] = vals

    # ------------------------------------------------------------ realtime control
    def table(self, now):
        """(x, y, qz, qw, flags) over the agents known at time ``now`` plus self; own row."""
        names = [nm for nm in self.roster if nm == self.agent_name or
                 (nm in self.neigh and now - self.neigh[nm][0] <= self.stale_after)]
        rows = np.array([self.neigh[nm][1:5] if nm != self.agent_name else
                         (self.core.pos[0, 0], self.core.pos[0, 1], *self.core.quaternion) for nm in names])
        flags = np.array([nm in self.leaders for nm in names])
        return names.index(self.agent_name), rows, flags

    def _on_tick(self):
        """Realtime: one control period.  The agent moves by the sim time that passed since its
        last state, in whole periods dt with u held (ZOH; `core.catch_up`), not by one dt per
        call: a /clock jump may cover two periods and fire the timer once (it catches up), or
        fire it again at the same time (nothing moves, so no two states share a stamp)."""
        if self.halted is not None:
            return
        now = self.get_clock().now().nanoseconds * 1e-9
        periods, t_new = catch_up(now, self.t, self.dt, self.catch_up_limit)
        if periods == 0:
            return
        if self.radio_on:
            own, rows, flags = self.radio_table(now)
        else:
            own, rows, flags = self.table(now)
        saved = self.core.index
        self.core.index = own
        try:
            u = self.core.control(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], self.lam, flags,
                                  self.steering, self.target, self.barrier)
        finally:
            self.core.index = saved
        if not math.isfinite(u):
            self.reject('u-nan', f'non-finite control u={u}; holding u=0')
            u = 0.0
        for _ in range(periods):
            self._apply(u)
        self.step += periods
        self.t = t_new
        self.publish_state()


def main(argv=None):
    return run_node(AgentNode, 'swarm_agent', argv)


if __name__ == '__main__':
    sys.exit(main())
