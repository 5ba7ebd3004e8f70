"""The shipped `ros2 bag record` QoS override file (src/swarm_tools/config/record_qos_overrides.yaml)
read as rosbag2 reads it (the reader of the emulation tests/fakes/rosbag2_record.py) and checked
against what the swarm's publishers offer.  The emulated recorder with the file on a run:
tests/tools/bags/ros/test_bag_qos_recorder.py.
"""
from __future__ import annotations

from tests.helpers import ROOT

OVERRIDES = ROOT / 'src' / 'swarm_tools' / 'config' / 'record_qos_overrides.yaml'


def test_overrides_match_what_the_publishers_offer():
    """An override asking for more than the publishers offer would match none of them."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

    from swarm_ros import protocol as P
    from tests.fakes.rosbag2_record import overrides_from_yaml

    got = overrides_from_yaml(OVERRIDES.read_text())
    offered = {P.STATES: P.qos_latched(P.STATES_DEPTH), P.CLOCK: P.qos_reliable(P.STEP_DEPTH)}
    assert set(got) == set(offered)
    for topic, want in got.items():
        have = offered[topic]
        assert want.history == HistoryPolicy.KEEP_LAST and want.depth >= 1000, topic
        assert want.reliability == ReliabilityPolicy.RELIABLE == have.reliability, topic
        assert want.durability == have.durability, topic
    assert got[P.STATES].durability == DurabilityPolicy.TRANSIENT_LOCAL
