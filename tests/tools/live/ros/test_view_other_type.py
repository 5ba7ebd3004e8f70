"""The live view (`swarm_tools.live.view.Bridge`, without its WebSocket server) next to a peer
that writes another type on a run's topic: the view serves the topic's own type, and a
message it cannot serve is counted, not the end of the view."""
from __future__ import annotations

import time
from types import SimpleNamespace


def _until(cond, timeout, step=None):
    end = time.monotonic() + timeout
    while not cond() and time.monotonic() < end:
        if step is not None:
            step()
        time.sleep(0.05)
    return cond()


def test_the_view_serves_a_topics_own_type_next_to_a_writer_of_another(rclpy_context, ros_domain):
    """A peer's std_msgs/String writer on /swarm/states is there before the run's: the view
    used to advertise /swarm/states as String (its first writer's type) and so never serve
    the run's states.  Now it advertises nav_msgs/msg/Odometry, reads the run's writer, and a
    message that makes its callback fail is counted."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from std_msgs.msg import String

    from swarm_ros import protocol as P
    from swarm_ros.rosutil import make_executor
    from swarm_tools.live.view import Bridge
    from tests.helpers import odom_cdr

    ctx2 = Context()
    rclpy.init(context=ctx2, domain_id=ros_domain)       # a participant of its own: another type
    peer = rclpy.create_node('peer', context=ctx2)
    peer.create_publisher(String, P.STATES, P.qos_latched(10)).publish(String(data='not yours'))
    node = rclpy.create_node('swarm_view', context=rclpy_context)
    server = SimpleNamespace(port=0, stop=lambda: None, broadcast_time=lambda t: None,
                             publish_status=lambda *a: None)
    said = []
    bridge = Bridge(node, lambda listener: server, log=said.append)
    ex = make_executor(rclpy_context)
    ex.add_node(node)
    try:
        assert _until(lambda: node.count_publishers(P.STATES) >= 1, 20)
        bridge.poll()
        assert bridge.types[P.STATES] == 'nav_msgs/msg/Odometry'
        run = node.create_publisher(Odometry, P.STATES, P.qos_latched(10))      # the run's agent
        logged = []

        def log(data, log_time):          # the channel's sink: the second state makes it fail
            logged.append(log_time)
            assert len(logged) == 1
        bridge.channels[P.STATES] = SimpleNamespace(log=log, has_sinks=lambda: True)
        bridge.work.put(('subscribe', P.STATES))
        bridge.step()
        assert P.STATES in bridge.subs
        assert _until(lambda: run.get_subscription_count() >= 1, 20)
        run.publish(odom_cdr('agent_0', 2_500_000_000, 1.0, 2.0, 0.0, 1.0, 0.0))
        run.publish(odom_cdr('agent_0', 3_000_000_000, 1.0, 2.0, 0.0, 1.0, 0.0))
        assert _until(lambda: bridge.reject.count, 20, lambda: ex.spin_once(timeout_sec=0.05))
        assert logged[0] == 2_500_000_000
        assert f'unreadable:{P.STATES}' in bridge.reject.kinds, said
    finally:
        bridge.close()
        node.destroy_node()
        peer.destroy_node()
        rclpy.try_shutdown(context=ctx2)
