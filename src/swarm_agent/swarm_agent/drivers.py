"""The drivers of an agent node, one per mode: what the node does each step in lockstep
(`LockstepDriver`) and in realtime (`RealtimeDriver`).  A robot agent's drivers build on these
(`robot_driver`); `agent_node.driver_class` chooses one."""
from __future__ import annotations

import numpy as np

from swarm_agent.agent_core import known_table
from swarm_agent.natural_core import container_of
from swarm_agent.natural_realtime import hear_own, natural_heard
from swarm_agent.process_io import (
    CLOCKS,
    AgentStatesWriter,
    LeaderMask,
    decode_batch,
    realtime_tick,
    step_message,
)
from swarm_agent.realtime_core import (
    CATCH_UP_MAX,
    FUTURE_TOLERANCE_MAX,
    STALE_AFTER,
    STALE_AFTER_MAX,
    Continued,
    HeardStates,
    time_limits,
)
from swarm_core.natural_radio import NaturalStreamRadio
from swarm_core.radio import StreamRadio
from swarm_ros import protocol as P
from swarm_ros.layouts import NaturalProcessStates, ProcessStates
from swarm_ros.msg_checks import FUTURE_TOLERANCE
from swarm_ros.rosutil import declare, step_time, when_matched
from swarm_ros.run_clock import follow_the_run_clock


class LockstepDriver:
    """Lockstep: one ``/lockstep/step`` message per step (alone: its own subscription and a
    `ContainerCore` of one; contained: the container decides for all its agents and calls
    `lockstep_outcome`)."""

    #: the parameters of this mode that ``ros2 param set`` changes during a run (the others are read-only)
    live_parameters = ()

    @staticmethod
    def declare(node):
        """This mode's parameters (every agent node declares those of every mode): read once at
        the start."""
        return dict(
            state_subscribers=declare(
                node, 'state_subscribers', 0, 'lockstep: publish the first state only once this many readers '
                'of /swarm/states have matched (1 = the recorder; the world reads /lockstep/agent_states)',
                lo=0, hi=100000, read_only=True),
            lockstep_clock=declare(
                node, 'lockstep_clock', 'step', 'lockstep: sim time from each step message (step: no /clock '
                "reader) or from /clock (topic); in a container its host node's parameter applies",
                choices=CLOCKS, read_only=True))

    def __init__(self, node, state_subscribers, lockstep_clock):
        self.node = node
        self.state_subscribers = state_subscribers
        self.lockstep_clock = lockstep_clock
        self.lock = None if node.contained else container_of([node.core])
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

    #: the parameters of this mode that ``ros2 param set`` changes during a run (next tick on)
    live_parameters = ('stale_after', 'catch_up_limit', 'future_tolerance')

    @staticmethod
    def declare(node):
        """This mode's parameters (every agent node declares those of every mode): live in
        realtime (`live_parameters`), read-only in lockstep, where nothing reads them.  Their
        ranges (`time_limits`) keep a peer's set within what a run can use; each set is logged
        and recorded as a ``parameter`` event (`AgentNode._apply_params`)."""
        fixed = node.mode != 'realtime'
        robot = fixed or node.robot != 'none'     # a robot agent takes its pose each tick: no catch-up
        stale, future = time_limits(node.dt, STALE_AFTER, STALE_AFTER_MAX), time_limits(
            node.dt, FUTURE_TOLERANCE, FUTURE_TOLERANCE_MAX)
        return dict(
            stale_after=declare(node, 'stale_after', STALE_AFTER, 'realtime: ignore neighbour states older than '
                                f'this (sim s, {stale[0]:g} to {stale[1]:g})',
                                lo=stale[0], hi=stale[1], read_only=fixed),
            catch_up_limit=declare(
                node, 'catch_up_limit', 4, 'realtime: most control periods the agent integrates (u held) after '
                'its process was stopped (SIGSTOP ... SIGCONT); a late tick of a running process integrates '
                f'every period that passed (up to {CATCH_UP_MAX})', lo=1, hi=CATCH_UP_MAX, read_only=robot),
            future_tolerance=declare(
                node, 'future_tolerance', FUTURE_TOLERANCE, 'realtime: reject neighbour states and decisions '
                f'stamped more than this many sim s ahead of this clock ({future[0]:g} to {future[1]:g})',
                lo=future[0], hi=future[1], read_only=fixed))

    def __init__(self, node, stale_after, catch_up_limit, future_tolerance):
        self.node = node
        self.stale_after = stale_after
        self.catch_up_limit = catch_up_limit
        self.future_tolerance = future_tolerance
        # alone, perfect radio: newest states (contained: the container's; `join`)
        self.heard = heard_table(node)
        self.heard.own[node.index] = True
        self.radio_heard = None      # radio model: the newest states heard, before the radio (`hear_batch`)
        self.stream = (NaturalStreamRadio if node.dim == 3 else StreamRadio)(node.radio, node.index)
        self.timer = None
        self.lock = None
        self.batch = None            # alone: its process's /swarm/agent_states writer
        self.process_tag = None      # the sender tag of its process's batches (`join`)

    def start(self):
        node = self.node
        if not node.contained:
            follow_the_run_clock(node)
            now = node._now()
            if now > CATCH_UP_MAX * node.dt:     # no sim clock: its time starts at the first reading
                node.t = now
                node.get_logger().info(
                    f'realtime: the clock reads {now:.3f} s at the start (use_sim_time is '
                    f'{node.get_parameter("use_sim_time").value}; in a swarm run the agents follow the world\'s '
                    '/clock from 0): this agent\'s time starts there')
            self.lock = container_of([node.core])
            self.batch = AgentStatesWriter(node, realtime=True)
            self.join(self.batch.tag, self.heard)
            leaders, continued = LeaderMask(node.roster), Continued()
            self.timer = node.create_timer(
                node.dt, lambda: realtime_tick([node], self.lock, self.heard, leaders, self.batch, continued))
        node.publish_state()
        if node.dim == 3:
            hear_own(self.heard, node)
        else:
            self.heard.hear(node.agent_name, (node.t, *node.own[2:]))
        if self.batch is not None:
            self.batch.publish([node])

    def radio_step(self):
        """The step from which a radio change applies: that of the sim time now."""
        return P.step_of(self.node._now(), self.node.dt)

    def join(self, tag, heard):
        """Its process: the sender tag of its batches and the table of what its agents heard
        (``heard.own`` marks them: alone this agent, contained the container's agents).  Its
        radio refuses a state claiming to be any of them from another publisher, as that table does."""
        self.process_tag, self.heard = tag, heard
        if self.radio_heard is not None:
            self.radio_heard.own = heard.own

    def radio_started(self):
        """`on_input` routes states through the radio from now on, checked first as the
        process's table checks them, on a table of this agent's own (`hear_batch`)."""
        if self.radio_heard is None:
            self.radio_heard = heard_table(self.node)
            self.radio_heard.own = self.heard.own      # the process's agents (`join`)

    def on_input(self, raw):
        """One agent process's states on ``/swarm/agent_states`` (serialized)."""
        node = self.node
        m = decode_batch(raw, node.run_id, node.roster, self.process_tag, node.reject,
                         NaturalProcessStates if node.dim == 3 else ProcessStates)
        if m is None:
            return
        if node.radio_on:
            self.hear_batch(m)
        else:
            self.heard.take(m, node.roster, node._now(), self.future_tolerance, node.reject)

    def hear_batch(self, m):
        """Another process's batch (`ProcessStates`; 3D `NaturalProcessStates`) through this
        agent's radio model: its states checked and taken as the process's table takes them
        (`HeardStates.take`: one claiming to be an agent of this process is refused), each taken
        one then heard by the radio (t, x, y, qz, qw, u; 3D t, r, x, y, z, u, v)."""
        node = self.node
        ok = self.radio_heard.take(m, node.roster, node._now(), self.future_tolerance, node.reject)
        core = node.core
        own, u = core.states.pos[core.slot], m.u.reshape(len(m.t), -1)
        for j in np.flatnonzero(ok).tolist():
            self.stream.hear(int(m.index[j]), (float(m.t[j]), *m.pose[:, j].tolist(), *u[j].tolist()), own)

    def table(self, now, heard=None):
        """(own row, states (m, 4) of x, y, qz, qw, leader flags) of the agents known at ``now``
        (perfect radio: from ``heard``, a `HeardStates`, default this driver's)."""
        node, core = self.node, self.node.core
        heard = self.heard if heard is None else heard
        own = (core.pos[0, 0], core.pos[0, 1], *core.quaternion)
        if not node.radio_on:
            return known_table(node.roster, node.agent_name, own, heard.newest, node.leaders, now, self.stale_after)
        rows, states = self.stream.table(now, own)     # what the radio delivered (`radio.StreamRadio`)
        flags = np.array([node.roster[j] in node.leaders for j in rows])
        return int(np.searchsorted(rows, node.index)), states, flags

    def control(self, now, heard):
        """u of this agent alone at ``now`` (a radio model, or not in a shared table)."""
        node = self.node
        own, rows, flags = self.table(now, heard)
        return node.core.control(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], node.lam, flags, node.steering,
                                 node.target, node.barrier, row=own, t=now)


def heard_table(node) -> HeardStates:
    """An empty table of the newest states heard of the agents of ``node``'s run."""
    return natural_heard(node.roster) if node.dim == 3 else HeardStates(node.roster)


#: the modes of an agent node (parameter ``mode``) and the class that drives each
DRIVERS = {'lockstep': LockstepDriver, 'realtime': RealtimeDriver}
MODES = tuple(DRIVERS)
