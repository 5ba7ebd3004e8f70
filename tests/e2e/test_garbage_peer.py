"""No message ends a node: a peer on the domain writes garbage on every topic a lockstep run
reads (bytes that are no message, values no node can take, JSON bombs, writers of another
type), and every node goes on; the run finishes with the batch engine's result, and each node
counts what it refused."""
from __future__ import annotations

import contextlib
import math

import numpy as np
import rclpy
from geometry_msgs.msg import Point32, PointStamped, PolygonStamped
from rclpy.context import Context
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String

from swarm_core.engine.reference import simulate
from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.layouts import Step
from swarm_ros.rosutil import make_executor
from swarm_tools.run.launch import build_nodes
from swarm_tools.run.params import node_parameters
from tests.helpers import short_homotopy, spin_for

RUN = 'c0ffee01'

#: bytes that are no Float64MultiArray: too short, a length past the end, a count of 2^32 − 1
NOT_MESSAGES = (b'', b'\x00\x01\x00\x00\x05', b'\x00\x01\x00\x00\x00\x00\x00\x00\xff\xff\xff\xff',
                b'\x00\x01\x00\x00' + b'\xff' * 64)
#: texts no reader of /swarm/events, /swarm/fault_request, /swarm/run or /lockstep/command can take
TEXTS = ('[' * 100_000, '{"kind": "leaders_chosen", "slots": [[1]], "run_id": "%s"}' % RUN,
         '{"kind": ["kill"], "agent": {}}', '{"kind": "freeze", "agent": "agent_1", "for": "x"}',
         '{"run_id": 5}', 'x' * 2_000_000, 'NaN')


class Peer:
    """The garbage writers: the test's participant (the run's own types) and a second
    participant for writers of another type (one participant refuses two types on a topic)."""

    #: the packed topics each mode's nodes read raw
    PACKED = {'lockstep': (P.LOCK_STEP, P.LOCK_AGENT_STATES), 'realtime': (P.AGENT_STATES, P.DECISION, P.RUN_CLOCK)}

    def __init__(self, ctx, domain, n, mode):
        self.n = n
        # /clock readers in the run: none (lockstep: the agents and the commander take their time
        # from the step messages; realtime: from the run's clock, /swarm/clock)
        self.clock_readers = 0
        self.node = rclpy.create_node('peer', context=ctx)
        self.ctx2 = Context()
        rclpy.init(context=self.ctx2, domain_id=domain)
        self.other = rclpy.create_node('peer_other_type', context=self.ctx2)
        lat = P.qos_latched(10)
        self.arrays = {t: self.node.create_publisher(Float64MultiArray, t, lat) for t in self.PACKED[mode]}
        self.setpoint = self.node.create_publisher(Float64MultiArray, P.LAMBDA_SETPOINT, P.qos_reliable(10))
        self.clock = self.node.create_publisher(Clock, P.CLOCK, P.qos_reliable(10))
        self.texts = [self.node.create_publisher(String, t, lat)
                      for t in (P.EVENTS, P.FAULT_REQUEST, P.RUN, P.LOCK_COMMAND)]
        self.target = self.node.create_publisher(PointStamped, P.TARGET, P.qos_latched())
        self.barrier = self.node.create_publisher(PolygonStamped, P.BARRIER, P.qos_latched())
        self.wrong = [self.other.create_publisher(String, t, lat) for t in (P.LOCK_STEP, P.CLOCK, P.STATES)]

    def matched(self, agents):
        return (next(iter(self.arrays.values())).get_subscription_count() >= agents     # the agents' input
                and self.clock.get_subscription_count() >= self.clock_readers
                and self.setpoint.get_subscription_count() >= 1)

    def write(self, k):
        """Round ``k`` of garbage on every topic: one message on each packed topic (its readers
        keep only the newest), every other round a step of the run (its id, as any peer reads
        it on /swarm/run) at t = NaN (lockstep: an agent takes it), else bytes that are no message."""
        n = self.n
        step = Step(0, math.nan, 0.0, np.zeros(n, bool), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n),
                    np.ones(n), np.zeros(n), np.ones(n, bool), None, None, None).to_cdr(RUN)
        for pub in self.arrays.values():
            pub.publish(step if k % 2 == 0 else NOT_MESSAGES[k // 2 % len(NOT_MESSAGES)])
        for data in ([math.nan], [0.5] * 1000, [0.5, -1.0]):
            self.setpoint.publish(Float64MultiArray(data=data))
        before = Clock()
        before.clock.sec = -5                      # rclpy's /clock reader raised on it
        self.clock.publish(before)
        for pub in self.texts:
            for text in TEXTS:
                pub.publish(String(data=text))
        pt = PointStamped()
        pt.point.x = math.inf
        self.target.publish(pt)
        poly = PolygonStamped()
        poly.polygon.points = [Point32(x=float(i), y=math.nan) for i in range(2000)]
        self.barrier.publish(poly)
        for pub in self.wrong:
            pub.publish(String(data='not yours'))

    def close(self):
        self.node.destroy_node()
        self.other.destroy_node()
        rclpy.try_shutdown(context=self.ctx2)


@contextlib.contextmanager
def run_beside_a_peer(tmp_path, ctx, domain, mode, duration, rounds, pause, **extra):
    """World, commander and six agents of run `RUN` in one executor (``mode``, ``duration`` s),
    started, while a `Peer` writes up to ``rounds`` rounds of garbage ``pause`` s apart; yields
    (scenario, executor, world, commander, agents, rounds written).  Nodes and peer are closed
    after, also when the test fails."""
    path = short_homotopy(tmp_path / 'g.yaml', duration=duration, lam='{kind: constant, value: 0.0}', at=100.0)
    scn = load(str(path))
    params = node_parameters(scn, str(path), mode, **extra)
    for p in params.values():
        p['run_id'] = RUN
    peer = Peer(ctx, domain, len(scn.names), mode)
    world, commander, agents = build_nodes(params, ctx, log=lambda *a, **k: None)
    ex = make_executor(ctx)
    nodes = [world, commander, *agents]
    try:
        for nd in nodes:
            ex.add_node(nd)
        assert spin_for(ex, lambda: peer.matched(len(agents)), 30.0)
        assert spin_for(ex, lambda: world.started, 60.0)
        written = 0
        while not world.done and written < rounds:        # a round now and then, mid-run
            peer.write(written)
            written += 1
            spin_for(ex, lambda: world.done, pause)
        yield scn, ex, world, commander, agents, written
    finally:
        for nd in nodes:
            nd.destroy_node()
        peer.close()


def test_garbage_on_every_topic_of_a_lockstep_run_ends_no_node(tmp_path, rclpy_context, ros_domain):
    """A lockstep run (world, commander, six agents in one executor) while a peer writes
    garbage on its topics a few times mid-run.  A /lockstep/step of the run at t = NaN used to
    end every agent (in setting its clock); the agents and the commander refuse it now (they
    take their time from the steps; no node of a lockstep run reads /clock, the realtime test
    below covers it).  Every message any node cannot read is counted and logged once: the run
    finishes equal to `simulate`, and each node's count says what it refused."""
    # 30 s (600 steps): at 8 s a clean clone's run ended after the peer's third round (all eight
    # rounds take about 370 steps here)
    with run_beside_a_peer(tmp_path, rclpy_context, ros_domain, 'lockstep', 30.0, 8, 0.2,
                           extra_world=dict(stall_timeout=0.3)) as (scn, ex, world, commander, agents, rounds):
        assert rounds >= 4, 'the run ended before the peer wrote four rounds'
        assert spin_for(ex, lambda: world.done, 60.0)
        assert world.failed is None
        got, ref = world.trajectory(), simulate(scn)
        assert np.abs(got.r - ref.r).max() <= 1e-9 and np.abs(got.u - ref.u).max() <= 1e-9
        kinds = {k for a in agents for k in a.reject.kinds}      # a newer step may replace one in a reader
        assert {'step-time', 'step-decode', 'target', 'barrier-size'} <= kinds, [a.reject.lines for a in agents]
        assert {'step-time', 'step-decode', 'setpoint'} <= set(commander.reject.kinds), \
            commander.reject.lines
        assert 'state-decode' in world.reject.kinds, world.reject.lines
        for nd in (world, commander, *agents):
            # one line per kind, one more per kind per 10 s of rejections
            assert len(nd.reject.lines) <= 2 * len(nd.reject.kinds), (nd.get_name(), nd.reject.lines)


def test_garbage_on_every_topic_of_a_realtime_run_ends_no_node(tmp_path, rclpy_context, ros_domain):
    """The same peer next to a realtime run: a /clock before 0 used to end every node that
    followed the sim clock (agents, commander; they follow the run's /swarm/clock now, and
    refuse garbage there), an event of the run naming a leader slot by a
    list the world.  Every node goes on to the end, no state is NaN, and the counts say what
    each refused."""
    with run_beside_a_peer(tmp_path, rclpy_context, ros_domain, 'realtime', 5.0, 4, 0.1,
                           rtf=5.0) as (scn, ex, world, commander, agents, rounds):
        assert rounds >= 2, 'the run ended before the peer wrote twice'
        assert spin_for(ex, lambda: world.done, 60.0)
        assert world.failed is None
        tr = world.trajectory()
        assert np.isfinite(tr.r[-1]).all() and np.isfinite(tr.theta[-1]).all()
        for a in agents:
            assert np.isfinite(a.core.pos).all() and a.target is None
            assert 'clock' in a.reject.kinds, a.reject.lines
        assert 'clock' in commander.reject.kinds, commander.reject.lines
        assert {f'unreadable:{P.EVENTS}', 'state-decode'} <= set(world.reject.kinds), world.reject.lines
        for nd in (world, commander, *agents):
            assert len(nd.reject.lines) <= 2 * len(nd.reject.kinds), (nd.get_name(), nd.reject.lines)
