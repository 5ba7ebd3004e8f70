"""The commander of a swarm bigger than one slice of its watch (docs/commands.md).

With 200 agents the commander looks at 64 steering topics per tick (``CommandWatch``), all of
them only for a while after a new node appeared.  ``ros2 topic pub --once`` (the faithful
emulation of the Jazzy tool in ``tests/fakes/emulate_topic_pub.py``, its own DDS participant) still takes
effect on the first try, on λ and on steering topics of agents far apart in the round robin.
"""
import sys
import threading

from tests.fakes.emulate_topic_pub import main as topic_pub_once
from tests.helpers import ROOT, spin_for


def test_topic_pub_once_reaches_a_200_agent_commander(tmp_path, rclpy_context):
    """Six tries (λ, then steering of agents 199, 0, 137, 64, 5) against a lockstep
    CommanderNode of 200 agents alone (no world: each command waits in ``pending`` for the
    next step).  Each try's command is queued once, with the try's value.  Then the tool's
    writers are gone and the commander dropped every command reader."""
    from rclpy.context import Context
    from rclpy.parameter import Parameter

    from homotopy_commander.commander_node import CommanderNode
    from swarm_ros.rosutil import make_executor
    sys.path.insert(0, str(ROOT / 'scripts'))
    from bench_ros import scenario_file

    path = scenario_file(200, 10, tmp_path)
    cmd = CommanderNode(context=rclpy_context, parameter_overrides=[Parameter('scenario', value=str(path))])
    assert cmd.watch.period() == 50                     # 200 topics, 4 a tick in turn
    ex = make_executor(rclpy_context, events=False)
    ex.add_node(cmd)
    tries = [('/swarm/lambda', None, 0.5)] + [(f'/agent_{i}/steering', f'agent_{i}', 0.001 * (k + 1))
                                              for k, i in enumerate([199, 0, 137, 64, 5])]
    try:
        for topic, agent, value in tries:
            n = len(cmd.taken)
            t = threading.Thread(target=topic_pub_once, args=([topic, 'std_msgs/msg/Float64', f'{{data: {value}}}'],),
                                 kwargs={'context': Context()})
            t.start()
            assert spin_for(ex, lambda t=t: not t.is_alive(), 120), topic
            assert spin_for(ex, lambda n=n: len(cmd.taken) > n, 30), topic
            got = list(cmd.taken)[n:]
            assert len(got) == 1 and got[0]['value'] == value, (topic, got)
            if agent is not None:
                assert got[0]['command'] == 'steer' and got[0]['agent'] == cmd.row[agent]
            else:
                assert got[0]['command'] == 'lambda'
        # the tools are gone: their readers are dropped (topics with a reader are looked at every tick)
        assert spin_for(ex, lambda: not cmd.reading and all(c.sub is None for c in cmd.commands.values()), 60)
    finally:
        ex.shutdown()
        cmd.destroy_node()
