"""CommanderNode: the λ schedule, the leaders and their steering programs, live commands.

The scenario's `swarm_core.command.plan.CommandPlan` (the batch engine runs the same) decides
λ, the leaders and s_k:
- lockstep: the world runs it on the table of each step, so that a step is two DDS hops
  (agents → world → agents), not four; the commander node forwards its live commands to the
  world (``/lockstep/command``) and reads each ``/lockstep/step`` for what was decided;
- realtime: the commander runs it, on a timer at 1/dt (sim time), from the newest states read
  from the agent processes' batches (``/swarm/agent_states``: one message per process and tick),
  and publishes it on ``/swarm/decision`` (`layouts.RealtimeDecision`) for the agents and the world.
It publishes the λ in force on ``/swarm/lambda``, ``/<leader>/steering`` (both reliable,
transient-local) and ``/swarm/leaders`` (latched), for the record and the tools.

Live commands (docs/commands.md), each applied at the next step decided and published with
that step on ``/swarm/events`` (``kind: command``; ``swarm simulate --replay`` re-applies them):
- ``/swarm/lambda`` (std_msgs/Float64) from anyone else, e.g. ``ros2 topic pub --once
  /swarm/lambda std_msgs/msg/Float64 "{data: 1.0}"``: ramp to it over ``ramp`` seconds;
- ``/commander/lambda_setpoint`` (std_msgs/Float64MultiArray ``[value, ramp_seconds]``, what
  ``swarm lambda`` sends): the same with its own ramp;
- ``/<agent>/steering`` from anyone else (``swarm steer agent_0 0.01``): that agent's program
  becomes the constant curvature (the agent becomes a leader if it was not);
- the parameters ``lambda``, ``ramp`` and ``steering.<agent>`` (``ros2 param set /commander
  lambda 1.0``): checked in the on-set callback, applied in the post-set callback.
The commander is the only node of a run that reads ``/swarm/lambda`` and ``/<agent>/steering``
with the VOLATILE durability of ``ros2 topic pub`` (agents and world read the decision; a
recorder reads the commander's transient-local output), so a one-shot publisher's single
match is always the commander, and no node of the run has a reader that a stock publisher's
default QoS cannot match (which would log an incompatible-QoS warning).

Every input topic's reader exists from the start (``ros2 node info /commander`` lists them),
but the readers of ``/swarm/lambda`` and ``/<agent>/steering``: each is made once a writer of
another node is seen there (`_watch_commands` says why).
λ outside [0, 1] or not finite, a non-finite steering value, an unknown agent: rejected with
one log line, nothing changes.

Faults (swarm_core.faults.agents): in lockstep the plan sees which agents the world heard at each step
(the alive mask of its table), so leader failover elects the same successor as the batch engine;
the decision carries the leader slots and the rendezvous (reunion) target.  The plan's events
(leaders chosen, failover, leader lost, rendezvous on/off, commands) go to ``/swarm/events``.
"""
from __future__ import annotations

import sys
import time
from collections import deque

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64, Float64MultiArray, String

from homotopy_commander.command_watch import CommandWatch, of_swarm
from swarm_core.checks import LAMBDA_BOUND, RAMP_BOUND, STEERING_BOUND
from swarm_core.command.plan import check_command
from swarm_core.faults.agents import event_names
from swarm_core.model.frenet import frame_from_quaternion, quaternion_from_heading
from swarm_ros import protocol as P
from swarm_ros.layouts import NaturalDecision, NaturalProcessStates, NaturalStep, ProcessStates, RealtimeDecision, Step
from swarm_ros.msg_checks import (
    FUTURE_TOLERANCE,
    ProcessSenders,
    RejectLog,
    check_agent_states,
    check_natural_pose,
    check_step_time,
    decoded,
    guard_subscriptions,
    new_sender_tag,
    refused,
)
from swarm_ros.rosutil import declare, gid_key, require_sim_clock, run_node, steady_clock, step_time, when_matched
from swarm_ros.run_clock import follow_run_clock
from swarm_ros.run_control import event_text, forward_text
from swarm_ros.runinfo import declare_run_id
from swarm_ros.scenario_params import declare_scenario

SETPOINT = P.LAMBDA_SETPOINT
#: depth of the commander's λ and steering writers (transient-local): a command reader made
#: later may receive that many of the commander's own last values
OWN_ECHO = P.STEP_DEPTH
#: wall seconds between looks at the graph for new command writers (which topics: CommandWatch)
COMMAND_POLL = 0.05
#: live commands the commander keeps (``taken``: what it accepted, for tools and tests)
TAKEN_KEPT = 100


class CommandReader:
    """A command topic and its reader (None until a writer of another node is seen)."""

    def __init__(self, topic, msg_type, callback, own=None):
        self.topic, self.msg_type, self.callback = topic, msg_type, callback
        self.own = own                   # key of the commander's own writer (own_sent), if any
        self.sub = None
        self.writers = frozenset()

    def drain(self):
        """Hand what the reader holds to the callback before it is dropped."""
        try:
            with self.sub.handle:
                while (got := self.sub.handle.take_message(self.msg_type, False)) is not None:
                    self.callback(got[0])
        except Exception:                # pragma: no cover - rclpy internals changed
            pass


class CommanderNode(Node):
    def __init__(self, node_name='commander', *, namespace=None, context=None, parameter_overrides=None,
                 cli_args=None):
        super().__init__(node_name, namespace=namespace, context=context, cli_args=cli_args,
                         parameter_overrides=parameter_overrides)
        self._declare_parameters()
        if self.mode == 'realtime':
            require_sim_clock(self, "the realtime commander's program runs on the world's sim clock (/clock) from 0")
        self.names = list(self.scn.names)
        self.n = len(self.names)
        self.row = {nm: i for i, nm in enumerate(self.names)}
        self.dt = self.scn.dt
        self.dim = self.scn.dim
        # s_k on /<agent>/steering: a curvature (Float64), in 3D (s_u, s_v) (Float64MultiArray)
        self.steer_type = Float64 if self.dim == 2 else Float64MultiArray
        self.plan = self.scn.command_plan()
        self.reject = RejectLog(self.get_logger())
        self.senders = ProcessSenders(self.n)    # realtime: each agent bound to its first process
        self.t = 0.0
        self.lam = float(self.plan.schedule.value(0.0))
        self._declare_live_parameters()
        self.leaders_sent = None
        self.steer_sent = {}
        self.pending = []            # realtime: live changes to apply at the next decision
        self.taken = deque(maxlen=TAKEN_KEPT)    # the live commands accepted, newest last
        self.decisions = 0
        self._create_outputs()
        self._create_command_readers()
        if self.mode == 'lockstep':
            self._start_lockstep()
        else:
            self._start_realtime()
        self.publish_leaders([])
        guard_subscriptions(self, self.reject)      # no message ends the commander

    def _declare_parameters(self):
        """The scenario (`declare_scenario`, as the world), the commander's own parameters
        and the run id."""
        d = lambda *a, **k: declare(self, *a, **k)
        self.mode = d('mode', 'lockstep', 'lockstep or realtime', choices=('lockstep', 'realtime'))
        self.ramp = d('ramp', 20.0, 'ramp duration (sim s) of a λ set-point from /swarm/lambda or the '
                      'lambda parameter (0 = jump)', lo=RAMP_BOUND.lo, hi=RAMP_BOUND.hi)
        self.ramp_shape = d('ramp_shape', 'smoothstep', 'shape of set-point ramps',
                            choices=('smoothstep', 'linear', 'tanh', 'step'))
        self.heard_timeout = d('heard_timeout', 1.0, 'realtime: an agent silent for this many sim s is not heard '
                               '(leader failover)', lo=0.0, hi=1e9)
        self.wait_for_recorder = d('wait_for_recorder', False, 'lockstep: take part only once the recorder '
                                   'matched /swarm/lambda and every steering topic too '
                                   f'(at most {P.RECORDER_MATCH_WAIT:g} s)')
        self.publish_every = d('publish_every', 10, 'lockstep: publish /swarm/lambda every this many steps',
                               lo=1, hi=10**9)
        self.run_id = declare_run_id(self, 'lockstep states of another run are rejected, decisions carry it')
        self.scn = declare_scenario(self)

    def _declare_live_parameters(self):
        """``lambda`` and ``steering.<agent>``: set during the run (docs/commands.md); checked
        in the on-set callback, applied in the post-set one."""
        d = lambda *a, **k: declare(self, *a, **k)
        d('lambda', self.lam, 'set λ: the commander ramps to it over `ramp` s from the next step '
          '(holds the last set-point)', lo=LAMBDA_BOUND.lo, hi=LAMBDA_BOUND.hi)
        for nm in self.names:
            d(f'steering.{nm}', 0.0, f'set the steering s_k (a curvature) of {nm} from the next step: it '
              'becomes a leader and its program this constant; holds the value set last (0.0 until set: not '
              f'the s_k in force, which is on {P.steering_topic(nm)})', lo=STEERING_BOUND.lo, hi=STEERING_BOUND.hi)
        self.add_pre_set_parameters_callback(self._pre_set)
        self.add_on_set_parameters_callback(self._check_params)
        self.add_post_set_parameters_callback(self._apply_params)

    def _create_outputs(self):
        # outputs: transient-local, so that a one-shot VOLATILE publisher (ros2 topic pub) matches
        # only the commander's command readers below, not the agents, world or recorder
        self.pub_lambda = self.create_publisher(Float64, P.LAMBDA, P.qos_latched(P.STEP_DEPTH))
        self.pub_leaders = self.create_publisher(String, P.LEADERS, P.qos_latched())
        self.pub_events = self.create_publisher(String, P.EVENTS, P.qos_latched(100))
        self.pub_steer = {nm: self.create_publisher(self.steer_type, P.steering_topic(nm),
                                                    P.qos_latched(P.STEP_DEPTH))
                          for nm in self.names}

    def _create_command_readers(self):
        # command readers (VOLATILE, as `ros2 topic pub` writes), each made only once a writer of
        # another node is in the graph (see _watch_commands).  rclpy's message info carries no
        # publisher id here, so the commander recognises its own publications by value: its own
        # messages come back in order (one FIFO per topic, kept while the reader exists)
        self.own_sent = {}
        self.commands = {P.LAMBDA: CommandReader(P.LAMBDA, Float64, self._on_lambda, P.LAMBDA)}
        for nm in self.names:
            self.commands[nm] = CommandReader(P.steering_topic(nm), self.steer_type,
                                              lambda msg, nm=nm: self._on_steering(nm, msg), nm)
        # λ every tick, the steering topics in turn (every one every tick up to 64 agents), and
        # those a node other than the swarm's writes, for a while after it appeared
        me = (self.get_name(), self.get_namespace())
        self.watch = CommandWatch([P.LAMBDA], self.names,
                                  ours=lambda nd: nd == me or of_swarm(nd, self.row))
        self.command_key = {c.topic: key for key, c in self.commands.items()}
        self.reading = set()         # keys of the commands whose reader exists
        self.create_timer(COMMAND_POLL, self._watch_commands, clock=steady_clock())
        # the set-point is the commander's own topic, read from the start: its writer (`swarm
        # lambda`, `Swarm.set_lambda`) waits for this reader, then for its acknowledgement
        self.create_subscription(Float64MultiArray, SETPOINT, self._on_setpoint, P.qos_reliable())

    def _start_lockstep(self):
        """The world decides each step (`swarm_world.lockstep`); the commander forwards its live
        commands and says when it takes part, then publishes what each step message carries."""
        self.last_step = -1
        # sim time from each step message, as the lockstep agents: no /clock reader, so that the
        # world's /clock goes to nobody in a run without a recorder or tools
        self._time_source.detach_node()
        self.forward_seq = 0
        self.forward_tag = new_sender_tag()
        self.pub_command = self.create_publisher(String, P.LOCK_COMMAND, P.qos_latched(100))
        self.create_subscription(Float64MultiArray, P.LOCK_STEP, self._on_step, P.qos_latched(), raw=True)
        if self.wait_for_recorder:
            # take part (the world waits for it) only once the recorder's readers of λ and
            # steering matched, so that it records the first of them
            when_matched(self, self._recorder_matched, self._join_lockstep, P.RECORDER_MATCH_WAIT,
                         f'the recorder has not matched {P.LAMBDA} and every steering topic')
        else:
            self._join_lockstep()

    def _start_realtime(self):
        """A timer at 1/dt (sim time) decides from the newest states (/swarm/agent_states); in a
        run (a run id) that sim time is the run's clock alone, not /clock (`swarm_ros.run_clock`)."""
        if self.run_id:
            follow_run_clock(self, self.run_id, self.reject)
        self.pos = self.scn.pos0.copy()
        if self.dim == 3:                        # the headings x heard (n, 3)
            self.heading = self.scn.frames0[0].copy()
        else:
            self.quat = np.stack(quaternion_from_heading(self.scn.theta0), axis=1)   # (n, 2) qz, qw heard
        self.last_seen = np.full(self.n, -np.inf)
        self.create_subscription(Float64MultiArray, P.AGENT_STATES, self._on_state, P.qos_latched(max(100, 4 * self.n)),
                                 raw=True)
        # what the agents and the world act on (never /swarm/lambda or steering: a user's command
        # there is for the commander alone); a reader that joins late gets the newest
        self.pub_rt_decision = self.create_publisher(Float64MultiArray, P.DECISION, P.qos_latched())
        self.timer = self.create_timer(self.dt, self._on_tick)

    def _recorder_matched(self):
        # readers of λ and steering: the recorder (and our own command reader, if one exists:
        # it matches our writer too)
        def others(key, pub):
            return pub.get_subscription_count() - (self.commands[key].sub is not None)
        return (others(P.LAMBDA, self.pub_lambda) >= 1
                and all(others(nm, p) >= 1 for nm, p in self.pub_steer.items()))

    def _watch_commands(self):
        """Make a command topic's reader when a writer of another node appears on it (again
        when another new one does), and drop it when none is left.

        ``ros2 topic pub --once`` publishes as soon as ONE reader matched ITS writer.  Discovery
        is asymmetric: a reader that existed before the writer may be matched on the writer's
        side before the reader's side knows the writer, and the reader then drops the sample
        (the tool has exited 0.1 s later, so it is never repaired).  A reader made after this
        participant discovered the writer is paired with it when it is made, before the tool
        can see it: the first sample is always taken.  That is why these two command topics
        have no reader from the start, as the node's other inputs have: against a reader that
        existed before it, the Jazzy ``ros2 topic pub --once`` lost its sample in 1 of 45 tries
        (one where the tool had to wait for discovery; docs/commands.md).

        One graph query per topic looked at: `CommandWatch` picks which (all of them in a swarm
        of up to 64 agents; in a bigger one those a new node writes, asked by node for 2 s after
        it appeared, and 4 more a tick in turn)."""
        me = (self.get_name(), self.get_namespace())
        now = time.monotonic()
        try:
            self.watch.nodes_seen(now, self.get_node_names_and_namespaces())
        except Exception:                # the context is going down
            return
        found = []
        for name, ns in self.watch.recent(now):
            try:
                writes = self.get_publisher_names_and_types_by_node(name, ns)
            except Exception:            # gone again, or the context is going down
                continue
            found += [self.command_key[t] for t, _ in writes if t in self.command_key]
        keys = self.watch.pick(now, self.reading, found)
        for key in keys:
            c = self.commands[key]
            try:
                infos = self.get_publishers_info_by_topic(c.topic)
            except Exception:            # the context is going down
                return
            writers = frozenset(gid_key(i.endpoint_gid) for i in infos if (i.node_name, i.node_namespace) != me)
            if writers - c.writers or (not writers and c.sub is not None):
                if c.sub is not None:
                    c.drain()
                    self.destroy_subscription(c.sub)
                    c.sub = None
                if writers:
                    c.sub = self.create_subscription(c.msg_type, c.topic, c.callback, P.qos_reliable())
                    guard_subscriptions(self, self.reject)
                    self.reading.add(key)
                else:
                    self.reading.discard(key)
                if c.own is not None and c.own in self.own_sent:
                    # a new reader may still get the last OWN_ECHO values of our own writer
                    # (its transient-local history): keep those to recognise them
                    del self.own_sent[c.own][:-OWN_ECHO]
            c.writers = writers

    def _join_lockstep(self):
        """Take part: the world starts once it has this message."""
        self._forward('ready')

    def _send(self, topic, pub, value):
        fifo = self.own_sent.setdefault(topic, [])
        fifo.append(value)
        if self.commands[topic].sub is None:          # no reader: only the writer's history can come back
            del fifo[:-OWN_ECHO]
        elif len(fifo) > 1000:
            del fifo[:500]
        pub.publish(Float64(data=value) if isinstance(value, float) else Float64MultiArray(data=list(value)))

    def _from_self(self, topic, value):
        fifo = self.own_sent.get(topic)
        if fifo and value in fifo:
            del fifo[:fifo.index(value) + 1]
            return True
        return False

    # ------------------------------------------------------------ live inputs
    def _on_lambda(self, msg):
        if self._from_self(P.LAMBDA, msg.data):
            return
        self.set_lambda(msg.data, self.ramp, P.LAMBDA)

    def _on_setpoint(self, msg):
        if len(msg.data) not in (1, 2):
            self.reject('setpoint', f'{SETPOINT} with {len(msg.data)} values (want [λ, ramp])')
            return
        ramp = msg.data[1] if len(msg.data) == 2 else self.ramp
        self.set_lambda(msg.data[0], ramp, SETPOINT)

    def set_lambda(self, value, ramp, source):
        """Queue a λ set-point for the next step (False, logged, if it is rejected)."""
        return self._queue(dict(command='lambda', value=value, ramp=ramp, shape=self.ramp_shape, source=source),
                           f'λ set-point {value:g} over {ramp:g} s (from {source})')

    def _on_steering(self, name, msg):
        value = msg.data if self.dim == 2 else tuple(msg.data)
        if self._from_self(name, value):
            return
        if self.dim == 3 and len(value) != 2:
            self.reject('steer', f'{P.steering_topic(name)} with {len(value)} values (want [s_u, s_v])')
            return
        self.set_steering(name, value, P.steering_topic(name))

    def set_steering(self, name, value, source):
        """Queue agent ``name``'s constant program ``value`` (3D: (s_u, s_v); a number is (s_u, 0))."""
        if self.dim == 3 and isinstance(value, float):
            value = (value, 0.0)
        shown = f'{value:g}' if isinstance(value, float) else '(' + ', '.join(f'{v:g}' for v in value) + ')'
        return self._queue(dict(command='steer', agent=self.row[name], value=value, source=source),
                           f'steering of {name} set to {shown} (from {source})')

    def _queue(self, cmd, text):
        try:
            cmd = check_command(cmd, self.n)
        except ValueError as err:
            self.reject(cmd['command'], f'{cmd["source"]}: {err}')
            return False
        self.taken.append(cmd)
        if self.mode == 'lockstep':          # the world decides: it applies it at its next step
            self._forward('command', cmd)
        else:
            self.pending.append(cmd)
        self.get_logger().info(text)
        return True

    def _forward(self, kind, command=None):
        """A message to the lockstep world (`run_control.forward_text`), numbered in order."""
        self.forward_seq += 1
        self.pub_command.publish(String(data=forward_text(kind, self.run_id, self.forward_tag, self.forward_seq,
                                                          command)))

    # parameters, as in ros2/demos (set_parameters_callback.py): pre-set adjusts the request,
    # on-set validates it, post-set applies it
    def _pre_set(self, params):
        """``ros2 param set /commander lambda 1`` sends an integer: make it the declared double."""
        return [Parameter(p.name, value=float(p.value))
                if self._live_param(p.name) and p.type_ == Parameter.Type.INTEGER else p for p in params]

    def _live_param(self, name):
        return name in ('lambda', 'ramp') or (name.startswith('steering.') and name[9:] in self.row)

    def _check_params(self, params):
        for p in params:
            if not self._live_param(p.name):
                continue
            v = p.value
            if p.type_ != Parameter.Type.DOUBLE:
                return SetParametersResult(successful=False, reason=f'{p.name}: want a double, got {v!r}')
            bound = LAMBDA_BOUND if p.name == 'lambda' else RAMP_BOUND if p.name == 'ramp' else STEERING_BOUND
            if not bound.ok(v):
                return SetParametersResult(successful=False, reason=f'{p.name}: {bound.error(v)}')
        return SetParametersResult(successful=True)

    def _apply_params(self, params):
        names = {p.name: p.value for p in params}
        if 'ramp' in names:
            self.ramp = float(names['ramp'])
        if 'lambda' in names:
            self.set_lambda(float(names['lambda']), self.ramp, 'parameter lambda')
        for name, v in names.items():
            if name.startswith('steering.') and name[9:] in self.row:
                self.set_steering(name[9:], float(v), f'parameter {name}')

    # ------------------------------------------------------------ deciding
    def decide(self, t, pos, cos_t, sin_t, heard=None):
        """Realtime: the plan's decision for time t (a `Decided`); pending commands apply now
        and are published with their step on /swarm/events."""
        commands, self.pending = self.pending, []
        d = self.plan.decide(t, pos, cos_t, sin_t, heard=heard, commands=commands)
        for ev in d.events:
            ev = dict(event_names(ev, self.names), node='commander')
            if ev['kind'] == 'command':
                ev['step'] = P.step_of(t, self.dt)
            self.pub_events.publish(String(data=event_text(ev, self.run_id)))
            if ev['kind'] in ('failover', 'leader_lost'):
                self.get_logger().warning(f't={t:.2f}: leader {ev["lost"]} lost; '
                                          + (f'{ev["agent"]} takes over its program' if 'agent' in ev
                                             else 'no follower to take over'))
        self.t, self.lam = t, d.lam
        self.decisions += 1
        return d

    def publish_outputs(self, lam, flags, steering, force=False):
        if force:
            self._send(P.LAMBDA, self.pub_lambda, float(lam))
        leaders = [self.names[i] for i in np.flatnonzero(flags)]
        if leaders != self.leaders_sent:
            self.publish_leaders(leaders)
        for i in np.flatnonzero(flags):
            nm = self.names[i]
            s = float(steering[i]) if self.dim == 2 else tuple(float(v) for v in steering[i])
            if force or self.steer_sent.get(nm) != s:
                self.steer_sent[nm] = s
                self._send(nm, self.pub_steer[nm], s)

    def publish_leaders(self, leaders):
        self.leaders_sent = list(leaders)
        self.pub_leaders.publish(String(data=','.join(leaders)))
        if leaders:
            self.get_logger().info(f'leaders: {", ".join(leaders)}')

    def _on_step(self, raw):
        """Lockstep: the world's step message, with its decision: published for the record."""
        s = decoded(Step if self.dim == 2 else NaturalStep, raw, self.run_id, self.reject, 'step-decode')
        if s is None or s.n <= self.last_step or refused(self.reject, check_step_time(s)):     # a repeat, a bad time
            return
        if len(s.flags) != self.n:
            self.reject('step-n', f'{P.LOCK_STEP} with {len(s.flags)} agents (scenario has {self.n})')
            return
        self.last_step = s.n
        self.t, self.lam = s.t, s.lam
        step_time([self], s)
        self.decisions += 1
        self.publish_outputs(s.lam, s.flags, s.steering, force=(s.n % self.publish_every == 0))

    def _on_state(self, raw):
        """Realtime: the states of one agent process (a serialized /swarm/agent_states
        message).  Bad ones are dropped without a line (the agents and the world log them): a
        message of another run, not finite, naming an agent outside the roster or twice, or
        not planar; a state from a second process for that agent, or stamped in the future."""
        three = self.dim == 3
        m = decoded(NaturalProcessStates if three else ProcessStates, raw, self.run_id, lambda *_: None, 'state-decode')
        if m is None or (check_natural_pose if three else check_agent_states)(m.index, m.pose, self.n,
                                                                             P.AGENT_STATES) is not None:
            return
        now = self.get_clock().now().nanoseconds * 1e-9
        ok, _ = self.senders.check(m.index, m.tag)
        ok = ok & (m.t <= now + FUTURE_TOLERANCE)           # not in place: `check` may hand back a shared mask
        idx = m.index[ok]
        self.senders.accept(idx, m.tag)
        if three:
            self.pos[idx], self.heading[idx] = m.pose[0:3, ok].T, m.pose[3:6, ok].T
        else:
            self.pos[idx] = m.pose[:2, ok].T
            self.quat[idx] = m.pose[2:, ok].T
        self.last_seen[idx] = m.t[ok]

    def _on_tick(self):
        t = self.get_clock().now().nanoseconds * 1e-9
        heard = None
        if self.plan.failover is not None:       # only failover reads it (a lagging agent is not lost)
            heard = t - self.last_seen <= self.heard_timeout
            heard = heard if heard.any() else None
        if self.dim == 3:                       # the headings seen from above, as `engine.natural` gives them
            cos_t, sin_t = self.heading[:, 0].copy(), self.heading[:, 1].copy()
        else:
            cos_t, sin_t = frame_from_quaternion(self.quat[:, 0], self.quat[:, 1])    # all at once, per tick
        d = self.decide(t, self.pos, cos_t, sin_t, heard=heard)
        decision = NaturalDecision if self.dim == 3 else RealtimeDecision
        self.pub_rt_decision.publish(decision(P.step_of(t, self.dt), t, d.lam, d.flags, d.steering, d.slots,
                                              d.rendezvous).to_cdr(self.run_id))
        self.publish_outputs(d.lam, d.flags, d.steering, force=True)


def main(argv=None):
    return run_node(CommanderNode, 'homotopy_commander', argv)


if __name__ == '__main__':
    sys.exit(main())
