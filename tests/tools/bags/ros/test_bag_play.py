"""`swarm play`: a bag republished with its recorded QoS and a /clock from its sim time."""
from __future__ import annotations

import subprocess
import time

STEPS, AGENTS, DT = 30, 3, 0.05


def _bag(path):
    from geometry_msgs.msg import PointStamped
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message

    from swarm_tools.bags.mcap_io import BagWriter, qos_dict

    raws = []
    with BagWriter(path) as w:
        w.add_topic('/world/target', 'geometry_msgs/msg/PointStamped',
                    [qos_dict(history=1, depth=1, reliability=1, durability=1)])
        w.add_topic('/swarm/states', 'nav_msgs/msg/Odometry',
                    [qos_dict(history=1, depth=10, reliability=1, durability=2)])
        t = PointStamped()
        t.point.x, t.point.y = 7.0, -2.0
        w.write('/world/target', serialize_message(t), 10**18)
        for k in range(STEPS):
            for i in range(AGENTS):
                m = Odometry()
                m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(round(k * DT * 1e9)), 10**9)
                m.child_frame_id = f'agent_{i}'
                m.pose.pose.position.x = float(k + 10 * i)
                raw = serialize_message(m)
                raws.append(raw)
                w.write('/swarm/states', raw, 10**18 + 1000 * (k * AGENTS + i + 1))
    return raws


def test_play_republishes_with_clock_and_latching(rclpy_context, processes, swarm_cmd, tmp_path):
    import rclpy
    from geometry_msgs.msg import PointStamped
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    bag = tmp_path / 'play.mcap'
    raws = _bag(bag)
    node = rclpy.create_node('play_probe', context=rclpy_context)
    ex = SingleThreadedExecutor(context=rclpy_context)
    ex.add_node(node)
    states, clocks, targets = [], [], []
    deep = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(Odometry, '/swarm/states', states.append, deep, raw=True)
    node.create_subscription(Clock, '/clock', clocks.append, deep)
    try:
        proc = processes.start([swarm_cmd, 'play', str(bag), '--rate', '1',
                                '--wait-for-subscribers', '20', '--delay', '0.5'],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        t_end = time.monotonic() + 30
        while not states and time.monotonic() < t_end:
            ex.spin_once(timeout_sec=0.05)
        assert states, 'nothing played'
        # a subscriber that joins after the target was published still gets it: latched
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(PointStamped, '/world/target', targets.append, latched)
        while proc.poll() is None and time.monotonic() < t_end:
            ex.spin_once(timeout_sec=0.05)
        for _ in range(20):
            ex.spin_once(timeout_sec=0.02)
        out, err = proc.communicate(timeout=10)
    finally:
        ex.shutdown()
        node.destroy_node()
    assert proc.returncode == 0, err
    assert [bytes(s) for s in states] == raws
    assert len(targets) == 1 and (targets[0].point.x, targets[0].point.y) == (7.0, -2.0)
    ts = [c.clock.sec + c.clock.nanosec * 1e-9 for c in clocks]
    assert len(ts) == STEPS                        # one per sim-time advance
    assert all(b > a for a, b in zip(ts, ts[1:]))
    assert abs(ts[0]) < 1e-9 and abs(ts[-1] - (STEPS - 1) * DT) < 1e-6
    assert f'/swarm/states: {STEPS * AGENTS} messages' in out


def test_play_rejects_bad_arguments(swarm_cmd, tmp_path):
    for args in (['--rate', '0'], ['--rate', '-2'], ['--rate', 'nan']):
        res = subprocess.run([swarm_cmd, 'play', str(tmp_path / 'x.mcap'), *args],
                             capture_output=True, text=True, timeout=60)
        assert res.returncode == 2, (args, res.stderr)
    res = subprocess.run([swarm_cmd, 'play', '--help'], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and '--rate' in res.stdout
