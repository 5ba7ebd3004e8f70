"""Live law changes without DDS: agents whose law parameters are set during a lockstep run
(`swarm_core.command.plan.law_with`, from the step each agent holds) compute the batch
engine's u bit for bit when the engine replays the same ``law`` commands at those steps
(`law_timeline`: one law call per group of agents that share a law), alone, in containers
(`ContainerCore.one_law` follows the change) and through a radio model."""
from types import SimpleNamespace

import numpy as np
import pytest

from swarm_agent.agent_core import AgentCore
from swarm_agent.container_core import ContainerCore
from swarm_core.command.plan import law_with
from swarm_core.engine.reference import SwarmStepper
from swarm_core.model.frenet import quaternion_from_heading
from swarm_core.radio import CommModel
from swarm_core.scenario.loader import parse

BASE = dict(name='law_changes', seed=3, dt=0.05, duration=15.0,
            agents=dict(positions=[[-1, 1], [0, 1], [1, 1], [-1, 0], [0, 0], [1, 0]]),
            law=dict(kind='homotopy', q0=0.5), leaders=dict(rule='lateral_extremes', at=2.0, programs=[
                dict(kind='constant', curvature=0.05), dict(kind='constant', curvature=-0.05)]),
            **{'lambda': dict(kind='constant', value=0.4)})
#: step → [(agent, parameters)]: two agents changed, one twice, one change of two parameters
CHANGES = {40: [(1, {'alpha': 0.4})], 90: [(4, {'mu': 0.3, 'cutoff_radius': 2.0})], 150: [(1, {'eta': 0.1})]}


def commands():
    return {step: [dict(command='law', agent=k, parameters=p) for k, p in cs] for step, cs in CHANGES.items()}


@pytest.mark.parametrize('groups,comms,compiled', [
    ([[0], [1], [2], [3], [4], [5]], None, False),
    ([[0, 1, 2], [3, 4, 5]], None, False),
    ([[0, 1, 2], [3, 4, 5]], None, True),
    ([[0, 1, 2, 3, 4, 5]], dict(loss=0.3, latency=0.1), False),
], ids=['alone', 'containers', 'containers-compiled', 'radio'])
def test_agents_with_live_law_changes_equal_the_engines_replay(groups, comms, compiled):
    """A set on one agent of a container changes that agent alone, from its step: the
    container then calls the law once per agent (its own law each), compiled sums or not."""
    if compiled:
        pytest.importorskip('numba')
    scn = parse(dict(BASE, **({'comms': comms} if comms else {})), 'test')
    n = len(scn.names)
    eng = SwarmStepper(scn, commands=commands(), neighbour_search='compiled' if compiled else 'auto')
    cores = [AgentCore(i, n, *scn.pos0[i], scn.theta0[i], scn.law, scn.dt) for i in range(n)]
    for c in cores if compiled else ():
        c.sums_compiled()
    if comms:
        for c in cores:
            c.attach_comms(CommModel.from_config(scn.comms_config(), scn.names, scn.dt, scn.seed))
    boxes = [ContainerCore([cores[i] for i in g]) for g in groups]
    x, y = scn.pos0[:, 0].copy(), scn.pos0[:, 1].copy()
    qz, qw = quaternion_from_heading(scn.theta0)
    u_sent = np.zeros(n)
    for step in range(scn.steps):
        for k, p in CHANGES.get(step, ()):        # what the agent node's post-set callback does
            cores[k].law = law_with(cores[k].law, p)
        t, lam, is_leader, steering, frame = eng.inputs()
        s = SimpleNamespace(n=step, t=t, lam=lam, flags=is_leader, steering=np.asarray(steering, float),
                            x=x.copy(), y=y.copy(), qz=qz.copy(), qw=qw.copy(), u=u_sent.copy(),
                            alive=np.ones(n, bool), target=None, barrier=None, rendezvous=None)
        u = np.full(n, np.nan)
        for box in boxes:
            for j, kind, detail in box.on_step(s):
                assert kind == 'moved', (kind, detail)
                u[box.cores[j].index] = detail
        want = eng.control(t, eng.pos, eng.theta, lam, is_leader, steering, frame)
        np.testing.assert_array_equal(u, want, err_msg=f'step {step}')
        eng.advance(t, want, lam, is_leader, steering)
        u_sent = want
        for i, c in enumerate(cores):
            x[i], y[i] = c.pos[0]
            qz[i], qw[i] = c.quaternion
        np.testing.assert_array_equal(np.stack([x, y], 1), eng.pos)
    for b in boxes:                               # a container with a changed agent: one law call per agent
        assert b.one_law == (len(b.cores) == 1 or not any(c.index in (1, 4) for c in b.cores))
    assert cores[1].law.alpha == 0.4 and cores[1].law.eta == 0.1 and cores[4].law.cutoff_radius == 2.0
    events = [e for e in eng.events if e.get('command') == 'law']
    assert [(e['step'], e['agent'], e['parameters']) for e in events] == [
        (40, 'agent_1', {'alpha': 0.4}), (90, 'agent_4', {'mu': 0.3, 'cutoff_radius': 2.0}),
        (150, 'agent_1', {'eta': 0.1})]


def test_a_law_change_changes_the_run_from_its_step_only():
    from swarm_core.engine.reference import simulate
    scn = parse(BASE, 'test')
    plain, changed = simulate(scn), simulate(scn, commands=commands())
    np.testing.assert_array_equal(changed.r[:41], plain.r[:41])     # states up to t_40: u_40 is the new law's
    assert not np.array_equal(changed.r[41], plain.r[41])
