"""What the agents of one process share, whether it holds one agent (`agent_node`) or several
(`container_node`): the subscriptions every agent reads alike, the step relay decoded once and
decided for all (lockstep), the sim time from the step messages, and the one
``/lockstep/agent_states`` message per step that carries the agents' new states to the world."""
from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import PointStamped, PolygonStamped
from nav_msgs.msg import Odometry
from rclpy.time import Time
from std_msgs.msg import Float64, Float64MultiArray, String

from swarm_ros import protocol as P
from swarm_ros.layouts import AgentStates, Step
from swarm_ros.msg_checks import check_values, decoded, new_sender_tag, refused

from .realtime_core import advance_periods, due_periods, shared_controls

#: lockstep: where an agent's sim time comes from (parameter ``lockstep_clock``)
CLOCKS = ('step', 'topic')


def shared_inputs(node, on_input):
    """(type, topic, callback, QoS, raw) of the subscriptions whose messages every agent of a
    process reads alike (a container makes each once and hands the messages to its agents;
    `node` is the agent or the container); ``on_input`` takes the mode's own input (lockstep:
    the step relay; realtime: /swarm/states)."""
    subs = [(Float64, P.LAMBDA, node._on_lambda, P.qos_latched(10), False),      # the λ in force
            (String, P.LEADERS, node._on_leaders, P.qos_latched(), False),
            (PointStamped, P.TARGET, node._on_target, P.qos_latched(), False),
            (PolygonStamped, P.BARRIER, node._on_barrier, P.qos_latched(), False),
            (String, P.EVENTS, node._on_event, P.qos_latched(100), False)]
    if node.mode == 'lockstep':
        subs.append((Float64MultiArray, P.LOCK_STEP, on_input, P.qos_latched(), True))
    else:
        subs.append((Odometry, P.STATES, on_input, P.qos_latched(max(50, 4 * node.n)), True))   # `decode_state`
    return subs


class AgentStatesWriter:
    """``/lockstep/agent_states`` of one agent process (`node`: the lone agent or the
    container's host node): its agents' states in one message for the world."""

    def __init__(self, node):
        self.tag = new_sender_tag()
        self.pub = node.create_publisher(Float64MultiArray, P.LOCK_AGENT_STATES, P.qos_latched())

    def publish(self, agents):
        """The state each of ``agents`` last published on /swarm/states."""
        if agents:
            rows = list(zip(*[(a.index, a.step, *a.own[2:]) for a in agents]))
            self.pub.publish(AgentStates(self.tag, rows[0], rows[1], rows[2:6], rows[6]).to_cdr(agents[0].run_id))


def step_time(agents, s):
    """Lockstep without /clock: the agents' sim time is that of step message ``s``."""
    now = Time(nanoseconds=int(round(s.t * 1e9)))
    for a in agents:
        a.get_clock().set_ros_time_override(now)


def step_message(raw, lock, agents, reject, batch):
    """One ``/lockstep/step`` message for the agents of a process: decoded once, decided by
    their `ContainerCore` (one law call), carried out by each agent's lockstep driver; then the
    states of the agents that answered go to the world in one message (``batch``, an
    `AgentStatesWriter`).  A step of another run (its id, swarm_ros.runinfo) is rejected
    (``reject``: the process's `RejectLog`)."""
    s = decoded(Step, raw, agents[0].run_id, reject, 'step-decode')
    if s is None:
        return None
    said = []
    for j, kind, detail in lock.on_step(s):
        agents[j].driver.lockstep_outcome(kind, detail, s)
        if kind in ('moved', 'repeat'):
            said.append(agents[j])
    batch.publish(said)
    return s


def decode_state(raw, reject):
    """(name, t, pose (x, y, qx, qy, qz, qw), angular.z, sender tag) of a serialized
    ``/swarm/states`` message (decoded without building an Odometry), or None (rejected)."""
    try:
        name, sec, nsec, pose, wz, tag = P.cdr_to_odometry_tagged(raw)
    except Exception as err:            # noqa: BLE001 - any malformed message is one rejection
        reject('state-decode', f'{P.STATES} message that does not decode: {str(err)[:120]}')
        return None
    return name, sec + nsec * 1e-9, pose, wz, tag


def own_echo(name, tag, own, reject) -> bool:
    """Is this state one of the process's own agents (``own``: name -> sender tag)?  From
    another publisher it is rejected as a duplicate agent name."""
    if name not in own:
        return False
    if tag != own[name]:
        reject('dup-self', f'state claiming to be {name!r} (this agent) from another publisher: duplicate agent name')
    return True


def hear_state(state, heard, senders, own, now, tolerance, reject):
    """A decoded state (`decode_state`) for the agents of a process that hear perfectly:
    checked once (`check_values`, one publisher per name) and kept in ``heard`` (a
    `HeardStates`).  ``own``: the process's agents, name -> sender tag; their own states are
    heard in-process when they publish, so their echo is dropped (from another publisher: a
    duplicate name)."""
    name, t, pose, wz, tag = state
    if own_echo(name, tag, own, reject):
        return
    if refused(reject, check_values(name, t, pose, wz, heard.row, heard.newest, now, tolerance)
               or senders.check(name, tag)):
        return
    senders.accept(name, tag)
    heard.hear(name, (t, pose[0], pose[1], pose[4], pose[5], wz))


class LeaderMask:
    """The leader flags (n,) of a set of names, made again only when the set changes."""

    def __init__(self, roster):
        self.roster = roster
        self.names = self.mask = None

    def __call__(self, names):
        if names is not self.names:
            self.names, self.mask = names, np.array([nm in names for nm in self.roster])
        return self.mask


def realtime_tick(agents, lock, heard, leader_mask):
    """One realtime tick of the agents of a process (`realtime_core`): each agent not halted
    moves by the sim time that passed since its state, in whole periods dt with u held (ZOH;
    `catch_up`), not by one dt per call: a /clock jump may cover two periods and fire the timer
    once (it catches up), or fire it again at the same time (nothing moves, so no two states
    share a stamp).  The agents that hear perfectly and are fresh in ``heard`` get their u from
    one law call; the others (a radio model) one each.  Then one batched move and one state
    published by each agent that moved.  ``lock``: the agents' `ContainerCore`; ``leader_mask``: a
    `LeaderMask` of the roster."""
    a0 = agents[0]
    now = a0._now()
    moving = due_periods(now, [a.t for a in agents], a0.dt, [a.driver.catch_up_limit for a in agents],
                         [a.halted is not None for a in agents])
    if not moving:
        return
    stale = a0.driver.stale_after
    shared = [j for j, _, _ in moving if not agents[j].radio_on and lock.one_law
              and agents[j].driver.stale_after == stale and now - heard.t[agents[j].index] <= stale]
    us = {}
    if shared:
        mask = leader_mask(a0.leaders)
        u = shared_controls([agents[j].core for j in shared], heard, now, stale, a0.lam, mask,
                            [agents[j].steering for j in shared], a0.target, a0.barrier)
        us.update(zip(shared, u))
    for j, _, _ in moving:
        if j not in us:
            us[j] = agents[j].driver.control(now, heard)
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
