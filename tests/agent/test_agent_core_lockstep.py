"""Pure-python check (no DDS) of the lockstep claim: one `AgentCore` per agent, each with a
table of the states it received (positions and quaternions as they would travel in
nav_msgs/Odometry), reproduces `swarm_core.engine.reference.simulate` bit for bit."""
import numpy as np
import pytest

from swarm_agent.agent_core import AgentCore
from swarm_core.engine.reference import simulate
from swarm_core.scenario.loader import load


@pytest.mark.parametrize('name,duration', [('homotopy_global', 40.0), ('target_barrier', 20.0)])
def test_agents_reproduce_batch_engine(name, duration):
    scn = load(name, duration=duration)
    if name == 'homotopy_global':
        # bring the leader choice and the λ ramp into the short run
        scn = load(name, duration=duration)
        scn.spec.leaders.at = 5.0
        scn.spec.lambda_.rise_at, scn.spec.lambda_.fall_at, scn.spec.lambda_.tau = 10.0, 30.0, 3.0
    ref = simulate(scn)
    n = len(scn.names)
    agents = [AgentCore(i, n, *scn.pos0[i], scn.theta0[i], scn.law, scn.dt) for i in range(n)]
    plan = scn.command_plan()
    for step in range(scn.steps + 1):
        t = step * scn.dt
        x = np.array([a.pos[0, 0] for a in agents])
        y = np.array([a.pos[0, 1] for a in agents])
        q = np.array([a.quaternion for a in agents])
        from swarm_core.model.frenet import frame_from_quaternion
        c, s = frame_from_quaternion(q[:, 0], q[:, 1])
        lam, leaders, steering = plan.update(t, np.stack([x, y], 1), c, s)
        flags = np.zeros(n, bool)
        flags[leaders] = True
        us = [a.control(x, y, q[:, 0], q[:, 1], lam, flags, steering[i], scn.target, scn.barrier)
              for i, a in enumerate(agents)]
        assert np.array_equal(np.stack([x, y], 1), ref.r[step])
        assert np.array_equal(np.array(us), ref.u[step])
        assert lam == ref.lam[step]
        for a, u in zip(agents, us):
            a.advance(u)
    if name == 'homotopy_global':
        assert ref.leader.any() and ref.lam.max() > 0.9    # the short run exercised leaders and λ
