"""What the agents of one process share, whether it holds one agent (`agent_node`) or several
(`container_node`): the subscriptions every agent reads alike, the step relay decoded once and
decided for all (lockstep), the sim time from the step messages, and the one message per step
(``/lockstep/agent_states``) or tick (realtime: ``/swarm/agent_states``) that carries the agents'
new states to the world and, in realtime, to the other agent processes and the commander."""
from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import PointStamped, PolygonStamped
from std_msgs.msg import Float64MultiArray, String

from swarm_agent.natural_realtime import natural_realtime_tick
from swarm_agent.realtime_core import CATCH_UP_MAX, advance_periods, due_periods, hear_mates, shared_controls
from swarm_core.laws import LawError
from swarm_ros import protocol as P
from swarm_ros.layouts import AgentStates, NaturalAgentStates, NaturalProcessStates, ProcessStates
from swarm_ros.msg_checks import batch_ok, check_step_time, decoded, new_sender_tag, refused
from swarm_ros.rosutil import fail

#: lockstep: where an agent's sim time comes from (parameter ``lockstep_clock``)
CLOCKS = ('step', 'topic')


def shared_inputs(node, on_input):
    """(type, topic, callback, QoS, raw) of the subscriptions whose messages every agent of a
    process reads alike (a container makes each once and hands the messages to its agents;
    `node` is the agent or the container); ``on_input`` takes the mode's own input (lockstep:
    the step relay; realtime: the processes' batches of states, /swarm/agent_states).

    λ, the leaders and s_k come with the commander's decision: in each step message (lockstep),
    on /swarm/decision (realtime).  No agent reads /swarm/lambda or /<agent>/steering: what a
    user publishes there is a command for the commander alone, and a reader there that a stock
    ``ros2 topic pub`` cannot match would log an incompatible-QoS warning (docs/ros-graph.md)."""
    subs = [(PointStamped, P.TARGET, node._on_target, P.qos_latched(), False),
            (PolygonStamped, P.BARRIER, node._on_barrier, P.qos_latched(), False),
            (String, P.EVENTS, node._on_event, P.qos_latched(100), False)]
    if node.mode == 'lockstep':
        subs.append((Float64MultiArray, P.LOCK_STEP, on_input, P.qos_latched(), True))
    else:
        subs.append((Float64MultiArray, P.AGENT_STATES, on_input,  # `decode_batch`
                     P.qos_latched(max(50, 4 * node.n)), True))
        subs.append((Float64MultiArray, P.DECISION, node._on_decision, P.qos_latched(), True))
    return subs


def decision_leaders(d, roster, leaders):
    """The leader names of decision ``d``: ``leaders`` (the set held) if they are the same, so
    that a set only changes when the leaders do (`LeaderMask` keys on it)."""
    now = {roster[i] for i in np.flatnonzero(d.flags)}
    return leaders if now == leaders else now


class AgentStatesWriter:
    """The states of one agent process's agents in one message (`node`: the lone agent or the
    container's host node), under the process's sender tag: lockstep ``/lockstep/agent_states``
    per step for the world; realtime ``/swarm/agent_states`` per tick for every reader of
    states (world, commander, the other agent processes)."""

    def __init__(self, node, realtime=False):
        self.tag = new_sender_tag()
        self.realtime = realtime
        topic, qos = (P.AGENT_STATES, P.qos_latched(P.AGENT_STATES_DEPTH)) if realtime else \
            (P.LOCK_AGENT_STATES, P.qos_latched())
        self.pub = node.create_publisher(Float64MultiArray, topic, qos)
        self.pack_one = None           # lockstep: (run id, `Layout.packer` of one agent's answer)
        self.pack_3d = None            # the same of a 3D agent (`_lone_3d`)

    def publish(self, agents):
        """The state each of ``agents`` last published on /swarm/states (realtime: with its stamp)."""
        if not agents:
            return
        if getattr(agents[0], 'dim', 2) == 3:                # a 3D run: from the bank (`NaturalStates`)
            b = agents[0].core.states
            index, rows = [a.index for a in agents], [a.core.slot for a in agents]
            msg = b.message(self.tag, index, rows)
            if self.realtime:
                msg = NaturalProcessStates(self.tag, msg.index, np.array([a.t for a in agents]),
                                           msg.state.transpose(0, 2, 1).reshape(12, -1), msg.uv)
            self.pub.publish(msg.to_cdr(agents[0].run_id))
            return
        if len(agents) == 1 and not self.realtime:          # a lone agent, each step: no message object
            a = agents[0]
            if self.pack_one is None or self.pack_one[0] != a.run_id:
                self.pack_one = (a.run_id, AgentStates.LAYOUT.packer((1,), a.run_id))
            self.pub.publish(self.pack_one[1](self.tag, a.index, a.step, *a.own[2:]))
            return
        if self.realtime:
            rows = list(zip(*[(a.index, a.own[0] + a.own[1] * 1e-9, *a.own[2:]) for a in agents]))
            msg = ProcessStates(self.tag, rows[0], rows[1], rows[2:6], rows[6])
        else:
            rows = list(zip(*[(a.index, a.step, *a.own[2:]) for a in agents]))
            msg = AgentStates(self.tag, rows[0], rows[1], rows[2:6], rows[6])
        self.pub.publish(msg.to_cdr(agents[0].run_id))

    def publish_rows(self, lock, js, run_id):
        """Lockstep: the states of the agents at positions ``js`` of ``lock`` (a
        `ContainerCore`) straight from its bank of states: one message, no Python per agent."""
        b = lock.bank
        if lock.dim == 3:
            self.pub.publish(self._lone_3d(b, lock.rows, int(js[0]), run_id) if len(js) == 1 else
                             b.message(self.tag, lock.rows[js], js).to_cdr(run_id))
            return
        stale = js[~b.fresh[js]]
        if stale.size:
            b.refresh(stale)
        msg = AgentStates(self.tag, lock.rows[js], b.step[js], (b.pos[js, 0], b.pos[js, 1], b.qz[js], b.qw[js]),
                          b.u[js])
        self.pub.publish(msg.to_cdr(run_id))

    def _lone_3d(self, b, rows, j, run_id) -> bytes:
        """What `NaturalStates.message` of the one row j makes, packed from plain floats (as a
        lone planar agent's answer, `publish`)."""
        if self.pack_3d is None or self.pack_3d[0] != run_id:
            self.pack_3d = (run_id, NaturalAgentStates.LAYOUT.packer((1,), run_id))
        return self.pack_3d[1](self.tag, float(rows[j]), float(b.step[j]), *b.pos[j].tolist(), *b.x[j].tolist(),
                               *b.y[j].tolist(), *b.z[j].tolist(), float(b.u[j]), float(b.v[j]))


def step_message(raw, lock, agents, reject, batch):
    """One ``/lockstep/step`` message for the agents of a process: decoded once, decided by
    their `ContainerCore` (one law call), carried out by each agent's lockstep driver; then the
    states of the agents that answered go to the world in one message (``batch``, an
    `AgentStatesWriter`), and only after it each agent's state on /swarm/states.  A step of
    another run (its id, swarm_ros.runinfo), or whose time is no sim time a stamp can hold, is
    rejected (``reject``: the process's `RejectLog`)."""
    s = decoded(lock.step_layout, raw, agents[0].run_id, reject, 'step-decode')
    if s is None:
        return None
    if refused(reject, check_step_time(s)):
        return None
    if (len(agents) > 1 or lock.dim == 3) and type(batch) is AgentStatesWriter:
        return _rows_step(s, lock, agents, batch)
    said = []
    try:
        outcomes = lock.on_step(s)
    except LawError as err:         # the agents' law failed: the process stops with one line
        fail(err)
        return None
    for a in agents:                # the answer to the world first: it is on the critical path
        a.states_held = []
    try:
        for j, kind, detail in outcomes:
            agents[j].driver.lockstep_outcome(kind, detail, s)
            if kind in ('moved', 'repeat'):
                said.append(agents[j])
        batch.publish(said)
    finally:                        # then /swarm/states, for the recorder and the user
        for a in agents:
            a.send_held_states()
    return s


def _rows_step(s, lock, agents, batch):
    """`step_message` of a container of kinematic agents: the rules, the law and the move over
    the bank's rows (`ContainerCore.step_rows`), the answer to the world from the bank
    (`AgentStatesWriter.publish_rows`), then each moved agent's bookkeeping (a few
    attributes); /swarm/states only where it has a reader (or in the first `P.STATES_DEPTH`
    steps), each agent its own, as alone."""
    try:
        moved, repeat, rules, nan = lock.step_rows(s)
    except LawError as err:         # the agents' law failed: the process stops with one line
        fail(err)
        return None
    said = np.concatenate((repeat, moved))
    if said.size:
        batch.publish_rows(lock, said, agents[0].run_id)
    n, n1, lam = s.n, s.n + 1, s.lam
    t1 = n1 * agents[0].dt
    for j, u in zip(moved.tolist(), lock.bank.u[moved].tolist()):
        a = agents[j]
        a.lam, a.step, a.t, a.own_due = lam, n1, t1, True
        h = a.u_history
        h.append((n, u))
        if len(h) > 10000:                  # bounded as `AgentNode.applied` keeps it
            del h[:5000]
    for j, kind, detail in rules + nan:     # the rare outcomes, one agent at a time
        agents[j].driver.lockstep_outcome(kind, detail, s)
    first = agents[int(said[0])] if said.size else None
    if first is not None and not first.unread():          # a reader of /swarm/states: each agent sends
        for j in said.tolist():
            agents[j].publish_state()
    return s


def decode_batch(raw, run_id, roster, own_tag, reject, layout=ProcessStates):
    """The serialized ``/swarm/agent_states`` message ``raw`` decoded (`layouts.ProcessStates`),
    or None for this process's own batch (``own_tag``) or a refused one (`msg_checks.batch_ok`).
    Its states are then checked and taken at once (`HeardStates.take`), by the process's table
    or by a radio agent's own table before its radio (`RealtimeDriver.hear_batch`)."""
    m = decoded(layout, raw, run_id, reject, 'state-decode')
    return m if m is not None and batch_ok(m, roster, own_tag, reject) else None


class LeaderMask:
    """The leader flags (n,) of a set of names, made again only when the set changes."""

    def __init__(self, roster):
        self.roster = roster
        self.names = self.mask = None

    def __call__(self, names):
        if names is not self.names:
            self.names, self.mask = names, np.array([nm in names for nm in self.roster])
        return self.mask


def realtime_tick(agents, lock, heard, leader_mask, batch, continued):
    """One realtime tick of the agents of a process (`realtime_core`): each agent not halted
    moves by the sim time that passed since its state, in whole periods dt with u held (ZOH;
    `due_periods`), not by one dt per call: a /clock jump may cover two periods and fire the timer
    once (it catches up), or fire it again at the same time (nothing moves, so no two states
    share a stamp); after the process was stopped (``continued``, a `Continued`) by at most
    each agent's ``catch_up_limit`` periods; more than `CATCH_UP_MAX` periods behind (a clock
    that started before the agent or jumped) an agent's time restarts at the clock (one line).
    The agents that hear perfectly and are fresh in ``heard`` get their u from one law call;
    the others (a radio model) one each.  Then one batched move, one state published by each
    agent that moved, each radio agent hearing the others' through its radio (`hear_mates`),
    and their states in one message (``batch``, an `AgentStatesWriter`).  ``lock``: the
    agents' `ContainerCore`; ``leader_mask``: a `LeaderMask` of the roster."""
    if lock.dim == 3:
        return natural_realtime_tick(agents, lock, heard, leader_mask, batch, continued)
    a0 = agents[0]
    now = a0._now()
    limits = [a.driver.catch_up_limit for a in agents] if continued() else None
    moving, follow = due_periods(now, [a.t for a in agents], a0.dt, [a.halted is not None for a in agents], limits)
    behind = [agents[j] for j, _ in follow if agents[j].halted is None]   # over CATCH_UP_MAX periods: no late tick
    if behind:
        who = 'this agent' if len(agents) == 1 else f'{len(behind)} agents ({behind[0].agent_name}, ...)'
        a0.get_logger().warning(
            f'realtime: the clock reads {now:.3f} s, {now - behind[0].t:.3f} s past the state of {who} (over '
            f'{CATCH_UP_MAX} periods: a clock that started before the agent or jumped); its time restarts there')
    for j, t_new in follow:
        agents[j].t = t_new
    if not moving:
        return
    stale = a0.driver.stale_after
    shared = [j for j, _, _ in moving if not agents[j].radio_on and lock.one_law
              and agents[j].driver.stale_after == stale and now - heard.t[agents[j].index] <= stale]
    us = {}
    try:
        if shared:
            mask = leader_mask(a0.leaders)
            u = shared_controls([agents[j].core for j in shared], heard, now, stale, a0.lam, mask,
                                [agents[j].steering for j in shared], a0.target, a0.barrier)
            us.update(zip(shared, u))
        for j, _, _ in moving:
            if j not in us:
                us[j] = agents[j].driver.control(now, heard)
    except LawError as err:         # the agents' law failed: the process stops with one line
        fail(err)
        return
    go = [j for j, _, _ in moving]
    for j in go:
        if not math.isfinite(us[j]):
            agents[j].reject('u-nan', f'non-finite control u={us[j]}; holding u=0')
            us[j] = 0.0
    advance_periods(lock, go, [p for _, p, _ in moving], [us[j] for j in go])
    for j, periods, t_new in moving:
        a = agents[j]
        for _ in range(periods):
            a.applied(float(us[j]))
        a.step += periods
        a.t = t_new
        a.publish_state()
        heard.hear(a.agent_name, (a.t, *a.own[2:]))
    if len(agents) > 1 and any(a.radio_on for a in agents):
        hear_mates(agents, [(agents[j].index, (agents[j].t, *agents[j].own[2:])) for j in go])
    batch.publish([agents[j] for j in go])
