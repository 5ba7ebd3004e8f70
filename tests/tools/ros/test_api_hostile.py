"""The Python API (swarm_tools.api.Swarm) against a careless or hostile domain: a second
`Swarm.start` where a run is already going fails at once, naming that run, and leaves the
first one's client as it was; garbage on /swarm/states is counted and dropped, and the client's
reader goes on.  The API's checks without a run: tests/tools/test_api_inputs.py."""
from __future__ import annotations

import math
import struct
import time

import pytest

from tests.helpers import ROOT, odom_cdr

SCENARIO = ROOT / 'examples' / 'six_agents_live.yaml'


def test_a_second_start_on_a_busy_domain_fails_and_the_first_run_goes_on(swarm, ros_domain, tmp_path):
    from swarm_tools.api import Swarm, SwarmError
    # realtime at rtf 4: what is checked does not need lockstep, which would spin a core meanwhile
    first = swarm(SCENARIO, mode='realtime', rtf=4, duration=4000, in_process=True, no_figure=True)
    runs, t0 = first.client.runs, first.wait_until(lambda m: m['t'] >= 1, timeout=10)['t']
    started = time.monotonic()
    with pytest.raises(SwarmError, match=rf'ROS_DOMAIN_ID={ros_domain} \(run {first.run_id} ') as err:
        # busy_wait 20 s, not the default 4: under the suite's load, discovering the first run
        # took more than 4 s once (the wait ends as soon as its announcement is heard)
        Swarm.start(SCENARIO, mode='realtime', rtf=4, duration=4000, in_process=True, no_figure=True,
                    out=tmp_path / 'second', busy_wait=20.0)
    assert 'refusing to start one more' in str(err.value) and time.monotonic() - started < 30
    assert not (tmp_path / 'second').exists()                    # nothing of it was started
    # the first run's client heard nothing of a second one: its commands still reach its run
    time.sleep(2.0)
    assert first.client.runs == runs and list(runs) == [first.run_id]
    first.set_lambda(1.0, ramp=0)
    assert first.wait_until(lambda m: m['lambda'] == 1.0, timeout=20)['t'] > t0
    assert first.running


def test_garbage_on_swarm_states_is_counted_and_the_reader_goes_on(rclpy_context):
    """Malformed /swarm/states messages (cut, a name longer than the message, NaN, a pose that
    is not planar, an agent not in the run): each counted and dropped; a good state after them
    is still read, so the client's thread lives."""
    import rclpy
    from nav_msgs.msg import Odometry

    from swarm_ros import protocol as P
    from swarm_tools.api import Client, Swarm
    good = odom_cdr('agent_0', 2_000_000_000, 1.0, 2.0, 0.0, 1.0, 0.01)
    cut = good[:30]
    long_name = good[:24] + struct.pack('<I', 1 << 30) + good[28:]    # child_frame_id past the end
    nan = odom_cdr('agent_0', 1_000_000_000, math.nan, 0.0, 0.0, 1.0, 0.0)
    tilted = odom_cdr('agent_0', 1_000_000_000, 0.0, 0.0, 0.6, 0.6, 0.0)
    stranger = odom_cdr('agent_9', 1_000_000_000, 0.0, 0.0, 0.0, 1.0, 0.0)
    client = Client(None, name='swarm_api')
    try:
        swarm = Swarm(client, {'run_id': 'r1', 'agents': ['agent_0', 'agent_1']})
        node = rclpy.create_node('peer', context=rclpy_context)
        pub = node.create_publisher(Odometry, P.STATES, P.qos_latched(P.STATES_DEPTH))
        end = time.monotonic() + 10
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.05)
        for raw in (b'', b'\x00\x01', cut, long_name, nan, tilted, stranger):
            pub.publish(raw)
        pub.publish(good)
        end = time.monotonic() + 10
        while swarm.states() is None and time.monotonic() < end:
            time.sleep(0.05)
        states = swarm.states()
        assert states is not None and states.names == ['agent_0'] and states.x.tolist() == [1.0]
        assert client._thread.is_alive()
        assert client.reject.count >= 6, client.reject.summary()
        node.destroy_node()
    finally:
        client.close()
