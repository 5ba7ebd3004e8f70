"""What the agents of one process share, whether it holds one agent (`agent_node`) or several
(`container_node`): the subscriptions every agent reads alike, the step relay decoded once and
decided for all (lockstep), the sim time from the step messages, and the one
``/lockstep/agent_states`` message per step that carries the agents' new states to the world."""
from __future__ import annotations

from geometry_msgs.msg import PointStamped, PolygonStamped
from nav_msgs.msg import Odometry
from rclpy.time import Time
from std_msgs.msg import Float64, Float64MultiArray, String

from swarm_ros import protocol as P
from swarm_ros.layouts import AgentStates, Step
from swarm_ros.msg_checks import decoded, new_sender_tag

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
        subs.append((Odometry, P.STATES, on_input, P.qos_latched(max(50, 4 * node.n)), False))
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
