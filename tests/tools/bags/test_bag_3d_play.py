"""`swarm play` of a 3D run's bag plays its leaders' (s_u, s_v) steering (the run's
announcement says it is 3D); without the announcement, the steering is the planar type and
the other is not played, said in one line."""
from argparse import Namespace

from swarm_ros.runinfo import run_json


def _bag(path, dim):
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64MultiArray, String

    from swarm_tools.bags.mcap_io import BagWriter, qos_dict
    latched = [qos_dict(history=1, depth=1, reliability=1, durability=1)]
    with BagWriter(path, flush_interval=3600) as w:
        if dim:
            w.add_topic('/swarm/run', 'std_msgs/msg/String', latched)
            w.write('/swarm/run', serialize_message(String(data=run_json('ab12', 's', 'lockstep', ['agent_0'], 1.0,
                                                                         dim=dim))), 1)
        w.add_topic('/agent_0/steering', 'std_msgs/msg/Float64MultiArray', latched)
        w.write('/agent_0/steering', serialize_message(Float64MultiArray(data=[0.0, 0.02])), 2)
    return path


def test_3d_steering_is_played(tmp_path, capsys):
    from swarm_tools.bags.play import _topics_to_play
    topics = _topics_to_play(Namespace(bag=str(_bag(tmp_path / 'b3.mcap', 3)), topics=None))
    assert topics['/agent_0/steering']['type'] == 'std_msgs/msg/Float64MultiArray'
    assert topics['/agent_0/steering']['count'] == 1 and capsys.readouterr().err == ''


def test_without_the_announcement_the_3d_steering_is_refused_in_one_line(tmp_path, capsys):
    from swarm_tools.bags.play import _topics_to_play
    assert _topics_to_play(Namespace(bag=str(_bag(tmp_path / 'b.mcap', None)), topics=None)) is None
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == ("swarm play: /agent_0/steering: not playing 1 messages of type std_msgs/msg/Float64MultiArray "
                      "(the project's /agent_0/steering is std_msgs/msg/Float64)"), err
