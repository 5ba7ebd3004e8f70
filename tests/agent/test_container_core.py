"""Agent containers without DDS (`swarm_agent.container_core`): K agents of one process, driven
by the step messages the world would send, reproduce `swarm_core.engine.reference.simulate` bit for bit
(one law call per container and step), with faults; the ``auto`` rule; the grouping."""
from types import SimpleNamespace

import numpy as np
import pytest

from swarm_agent.agent_core import AgentCore
from swarm_agent.container_core import (
    CONTAINER_SIZE,
    PROCESSES_PER_CORE,
    ContainerCore,
    agents_per_process,
    split_agents,
)
from swarm_core.engine.reference import simulate
from swarm_core.scenario.loader import load
from tests.helpers import short_homotopy


def drive(scn, groups, compiled=False, silent_at_least=2):
    """Run the agents as containers (``groups``: agent indices per process) on the batch
    engine's own step inputs (what the world relays: λ, leaders, s_k, who is in the table),
    checking u and positions against the engine step by step; returns the agent-steps moved.
    ``compiled``: both sum pairs in the compiled kernels (a run's ``--compiled on``)."""
    from swarm_core.engine.reference import SwarmStepper
    from swarm_core.model.frenet import quaternion_from_heading
    eng = SwarmStepper(scn, neighbour_search='compiled' if compiled else 'auto')
    n = len(scn.names)
    cores = [AgentCore(i, n, *scn.pos0[i], scn.theta0[i], scn.law, scn.dt,
                       (scn.spec.noise.position, scn.spec.noise.heading), scn.noise_rng(i)) for i in range(n)]
    for c in cores if compiled else ():
        c.sums_compiled()
    boxes = [ContainerCore([cores[i] for i in g]) for g in groups]
    x, y = scn.pos0[:, 0].copy(), scn.pos0[:, 1].copy()
    qz, qw = quaternion_from_heading(scn.theta0)
    moved = silent = in_table = 0
    for step in range(scn.steps):
        t, lam, is_leader, steering, frame = eng.inputs()
        alive = eng.faults.alive.copy()
        in_table += int(alive.sum())
        s = SimpleNamespace(n=step, t=t, lam=lam, flags=is_leader, steering=np.asarray(steering, float),
                            x=x.copy(), y=y.copy(), qz=qz.copy(), qw=qw.copy(), u=np.zeros(n), alive=alive,
                            target=scn.target, barrier=scn.barrier, rendezvous=eng.plan.rendezvous_now)
        u = np.full(n, np.nan)
        for box in boxes:
            for j, kind, detail in box.on_step(s):
                assert kind in ('moved', 'silent', 'back'), (kind, detail)
                if kind == 'moved':
                    u[box.cores[j].index] = detail
                    moved += 1
                silent += kind == 'silent'
        want = eng.control(t, eng.pos, eng.theta, lam, is_leader, steering, frame)
        np.testing.assert_array_equal(u[alive], want[alive])
        assert np.isnan(u[~alive]).all()
        eng.advance(t, want, lam, is_leader, steering)
        for i, c in enumerate(cores):          # what the agents publish (the others keep their last)
            if alive[i]:
                x[i], y[i] = c.pos[0]
                qz[i], qw[i] = c.quaternion
        np.testing.assert_array_equal(np.stack([x, y], 1), eng.pos)
    assert silent >= silent_at_least           # the frozen one and the dead one left the table
    return moved, in_table


@pytest.fixture
def counted(monkeypatch):
    """Count the calls of the core law made by container_core (one per container and step)."""
    import swarm_agent.container_core as cc
    calls = {'n': 0, 'idle': 0}
    real = cc.alive_control

    def wrapped(*a, **k):
        calls['n'] += 1
        return real(*a, **k)
    monkeypatch.setattr(cc, 'alive_control', wrapped)
    return calls


@pytest.mark.parametrize('groups', [[[0, 1, 2], [3, 4, 5]], [[0, 1, 2, 3, 4, 5]], [[0], [1, 5], [2, 3, 4]]],
                         ids=['2x3', '1x6', 'mixed'])
def test_containers_equal_simulate_with_faults(tmp_path, counted, groups):
    path = short_homotopy(tmp_path / 'f.yaml', name='container_faults', duration=12, at=1, curvature=0.05,
                          lam={'kind': 'tanh_window', 'rise_at': 3, 'fall_at': 1000, 'tau': 1},
                          faults=[{'at': 2, 'freeze': 'agent_1', 'for': 2.0}, {'at': 5, 'kill': 'agent_4'}],
                          noise={'position': 0.001, 'heading': 0.001})
    scn = load(str(path))
    ref = simulate(scn)
    alive = np.isfinite(ref.u)
    assert not alive.all()                             # the faults took agents out
    moved, in_table = drive(scn, groups)
    # one law call per container and step, none for a container whose agents are all out
    idle = sum(int(sum(not alive[k, g].any() for k in range(scn.steps))) for g in groups)
    assert counted['n'] == scn.steps * len(groups) - idle
    assert moved == in_table                           # every agent in the table moved, once


COMPILED_CASES = {
    'homotopy': {},
    'global': {'law': {'kind': 'global'}},
    'local': {'law': {'kind': 'local', 'cutoff_radius': 1.5}, 'seed': 3},
    # λ = 1 exactly: a follower alone has no weight beyond w, but the table's leaders do, so
    # every process sums over all pairs, as the batch engine does (`all_pairs_wanted`)
    'lambda_one': {'lam': {'kind': 'ramps', 'ramps': [{'at': 2.0, 'to': 1.0, 'duration': 1.0}]}},
}


@pytest.mark.parametrize('case', COMPILED_CASES, ids=list(COMPILED_CASES))
def test_containers_equal_simulate_compiled(tmp_path, case):
    """With the compiled pair sums on (`compiled_sums`: a container asks the kernel for its own
    rows, the batch engine for all), the containers' u and positions equal the batch engine's
    bit for bit, with faults, noise and leaders; and they differ from the numpy sums' (the
    kernel is another path, not the reference again)."""
    pytest.importorskip('numba')
    over = dict(lam={'kind': 'tanh_window', 'rise_at': 3, 'fall_at': 1000, 'tau': 1}) | COMPILED_CASES[case]
    path = short_homotopy(tmp_path / 'c.yaml', name=f'compiled_{case}', duration=8, at=1, curvature=0.05,
                          faults=[{'at': 2, 'freeze': 'agent_1', 'for': 2.0}, {'at': 5, 'kill': 'agent_4'}],
                          noise={'position': 0.001, 'heading': 0.001}, **over)
    scn = load(str(path))
    moved, in_table = drive(scn, [[0], [1, 2], [3, 4, 5]], compiled=True)
    assert moved == in_table
    fast, ref = simulate(scn, compiled='on'), simulate(scn, compiled='off')
    assert fast.meta['neighbour_search'] == 'compiled' and ref.meta['neighbour_search'] == 'numpy'
    assert not np.array_equal(fast.u, ref.u, equal_nan=True)
    np.testing.assert_allclose(fast.u, ref.u, rtol=0, atol=1e-9)


def test_repeat_reject_and_kill():
    scn = load('homotopy_global', duration=1.0)
    n = len(scn.names)
    cores = [AgentCore(i, n, *scn.pos0[i], scn.theta0[i], scn.law, scn.dt) for i in range(n)]
    box = ContainerCore(cores[:3])
    from swarm_core.model.frenet import quaternion_from_heading
    qz, qw = quaternion_from_heading(scn.theta0)

    def msg(k, alive=None):
        return SimpleNamespace(n=k, t=k * scn.dt, lam=0.0, flags=np.zeros(n, bool), steering=np.zeros(n),
                               x=scn.pos0[:, 0], y=scn.pos0[:, 1], qz=qz, qw=qw, u=np.zeros(n),
                               alive=np.ones(n, bool) if alive is None else alive, target=None, barrier=None,
                               rendezvous=None)
    assert [k for _, k, _ in box.on_step(msg(0))] == ['moved'] * 3
    assert [k for _, k, _ in box.on_step(msg(0))] == ['repeat'] * 3       # the world's stall recovery
    assert [k for _, k, _ in box.on_step(msg(5))] == ['back'] * 3 + ['moved'] * 3
    out = box.on_step(msg(3))
    assert [k for _, k, _ in out] == ['reject'] * 3 and 'this agent is at step 6' in out[0][2][1]
    box.kill(1)
    alive = np.ones(n, bool)
    alive[2] = False
    assert [(j, k) for j, k, _ in box.on_step(msg(6, alive))] == [(2, 'silent'), (0, 'moved')]
    assert cores[1].step == 6 and cores[0].step == 7


def test_auto_rule_and_groups():
    assert agents_per_process(6, 2) == 1 and agents_per_process(PROCESSES_PER_CORE * 4, 4) == 1
    assert agents_per_process(7, 2) == 4 and agents_per_process(24, 2) == 12
    assert agents_per_process(1000, 2) == 500 and agents_per_process(1000, 32) == 32
    assert agents_per_process(10000, 2) == CONTAINER_SIZE
    for n in (24, 96, 240, 500, 1000, 5000):
        k = agents_per_process(n, 2)
        groups = split_agents([f'a{i}' for i in range(n)], k)
        assert len(groups) >= 2 and max(map(len, groups)) <= CONTAINER_SIZE
        assert sum(map(len, groups)) == n
    assert split_agents(['a', 'b', 'c'], 2) == [['a', 'b'], ['c']]


def test_an_agent_on_a_mujoco_robot_takes_its_pose_from_the_table_and_does_not_integrate():
    """Lockstep on a MuJoCo robot (``reported``): the agent's pose of the step is its row of the
    table (the robot world's report), its frame the table's quaternion, its heading unwrapped
    near the one before; it computes u as a kinematic agent standing there would, and leaves
    the move to its robot.  The kinematic agents beside it move as before."""
    from swarm_core.model.frenet import frame_from_quaternion, quaternion_from_heading
    scn = load('homotopy_global', duration=1.0)
    n = len(scn.names)
    theta = scn.theta0 + np.linspace(0.0, 0.5, n) + 4 * np.pi * (np.arange(n) == 1)   # b's report: 2 turns on
    qz, qw = quaternion_from_heading(theta)
    s = SimpleNamespace(n=0, t=0.0, lam=0.3, flags=np.zeros(n, bool), steering=np.zeros(n), x=scn.pos0[:, 0] + 0.1,
                        y=scn.pos0[:, 1], qz=qz, qw=qw, u=np.zeros(n), alive=np.ones(n, bool), target=None,
                        barrier=None, rendezvous=None)

    def box(reported):
        """Three agents; the kinematic ones stand where the table says, b too unless on a robot."""
        cores = [AgentCore(i, n, s.x[i], s.y[i], theta[i], scn.law, scn.dt) for i in range(3)]
        if reported:
            cores[1] = AgentCore(1, n, *scn.pos0[1], scn.theta0[1], scn.law, scn.dt)
            cores[1].reported = True
        return cores, ContainerCore(cores)
    robot, rbox = box(True)
    points, pbox = box(False)
    got, want = rbox.on_step(s), pbox.on_step(s)
    assert [k for _, k, _ in got] == ['moved'] * 3
    np.testing.assert_array_equal([u for *_, u in got], [u for *_, u in want])
    b = robot[1]
    assert b.pos.tolist() == [[s.x[1], s.y[1]]] and b.quaternion == (qz[1], qw[1])     # not moved
    assert b._own_frame() == tuple(np.asarray(frame_from_quaternion(qz, qw))[:, 1])
    assert b.theta[0] == pytest.approx(theta[1] - 4 * np.pi) and b.u_last == got[1][2] and b.step == 1
    for i in (0, 2):
        np.testing.assert_array_equal(robot[i].pos, points[i].pos)
        np.testing.assert_array_equal(robot[i].theta, points[i].theta)
    assert points[1].pos.tolist() != [[s.x[1], s.y[1]]]                # a kinematic b moved


@pytest.mark.parametrize('case', ['homotopy', 'local', 'lambda_one'])
def test_the_compiled_step_equals_the_batch_engine(tmp_path, monkeypatch, case):
    """Without noise a container of agents that sum compiled takes its usual steps in one
    compiled call (`compiled_step`), and a lone agent too; the steps a fault makes unusual go
    through numpy.  Both give the batch engine's bits (`drive` checks u and positions each step)."""
    pytest.importorskip('numba')
    from swarm_core.laws.paper import compiled_step
    calls = []
    real = compiled_step.CompiledStep.__call__
    monkeypatch.setattr(compiled_step.CompiledStep, '__call__', lambda self, *a: calls.append(1) or real(self, *a))
    over = dict(lam={'kind': 'tanh_window', 'rise_at': 3, 'fall_at': 1000, 'tau': 1}) | COMPILED_CASES[case]
    path = short_homotopy(tmp_path / 'c.yaml', name=f'step_{case}', duration=8, at=1, curvature=0.05,
                          faults=[{'at': 2, 'freeze': 'agent_1', 'for': 2.0}, {'at': 5, 'kill': 'agent_4'}], **over)
    scn = load(str(path))
    moved, in_table = drive(scn, [[0], [1, 2], [3, 4, 5]], compiled=True)
    assert moved == in_table
    # agent_0 alone steps compiled until the kill (then the table is not whole); the others less
    assert scn.steps // 2 < len(calls) < 3 * scn.steps
