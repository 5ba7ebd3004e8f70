"""The commander node (`homotopy_commander.commander_node`) with an rclpy executor on the
test's own ROS_DOMAIN_ID and rclpy Context (fixtures in tests/conftest.py): bad λ and steering
values rejected, set points taken."""

import numpy as np
import pytest
import rclpy
from std_msgs.msg import Float64

from swarm_core.scenario.loader import load
from swarm_ros.rosutil import make_executor
from tests.helpers import overrides, spin_for


def test_commander_rejects_bad_lambda_and_takes_setpoints(rclpy_context):
    from homotopy_commander.commander_node import CommanderNode
    ctx = rclpy_context
    ex = make_executor(ctx)
    cmd = CommanderNode(context=ctx, parameter_overrides=overrides(dict(scenario='homotopy_global', mode='lockstep')))
    probe = rclpy.create_node('probe', context=ctx)
    lam = probe.create_publisher(Float64, '/swarm/lambda', 10)
    steer = probe.create_publisher(Float64, '/agent_4/steering', 10)
    ex.add_node(cmd)
    ex.add_node(probe)
    assert spin_for(ex, lambda: lam.get_subscription_count() >= 1 and steer.get_subscription_count() >= 1)
    for bad in (float('nan'), 2.0, -1.0, float('-inf')):
        lam.publish(Float64(data=bad))
    steer.publish(Float64(data=float('nan')))
    assert spin_for(ex, lambda: cmd.reject.count >= 5)
    assert len(cmd.reject.lines) == 2                  # one line per kind (λ, steering)
    assert not cmd.pending
    lam.publish(Float64(data=1.0))
    steer.publish(Float64(data=0.02))
    assert spin_for(ex, lambda: len(cmd.pending) == 2)
    scn = load('homotopy_global')
    c, s = np.cos(scn.theta0), np.sin(scn.theta0)
    lam0, flags, steering = cmd.decide(100.0, scn.pos0, c, s)
    assert lam0 == pytest.approx(0.0, abs=1e-4) and flags[4] and steering[4] == 0.02
    lam_mid, _, _ = cmd.decide(110.0, scn.pos0, c, s)          # ramping to 1 over ramp = 20
    lam_end, _, _ = cmd.decide(125.0, scn.pos0, c, s)
    assert 0.2 < lam_mid < 0.8 and lam_end == 1.0
    probe.destroy_node()
