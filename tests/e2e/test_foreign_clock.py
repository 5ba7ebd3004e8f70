"""A peer's ``/clock`` cannot stop or blind a realtime run: the nodes of a run follow its own
clock (``/swarm/clock``: the run id and the world's tag) and read no ``/clock``.  A peer writing
``rosgraph_msgs/Clock`` 1000 s ahead made the world lose every agent (exit 1); one stuck in the
past made the agents refuse their neighbours' states as from the future.  The guard on the run's
own clock: tests/swarm_ros/test_run_clock.py, tests/agent/ros/test_run_clock.py."""
from __future__ import annotations

import json
import subprocess
import time

import pytest
import rclpy
from rosgraph_msgs.msg import Clock

from swarm_ros import protocol as P
from swarm_ros.rosutil import make_executor
from swarm_tools.run.processes import read_events
from tests.helpers import Lines, spin_for

RTF = 2.0


def peer_time(clock: str, since: float) -> float:
    """The peer's /clock: 1000 s ahead of a run started ``since`` (monotonic s), or stuck at 0.5."""
    return 1000.0 + RTF * (time.monotonic() - since) if clock == 'ahead' else 0.5


@pytest.mark.parametrize('clock', ['ahead', 'stuck'])
def test_a_foreign_clock_neither_stops_nor_blinds_a_realtime_run(clock, ros_domain, rclpy_context, processes,
                                                                  swarm_cmd, tmp_path):
    out = tmp_path / 'out'
    p = processes.start([swarm_cmd, 'run', 'global_alignment', '--mode', 'realtime', '--rtf', str(RTF),
                         '--duration', '10', '--out', out, '--no-figure', '--progress-every', '2'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    peer = rclpy.create_node('peer', context=rclpy_context)
    pub = peer.create_publisher(Clock, P.CLOCK, P.qos_reliable(10))
    ex = make_executor(rclpy_context)
    ex.add_node(peer)
    since, readers, run_clock_readers = time.monotonic(), None, 0
    while p.poll() is None and time.monotonic() - since < 150:
        sec, ns = P.time_to_stamp(peer_time(clock, since))
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = sec, ns
        pub.publish(msg)
        spin_for(ex, lambda: False, 0.01)
        if readers is None and any('[world] t=' in ln for ln in lines.lines):     # the run goes
            readers = [f'{r.node_namespace}/{r.node_name}' for r in peer.get_subscriptions_info_by_topic(P.CLOCK)]
        if readers is not None and run_clock_readers < 7:      # the peer's graph may learn of them one by one
            run_clock_readers = len(peer.get_subscriptions_info_by_topic('/swarm/clock'))
    code = lines.wait(p, 60)
    text = ''.join(lines.lines)
    assert code == 0, text[-4000:]
    assert 'from the future' not in text and 'rejected' not in text, text[-4000:]
    assert '[world]: another writer of /clock: /peer; the nodes of this run do not read it' in text, text[-4000:]
    assert not [e for e in read_events(out / 'events.jsonl') if e['kind'] == 'lost']
    assert json.loads((out / 'metrics.json').read_text())['summary']['t_end'] == pytest.approx(10.0, abs=0.2)
    assert readers == [], f'nodes of the run read /clock: {readers}'
    assert run_clock_readers == 7, run_clock_readers               # six agent processes, the commander
