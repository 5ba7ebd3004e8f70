"""swarm_agent_container: an agent container — several agents of the swarm in one process.

Usage: ``swarm_agent_container [--no-services] AGENT [AGENT ...] --ros-args --params-file FILE``
(``swarm run --agents-per-process K`` starts it; ``--no-services``: the agent nodes have no
parameter services, type-description service or /rosout writer, see ``--agent-services``). Every
agent is its own rclpy node ``/AGENT/agent`` (its own parameters from FILE, logger and
``/swarm/states`` publisher), as an agent process would be. What the agents
share is done once per process, on a host node ``/agent_container_<first index>``: one
subscription each to the step relay (lockstep: decoded once, the controls of all agents from one
law call, see `swarm_agent.container_core`; the agents' new states go to the world in ONE
``/lockstep/agent_states`` message), ``/swarm/agent_states`` (realtime: the other processes'
batches of states, one table of the states heard, checked once; and the commander's decision,
``/swarm/decision``: λ, leaders, s_k), target, barrier and ``/swarm/events``, and one sim clock.
Realtime: ONE timer at the control rate drives all the agents (`process_io.realtime_tick`: one
law call for the agents that hear perfectly, one batched move, each agent publishing its state,
and their new states in ONE ``/swarm/agent_states`` message); an agent with a radio model hears
through its own radio and computes its own u.

Sim time: in lockstep the agents' clocks are set from each step message (parameter
``lockstep_clock`` = step, default; no ``/clock`` reader) or follow ``/clock`` (topic); in
realtime they follow ``/clock`` through one subscription of the host node.

Robot agents (parameter ``robot``, `swarm_agent.robot_driver`) share a container as kinematic
ones do, each with its own cmd_vel, odom and events on its own node.  Lockstep: the container's
answer to a step waits until every robot agent that moved has its odometry of the next state
(`robot_driver.OdometryHold`), so it stays one message per step.  Realtime: the kinematic agents
tick on the one timer; each robot agent on a timer of its own (on the same clock), its state in
the container's batches.

Faults: the world does not signal a process that holds several agents; the container obeys
the fault events on ``/swarm/events`` for its own agents (kill: the agent stops for good;
freeze ... resume), and the others go on. Killing the process kills all its agents.
"""
from __future__ import annotations

import sys

from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time_source import TimeSource
from rclpy.utilities import remove_ros_args

from swarm_agent.agent_node import AgentNode
from swarm_agent.drivers import heard_table
from swarm_agent.natural_core import container_of
from swarm_agent.natural_realtime import hear_own
from swarm_agent.process_io import (
    CLOCKS,
    AgentStatesWriter,
    LeaderMask,
    decision_leaders,
    decode_batch,
    realtime_tick,
    shared_inputs,
    step_message,
)
from swarm_agent.realtime_core import Continued
from swarm_agent.robot_driver import OdometryHold
from swarm_core.laws import LawError
from swarm_ros import protocol as P
from swarm_ros.layouts import NaturalDecision, NaturalProcessStates, ProcessStates, RealtimeDecision
from swarm_ros.msg_checks import RejectLog, check_decision_time, decoded, guard_subscriptions, refused
from swarm_ros.rosutil import ParameterError, declare, run_node, step_time
from swarm_ros.run_clock import follow_run_clock


class AgentContainer(Node):
    """The host node of a container and its agents (`agents`)."""

    USAGE_ARGS = '[--no-services] AGENT [AGENT ...]'      # for --help

    def __init__(self, names=None, *, context=None, parameter_overrides=None, agent_overrides=None, services=None):
        names = list(names if names is not None else AGENT_NAMES)
        services = SERVICES[0] if services is None else services
        if not names:
            raise ParameterError('swarm_agent_container: name at least one agent '
                                 '(swarm_agent_container AGENT [AGENT ...])')
        agent_overrides = agent_overrides or {}
        self.agents = [AgentNode('agent', namespace=nm, context=context, contained=True, services=services,
                                 parameter_overrides=agent_overrides.get(nm)) for nm in names]
        first = self.agents[0]
        super().__init__(f'agent_container_{first.index}', context=context,
                         parameter_overrides=[Parameter('use_sim_time', value=False)] + list(parameter_overrides or []))
        self.mode = first.mode
        self.n = first.n
        if any(a.mode != self.mode or a.roster != first.roster for a in self.agents):
            raise ParameterError('swarm_agent_container: the agents of a container need the same mode and agent_names')
        self.lockstep_clock = declare(self, 'lockstep_clock', 'step', "lockstep: the agents' sim time from each "
                                      'step message (step) or from /clock (topic)', choices=CLOCKS, read_only=True)
        self.reject = RejectLog(self.get_logger())
        self.lock = container_of([a.core for a in self.agents])
        for j, a in enumerate(self.agents):
            a.lock_kill = (lambda j=j: self.lock.kill(j))
        # one sim clock for all agents: their own /clock readers go, their clocks follow one source
        # (realtime: the agents read the first one's clock, so a /clock message sets one clock, not K;
        # lockstep: every agent node's clock IS the first one's, so a step sets one clock, not K)
        self.clock_source = TimeSource()
        for a in self.agents:
            a._time_source.detach_node()
            if self.mode == 'realtime':
                a.sim_clock = first.get_clock()
            else:
                a._clock = first.get_clock()        # rclpy's Node keeps its clock there (get_clock)
        self.clock_source.attach_clock(first.get_clock())
        if self.mode == 'realtime' and first.run_id:      # a run's: its clock alone (`run_clock`), no /clock
            self.clock_source.ros_time_is_active = True
            follow_run_clock(self, first.run_id, self.reject, [first.get_clock()], self.clock_source)
        elif self.mode == 'realtime' or self.lockstep_clock == 'topic':
            self.clock_source.attach_node(self)
            self.clock_source.ros_time_is_active = True
        else:
            self.clock_source.ros_time_is_active = True          # set by hand from the step messages
        on_input = self._on_step if self.mode == 'lockstep' else self._on_state
        for typ, topic, cb, qos, raw in shared_inputs(self, on_input):
            self.create_subscription(typ, topic, cb, qos, raw=raw)
        if self.mode == 'realtime':
            self._start_realtime()
        else:
            self.batch = AgentStatesWriter(self)     # the agents' states for the world, in one message
            self.answers = self.batch
            if any(a.robot != 'none' for a in self.agents):     # held until their robots' odometry came
                self.answers = OdometryHold(self.batch, self.agents)
                for a in self.agents:
                    a.driver.hold = self.answers
            for a in self.agents:
                a.driver.start_lockstep(self._first_state)
        guard_subscriptions(self, self.reject, passes=(LawError,))    # no message ends the container
        self.get_logger().info(f'{len(self.agents)} agents: {", ".join(a.agent_name for a in self.agents)}')

    def _first_state(self, _agent):
        """Lockstep: once every agent has published its first state, send them to the world."""
        if all(a.own is not None for a in self.agents):
            self.batch.publish(self.agents)

    # the shared inputs, handed to every agent
    def _on_step(self, raw):
        s = step_message(raw, self.lock, self.agents, self.reject, self.answers)
        if s is not None and self.lockstep_clock == 'step':
            step_time(self.agents[:1], s)           # the clock of every agent (see __init__)

    def _to_every_agent(name):                             # builds a method of the class
        def handler(self, msg):
            for a in self.agents:
                getattr(a, name)(msg)
        handler.__name__ = name
        return handler

    def _on_decision(self, raw):
        """Realtime: the commander's decision comes every control period: decoded once, its
        leaders made a set once, taken by every agent (each checks its values as it would alone)."""
        first = self.agents[0]
        d = decoded(NaturalDecision if first.dim == 3 else RealtimeDecision, raw, first.run_id, self.reject,
                    'decision')
        if d is not None and refused(self.reject, check_decision_time(d, first._now(), first.driver.future_tolerance)):
            return
        if d is None or len(d.flags) != first.n:
            if d is not None:
                self.reject('decision-n', f'{P.DECISION} with {len(d.flags)} agents (the roster has {first.n})')
            return
        leaders = decision_leaders(d, first.roster, first.leaders)
        for a in self.agents:
            a.take_decision(d, leaders)

    _on_target = _to_every_agent('_on_target')
    _on_barrier = _to_every_agent('_on_barrier')
    _on_event = _to_every_agent('_on_event')
    del _to_every_agent

    def _start_realtime(self):
        """One table of the states heard and one batch writer for all the agents; one timer for
        the kinematic ones and one for each robot agent (`robot_driver.RealtimeRobotDriver`: its
        robot's pose, not a move), all on the first agent's clock."""
        first = self.agents[0]
        self.heard = heard_table(first)
        self.batch = AgentStatesWriter(self, realtime=True)
        for a in self.agents:          # each published its first state when it was built
            a.driver.join(self.batch.tag, self.heard)
            self.heard.own[a.index] = True
            if a.dim == 3:
                hear_own(self.heard, a)
            else:
                self.heard.hear(a.agent_name, (a.t, *a.own[2:]))
        self.batch.publish(self.agents)
        kinematic = [a for a in self.agents if a.robot == 'none']
        self.rt_timers = []
        for a in self.agents:
            if a.robot != 'none':
                a.driver.batch = self.batch
                self.rt_timers.append(first.create_timer(first.dt, a.driver.on_tick))
        if kinematic:
            lock, leaders, continued = container_of([a.core for a in kinematic]), LeaderMask(first.roster), Continued()
            self.rt_timers.append(first.create_timer(
                first.dt, lambda: realtime_tick(kinematic, lock, self.heard, leaders, self.batch, continued)))

    def _on_state(self, raw):
        """Another process's states on /swarm/agent_states (serialized): decoded once, checked
        and taken at once into the shared table, and heard by each agent with a radio model
        through its own radio (`RealtimeDriver.hear_batch`; it hears the container's own agents
        through it each tick, `realtime_core.hear_mates`)."""
        first = self.agents[0]
        m = decode_batch(raw, first.run_id, first.roster, self.batch.tag, self.reject,
                         NaturalProcessStates if first.dim == 3 else ProcessStates)
        if m is None:
            return
        radio = [a for a in self.agents if a.radio_on]
        for a in radio:
            a.driver.hear_batch(m)
        if len(radio) < len(self.agents):
            self.heard.take(m, first.roster, first._now(), first.driver.future_tolerance, self.reject)

    def destroy_node(self):
        for a in self.agents:
            a.destroy_node()
        return super().destroy_node()


AGENT_NAMES: list = []
SERVICES = [True]
#: ``swarm_agent_container --no-services AGENT ...``: the agent nodes without parameter services,
#: type-description service and /rosout (see `container_core.agent_services`)
NO_SERVICES = '--no-services'


def main(argv=None):
    args = sys.argv if argv is None else argv
    own = remove_ros_args(list(args))[1:]
    SERVICES[0] = NO_SERVICES not in own
    AGENT_NAMES[:] = [a for a in own if a not in ('-h', '--help', NO_SERVICES)]
    return run_node(AgentContainer, 'swarm_agent_container', args, more_nodes=lambda c: c.agents,
                    fatal=(LawError,))        # a law that failed: one line


if __name__ == '__main__':
    sys.exit(main())
