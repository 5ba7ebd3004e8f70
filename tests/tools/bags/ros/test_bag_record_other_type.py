"""A writer of another type on the recorded topics of a run (a stray or hostile peer on the
domain): the recorder keeps each topic's own type and writers, records the run whole, and
says what it did not record."""
from __future__ import annotations

import subprocess

import pytest

from tests.helpers import Lines, two_agents

#: the run's topics the peer writes std_msgs/String on: presubscribed ones and one found later
HIJACKED = ('/swarm/states', '/clock', '/world/metrics', '/lockstep/step')


@pytest.mark.refuses_inputs      # a peer writes other types on the recorded topics
def test_a_writer_of_another_type_on_recorded_topics_loses_nothing(rclpy_context, processes, swarm_cmd, tmp_path):
    """A peer writes std_msgs/String on /swarm/states, /clock, /world/metrics and
    /lockstep/step before the run starts.  The recorder used to re-subscribe those topics with
    the peer's type: the bag held the peer's strings instead of the run's states, the agents
    and the world waited 30 s each for a recorder that never matched them, and the run still
    exited 0.  Now each topic keeps its own type: the run exits 0 at once, the bag is whole
    (every state of both agents), and the recorder names each writer it did not record."""
    import rclpy
    from std_msgs.msg import String

    from swarm_ros import protocol as P
    from swarm_tools.bags.mcap_io import bag_complete, bag_topics
    from swarm_tools.bags.record import swarm_type

    peer = rclpy.create_node('peer', context=rclpy_context)      # the test's participant: types of its own
    pubs = [peer.create_publisher(String, topic, P.qos_latched(10)) for topic in HIJACKED]
    for p in pubs:
        p.publish(String(data='not yours'))
    two_agents(tmp_path / 'two.yaml', 5)
    bag = tmp_path / 'run.mcap'
    proc = processes.start([swarm_cmd, 'run', tmp_path / 'two.yaml', '--record', bag, '--out', tmp_path / 'out',
                            '--no-figure', '--start-timeout', '25'],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(proc)
    code = lines.wait(proc, 90)
    lines.t.join(10)
    out = ''.join(lines.lines)
    peer.destroy_node()
    assert code == 0, out
    assert 'readers matched after' not in out and 'starting anyway' not in out, out    # no 30 s waits
    for topic in HIJACKED:
        assert (f'{topic}: 1 writer(s) of another type (std_msgs/msg/String) not recorded; '
                f'{swarm_type(topic)} recorded') in out, out
    assert bag_complete(bag)
    topics = bag_topics(bag, swarm_type)
    steps = 5 / 0.05 + 1
    assert topics['/swarm/states']['type'] == 'nav_msgs/msg/Odometry'
    assert topics['/swarm/states']['count'] >= 2 * steps and not topics['/swarm/states']['other'], topics
    # /lockstep/step is not presubscribed: recorded from when the recorder finds it (its writer
    # keeps one message, the critical path: 80 to 101 of 101 steps here), in the run's own type
    assert topics['/lockstep/step']['count'] >= 1 and not topics['/lockstep/step']['other'], topics
    assert topics['/clock']['count'] >= steps and not topics['/clock']['other']
    assert (tmp_path / 'out' / 'trajectory.npz').exists()
