"""The commander node (`homotopy_commander.commander_node`) with an rclpy executor on the
test's own ROS_DOMAIN_ID and rclpy Context (fixtures in tests/conftest.py): bad λ and steering
values rejected, set points taken and, in lockstep, forwarded to the world."""

import numpy as np
import pytest
import rclpy
from std_msgs.msg import Float64, String

from swarm_core.scenario.loader import load
from swarm_ros import protocol as P
from swarm_ros.rosutil import make_executor
from swarm_ros.run_control import forwarded
from tests.helpers import overrides, spin_for


def test_commander_rejects_bad_lambda_and_forwards_setpoints(rclpy_context):
    from homotopy_commander.commander_node import CommanderNode
    ctx = rclpy_context
    ex = make_executor(ctx)
    cmd = CommanderNode(context=ctx, parameter_overrides=overrides(dict(scenario='homotopy_global', mode='lockstep')))
    probe = rclpy.create_node('probe', context=ctx)
    lam = probe.create_publisher(Float64, '/swarm/lambda', 10)
    steer = probe.create_publisher(Float64, '/agent_4/steering', 10)
    got = []
    probe.create_subscription(String, P.LOCK_COMMAND, lambda m: got.append(forwarded(m.data, '')), P.qos_latched(100))
    ex.add_node(cmd)
    ex.add_node(probe)
    assert spin_for(ex, lambda: lam.get_subscription_count() >= 1 and steer.get_subscription_count() >= 1)
    assert spin_for(ex, lambda: [m['kind'] for m in got] == ['ready'])       # it takes part at once
    for bad in (float('nan'), 2.0, -1.0, float('-inf')):
        lam.publish(Float64(data=bad))
    steer.publish(Float64(data=float('nan')))
    assert spin_for(ex, lambda: cmd.reject.count >= 5)
    assert len(cmd.reject.lines) == 2                  # one line per kind (λ, steering)
    assert len(got) == 1                               # nothing bad was forwarded
    lam.publish(Float64(data=1.0))
    steer.publish(Float64(data=0.02))
    assert spin_for(ex, lambda: len(got) == 3)
    assert [m['seq'] for m in got] == [1, 2, 3] and len({m['tag'] for m in got}) == 1
    commands = [m['command'] for m in got[1:]]
    assert [(c['command'], c['value']) for c in commands] == [('lambda', 1.0), ('steer', 0.02)]
    # what the world's plan then does with them at its next step
    scn = load('homotopy_global')
    plan = scn.command_plan()
    c, s = np.cos(scn.theta0), np.sin(scn.theta0)
    d0 = plan.decide(100.0, scn.pos0, c, s, commands=commands)
    assert d0.lam == pytest.approx(0.0, abs=1e-4) and d0.flags[4] and d0.steering[4] == 0.02
    lam_mid = plan.decide(110.0, scn.pos0, c, s).lam          # ramping to 1 over ramp = 20
    lam_end = plan.decide(125.0, scn.pos0, c, s).lam
    assert 0.2 < lam_mid < 0.8 and lam_end == 1.0
    probe.destroy_node()
