"""A lone agent started by hand (``swarm_agent --ros-args ... -p mode:=realtime``, no
use_sim_time: its clock is the system clock, ≈1.8e9 s) starts from that clock (its time starts at
the first reading, one line says so; before, its first tick owed billions of periods in one
callback and the process spun at 100 % ignoring SIGINT and SIGTERM), and stops within 1 s of
SIGINT and of SIGTERM, also while a callback runs on (`swarm_ros.rosutil.ExitWatch`).  A
realtime agent whose sim clock is far ahead at its first tick restarts its time there
(`realtime_core.CATCH_UP_MAX`)."""
from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from tests.helpers import Lines

#: a node must be gone this long after SIGINT / SIGTERM, whatever its callbacks do
STOP_WITHIN = 1.0
LONE = ['--ros-args', '-r', '__ns:=/agent_0', '-r', '__node:=agent', '-p', 'agent_names:=[agent_0]',
        '-p', 'mode:=realtime']


def _exit_time(proc, sig, lines):
    """Send ``sig``; wall s until the process has exited (fails with its output after 10 s)."""
    t0 = time.monotonic()
    proc.send_signal(sig)
    with contextlib.suppress(subprocess.TimeoutExpired):     # then `Lines.wait` fails with its output
        proc.wait(timeout=10)
    took = time.monotonic() - t0
    lines.wait(proc, 1)                 # and every line it wrote is in ``lines``
    return took


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_lone_agent_on_the_system_clock_runs_and_stops_within_a_second(sig, ros_domain, processes, rclpy_context):
    """It says in one line that its time starts at the clock's first reading, publishes states
    stamped on the system clock, one per control period, and exits within 1 s of the signal."""
    import rclpy
    from nav_msgs.msg import Odometry

    from swarm_ros import protocol as P
    from swarm_ros.rosutil import make_executor
    from tests.helpers import spin_for

    proc = processes.start([Path(sys.executable).parent / 'swarm_agent', *LONE],     # as `ros2 run` starts it
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(proc)
    assert lines.wait_for("this agent's time starts there", 60), ''.join(lines.lines)
    node = rclpy.create_node('probe', context=rclpy_context)
    stamps = []
    node.create_subscription(Odometry, P.STATES, lambda m: stamps.append(
        m.header.stamp.sec + m.header.stamp.nanosec * 1e-9), P.qos_latched(100))
    ex = make_executor(rclpy_context)
    ex.add_node(node)
    assert spin_for(ex, lambda: len(stamps) >= 8, 30), (stamps, ''.join(lines.lines))
    assert proc.poll() is None
    now = time.time()
    assert abs(stamps[-1] - now) < 5.0                     # its time is the system clock's
    steps = [b - a for a, b in zip(stamps[1:], stamps[2:])]
    assert all(0.0 < s < 1.0 for s in steps), steps        # period by period (dt 0.05), no leap
    took = _exit_time(proc, sig, lines)
    assert took < STOP_WITHIN, (took, ''.join(lines.lines))
    starts = [ln for ln in lines.lines if 'time starts there' in ln]
    assert len(starts) == 1 and 'use_sim_time is False' in starts[0]
    assert not any('Traceback' in ln for ln in lines.lines), ''.join(lines.lines)
    node.destroy_node()


#: the agent executable with its realtime tick made slow on purpose: the first tick that moves
#: the agent busy-loops for a minute (as billions of periods of catch-up did), after a marker
SLOW_TICK = textwrap.dedent('''
    import sys, time
    import swarm_agent.process_io as io

    def slow(*args):
        print('SLOW TICK', flush=True)
        end = time.monotonic() + 60
        while time.monotonic() < end:
            pass
    io.advance_periods = slow
    from swarm_agent.agent_node import main
    sys.exit(main(sys.argv))
''')


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_lone_agent_stops_within_a_second_in_the_middle_of_a_long_callback(sig, tmp_path, ros_domain, processes):
    """A callback that would run for a minute: the signal's watch ends the process within 1 s
    of the signal with one line saying a callback still ran, exit 128 + signal."""
    script = tmp_path / 'slow_agent.py'
    script.write_text(SLOW_TICK)
    proc = processes.start([sys.executable, script, *LONE], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
    lines = Lines(proc)
    assert lines.wait_for('SLOW TICK', 60), ''.join(lines.lines)
    time.sleep(0.2)                                        # well inside the callback
    took = _exit_time(proc, sig, lines)
    assert took < STOP_WITHIN, (took, ''.join(lines.lines))
    assert proc.returncode == 128 + sig, ''.join(lines.lines)
    said = [ln for ln in lines.lines if 'a callback still runs' in ln]
    assert len(said) == 1 and signal.Signals(sig).name in said[0], ''.join(lines.lines)


def test_a_realtime_agent_that_joins_a_clock_far_ahead_restarts_its_time_there(rclpy_context):
    """The sim clock already at 1000 s when the agent first ticks (a run it joined late): its
    time restarts there without a move (it owed 20,000 periods in one callback), and the next
    period moves it one."""
    import numpy as np
    import rclpy
    from rosgraph_msgs.msg import Clock

    from swarm_agent.agent_node import AgentNode
    from swarm_core.scenario.loader import load
    from swarm_ros import protocol as P
    from swarm_ros.rosutil import make_executor
    from swarm_tools.run.params import agent_parameters
    from tests.helpers import overrides, spin_for

    scn = load('homotopy_global')
    agent = AgentNode('agent', namespace='agent_1', context=rclpy_context,
                      parameter_overrides=overrides(agent_parameters(scn, 1, 'realtime')))
    probe = rclpy.create_node('probe', context=rclpy_context)
    clock = probe.create_publisher(Clock, '/clock', 10)
    ex = make_executor(rclpy_context)
    for nd in (agent, probe):
        ex.add_node(nd)
    assert spin_for(ex, lambda: clock.get_subscription_count() > 0)

    def at(t):
        c = Clock()
        c.clock.sec, c.clock.nanosec = P.time_to_stamp(t)
        clock.publish(c)
        spin_for(ex, lambda: False, 0.3)

    start = agent.core.pos.copy()
    t0 = time.monotonic()
    at(1000.0)
    assert time.monotonic() - t0 < 5.0
    assert agent.t == pytest.approx(1000.0, abs=scn.dt) and agent.step == 0
    assert np.array_equal(agent.core.pos, start)                  # no move for the time it never had
    at(agent.t + scn.dt)
    assert agent.step == 1 and agent.t == pytest.approx(1000.0, abs=2 * scn.dt)
    probe.destroy_node()
    agent.destroy_node()
