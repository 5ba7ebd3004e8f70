"""Faults, leader failover and reunion in the pure core (swarm_core.faults.agents, no ROS)."""
import copy

import numpy as np
import pytest

from swarm_agent.agent_core import AgentCore
from swarm_core.analysis import outcomes
from swarm_core.analysis.outputs import analyse
from swarm_core.command.plan import CommandPlan
from swarm_core.command.schedules import ConstantSteering
from swarm_core.engine.reference import simulate
from swarm_core.faults.agents import (
    Fault,
    FaultTimeline,
    elect_successor,
    followers_of,
    reunion_law,
    track_slots,
)
from swarm_core.laws import swarm_control
from swarm_core.model.frenet import frame_from_quaternion, heading_frame
from swarm_core.scenario.loader import ScenarioError, load, parse
from swarm_core.step import alive_control
from tests.core.laws import paper_law

BASE = dict(name='faulty', seed=1, dt=0.05, duration=3.0,
            agents=dict(positions=[[-1, 1], [0, 1], [1, 1], [-1, 0], [0, 0], [1, 0]]),
            law=dict(kind='global'))


def scenario(**over):
    d = copy.deepcopy(BASE)
    d.update(over)
    return parse(d, 'test.yaml')


# ------------------------------------------------------------------ scenario fields

@pytest.mark.parametrize('faults,msg', [
    ([{'at': 1, 'kill': 'agent_1', 'freeze': 'agent_2', 'for': 1}], 'faults.0: Value error, give exactly one'),
    ([{'at': 1, 'freeze': 'agent_2'}], 'faults.0: Value error, freeze needs for'),
    ([{'at': -1, 'kill': 'agent_2'}], 'faults.0.at: Input should be greater than or equal to 0'),
    ([{'at': 1, 'kill': 'agent_9'}], "faults.0.kill: unknown agent 'agent_9'"),
    ([{'at': 1, 'kill': 'leader:x'}], 'leader slots are leader:0'),
])
def test_bad_fault_fields_are_one_line_errors(faults, msg):
    with pytest.raises(ScenarioError) as err:
        scenario(faults=faults)
    assert msg in str(err.value) and '\n' not in str(err.value)


def test_reunion_and_target_exclude_each_other():
    with pytest.raises(ScenarioError, match='reunion'):
        scenario(target={'position': [10, 0]}, reunion=[{'at': 1, 'for': 1}])


# ------------------------------------------------------------------ kill and freeze

def test_killed_agent_leaves_the_swarm():
    scn = scenario(faults=[{'at': 1.0, 'kill': 'agent_2'}])
    tr = simulate(scn)
    k0 = 20
    assert np.isfinite(tr.r[:k0]).all() and np.isnan(tr.r[k0:, 2]).all() and np.isnan(tr.theta[k0:, 2]).all()
    assert np.isfinite(np.delete(tr.r, 2, axis=1)).all()
    assert [e['kind'] for e in tr.meta['events']] == ['kill'] and tr.meta['events'][0]['t'] == 1.0
    # the others fly exactly as a five-agent swarm started from their states at t = 1
    keep = [0, 1, 3, 4, 5]
    five = parse(dict(BASE, duration=2.0, agents=dict(positions=tr.r[k0, keep].tolist(),
                                                        headings=tr.theta[k0, keep].tolist())), 'five')
    ref = simulate(five)
    np.testing.assert_array_equal(tr.r[k0:, keep], ref.r)
    # metrics skip the dead agent
    series, _ = analyse(tr, scenario=scn)
    assert np.all(np.isfinite(series['polarisation'])) and np.all(np.isfinite(series['centroid']))


def test_frozen_agent_holds_still_is_not_heard_then_resumes():
    scn = scenario(faults=[{'at': 1.0, 'freeze': 'agent_4', 'for': 0.5}])
    tr = simulate(scn)
    k0, k1 = 20, 30
    assert np.all(tr.r[k0:k1 + 1, 4] == tr.r[k0, 4]) and np.all(tr.theta[k0:k1 + 1, 4] == tr.theta[k0, 4])
    assert np.all(tr.u[k0:k1, 4] == 0.0)
    assert np.any(tr.r[k1 + 1, 4] != tr.r[k1, 4])                        # moves again
    # during the freeze the others' u is computed without agent_4
    k = k0 + 3
    rows = [0, 1, 2, 3, 5]
    c, s = heading_frame(tr.theta[k, rows])
    u = swarm_control(tr.r[k, rows], c, s, np.arange(5), scn.law)
    np.testing.assert_array_equal(tr.u[k, rows], u)
    assert [e['kind'] for e in tr.meta['events']] == ['freeze', 'resume']
    assert tr.meta['events'][1]['t'] == pytest.approx(1.5)


def test_fault_timeline_resolves_leader_slots_and_ignores_the_dead():
    tl = FaultTimeline([Fault(0.1, 'kill', 'leader:1'), Fault(0.2, 'kill', 'agent_3'),
                        Fault(0.2, 'freeze', 'agent_3', 1.0)], ['agent_0', 'agent_1', 'agent_2', 'agent_3'], 0.1)
    assert tl.apply(0, {1: 2}) == []
    ev = tl.apply(1, {1: 2})
    assert ev[0]['agent'] == 'agent_2' and ev[0]['slot'] == 1 and tl.dead.tolist() == [False, False, True, False]
    ev = tl.apply(2, {})
    assert [e['kind'] for e in ev] == ['kill'] and not tl.frozen.any()     # freezing the dead: no-op
    assert tl.alive.tolist() == [True, True, False, False]


def test_slots_tracked_from_the_commanders_events_resolve_leader_i_as_the_engine_does():
    """Realtime: the world knows the leader slots only from the commander's events; followed
    with `track_slots`, they name the agent the batch engine killed as 'leader:0' and, after
    failover, the successor."""
    scn = load('leader_failover', duration=480.0)
    ref = simulate(scn)
    row = {nm: i for i, nm in enumerate(scn.names)}
    slots = dict(scn.command_plan().slots)
    seen = []
    for ev in ref.meta['events']:
        if ev['kind'] == 'kill':
            assert scn.names[slots[ev['slot']]] == ev['agent']
            seen.append('kill')
        track_slots(slots, ev, row)
        if ev['kind'] == 'failover':
            assert scn.names[slots[ev['slot']]] == ev['agent']
            seen.append('failover')
    assert seen == ['kill', 'failover'], ref.meta['events']


# ------------------------------------------------------------------ failover rule

def test_elect_successor_nearest_ties_low_none():
    pos = np.array([[0, 0], [3, 0], [-3, 0], [1, 1], [10, 0]], float)
    assert elect_successor([0, 0], pos, [False, True, True, False, True]) == 1     # tie 1/2: lower
    assert elect_successor([0, 0], pos, [False, True, True, True, True]) == 3
    assert elect_successor([0, 0], pos, [False] * 5) == -1


def test_followers_of_uses_heard_leaders_only():
    pos = np.array([[0, 0], [10, 0], [1, 0], [9, 0], [5.5, 0]], float)
    lk = followers_of(pos, [True] * 5, [0, 1])
    assert lk.tolist() == [-1, -1, 0, 1, 1]
    lk = followers_of(pos, [True, False, True, True, True], [0, 1])
    assert lk.tolist() == [-1, -1, 0, 0, 0]


def test_plan_failover_after_timeout_to_the_lost_leaders_follower():
    pos = np.array([[0, 0], [20, 0], [1, 0], [2.5, 0], [19, 0], [21.5, 0]], float)
    c, s = np.ones(6), np.zeros(6)
    for timeout, want in ((0.5, 2), (None, None)):
        plan = CommandPlan(fixed_leaders={0: ConstantSteering(0.01), 1: ConstantSteering(-0.01)},
                           failover_timeout=timeout)
        heard = np.ones(6, bool)
        plan.update(0.0, pos, c, s, heard)
        heard[0] = False
        for k in range(1, 12):
            _, leaders, steer = plan.update(k * 0.1, pos, c, s, heard)
            if timeout is not None and k * 0.1 < 0.1 + timeout - 1e-9:
                assert leaders == [0, 1] and steer[0] == 0.01      # from its last known state
        if want is None:
            assert leaders == [0, 1] and plan.events == []
        else:
            assert leaders == [1, want] and steer[want] == 0.01 and plan.slots == {0: want, 1: 1}


# ------------------------------------------------------------------ lockstep agents == engine

def test_agent_cores_reproduce_engine_with_faults_failover_and_reunion():
    scn = parse(dict(BASE, duration=6.0, law=dict(kind='homotopy', q0=0.0),
                     agents=dict(count=8, positions=dict(rule='grid', spacing=1.5)),
                     **{'lambda': dict(kind='ramps', ramps=[dict(at=0.5, to=1.0, duration=1.0)])},
                     leaders=dict(rule='lateral_extremes', at=0.2,
                                  programs=[dict(kind='constant', curvature=0.2),
                                            dict(kind='constant', curvature=-0.2)]),
                     faults=[dict(at=2.0, kill='leader:0'), dict(at=1.0, freeze='agent_3', **{'for': 1.5})],
                     failover=dict(timeout=0.5),
                     reunion=[dict(at=4.0, **{'for': 1.0}, gain=0.5, coupling=0.3)]), 'lockstep')
    ref = simulate(scn)
    kinds = [e['kind'] for e in ref.meta['events']]
    for k in ('leaders_chosen', 'freeze', 'kill', 'resume', 'failover', 'rendezvous_on', 'rendezvous_off'):
        assert k in kinds, kinds
    n = len(scn.names)
    agents = [AgentCore(i, n, *scn.pos0[i], scn.theta0[i], scn.law, scn.dt) for i in range(n)]
    plan = scn.command_plan()
    faults = scn.fault_timeline()
    for step in range(scn.steps + 1):
        t = step * scn.dt
        faults.apply(step, plan.slots)
        alive = faults.alive
        x = np.array([a.pos[0, 0] for a in agents])
        y = np.array([a.pos[0, 1] for a in agents])
        q = np.array([a.quaternion for a in agents])
        c, s = frame_from_quaternion(q[:, 0], q[:, 1])
        lam, leaders, steering = plan.update(t, np.stack([x, y], 1), c, s, heard=alive)
        flags = np.zeros(n, bool)
        flags[leaders] = True
        live = np.flatnonzero(alive)
        us = {i: agents[i].control(x, y, q[:, 0], q[:, 1], lam, flags, steering[i], alive=alive,
                                   rendezvous=plan.rendezvous_now) for i in live}
        np.testing.assert_array_equal(np.stack([x, y], 1)[live], ref.r[step, live])
        np.testing.assert_array_equal(np.array([us[i] for i in live]), ref.u[step, live])
        assert np.isnan(ref.r[step, faults.dead]).all()
        for i in live:
            agents[i].advance(us[i])


# ------------------------------------------------------------------ the table of a step (alive_control)

def _table(n=7, seed=3):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-2.0, 2.0, size=(n, 2))
    c, s = heading_frame(rng.uniform(-np.pi, np.pi, size=n))
    flags = np.zeros(n, bool)
    flags[[1, n - 2]] = True
    return pos, c, s, flags, rng.uniform(-0.3, 0.3, size=n)


LAW = paper_law(kind='homotopy', q0=0.5)


def test_alive_control_leaves_a_killed_agent_out_of_everyones_table():
    """Agent 3 of 7 dead: the others' u are those of the table without its row (the engine's
    rule), bit for bit whoever asks (all receivers or one), and the dead agent's u is 0."""
    pos, c, s, flags, steer = _table()
    n, dead = len(pos), 3
    alive = np.ones(n, bool)
    alive[dead] = False
    u = alive_control(pos, c, s, np.arange(n), LAW, 0.6, flags, steer, alive=alive)
    keep = np.flatnonzero(alive)
    want = swarm_control(pos[keep], c[keep], s[keep], np.arange(keep.size), LAW, lambda_=0.6,
                         is_leader=flags[keep], steering=steer[keep])
    np.testing.assert_array_equal(u[keep], want)
    assert u[dead] == 0.0
    full = alive_control(pos, c, s, np.arange(n), LAW, 0.6, flags, steer)
    assert not np.any(full[keep] == u[keep])           # the dead agent's row did count before
    for k in (0, 4, 6):                                 # one receiver: its row of the same table
        one = alive_control(pos, c, s, [k], LAW, 0.6, flags, steer[[k]], alive=alive)
        assert one[0] == u[k]
    two = alive_control(pos, c, s, [dead, 5], LAW, 0.6, flags, steer[[dead, 5]], alive=alive)
    assert two[0] == 0.0 and two[1] == u[5]


def test_alive_control_reunion_and_pairs_see_the_alive_table():
    pos, c, s, flags, steer = _table()
    alive = np.array([1, 1, 0, 1, 0, 1, 1], bool)
    keep = np.flatnonzero(alive)
    rdv = ((0.5, -0.5), 0.7, False, 0.2)
    seen = []

    def pairs(p):
        seen.append(p.copy())
        return None
    u = alive_control(pos, c, s, np.arange(7), LAW, 0.3, flags, steer, target=None, alive=alive, rendezvous=rdv,
                      pairs=pairs)
    law, target = reunion_law(LAW, None, rdv)
    assert law != LAW and target is not None
    want = swarm_control(pos[keep], c[keep], s[keep], np.arange(keep.size), law, lambda_=0.3,
                         is_leader=flags[keep], steering=steer[keep], target=target)
    np.testing.assert_array_equal(u[keep], want)
    assert len(seen) == 1 and np.array_equal(seen[0], pos[keep])


def test_agent_core_row_is_its_place_in_a_table_of_the_agents_it_knows():
    """Realtime: the table holds only the agents an agent knows; `row` is its own place there,
    and its index (its place in the roster) is left alone."""
    pos, c, s, flags, _ = _table(n=5)
    theta = np.arctan2(s, c)
    agent = AgentCore(4, 9, *pos[2], theta[2], LAW, 0.05)
    q = np.array([AgentCore(0, 1, 0, 0, t, LAW, 0.05).quaternion for t in theta])
    u = agent.control(pos[:, 0], pos[:, 1], q[:, 0], q[:, 1], 0.5, flags, 0.1, row=2)
    want = swarm_control(pos, *frame_from_quaternion(q[:, 0], q[:, 1]), [2], LAW, lambda_=0.5,
                         is_leader=flags, steering=[0.1])
    assert u == want[0] and agent.index == 4


# ------------------------------------------------------------------ the shipped scenarios

EARLY = dict(name='early_failover', seed=0, dt=0.05, duration=24.0,
             agents=dict(positions=[[-1, 1], [0, 1], [1, 1], [-1, 0], [0, 0], [1, 0]]),
             law=dict(kind='homotopy', q0=1.0),
             leaders=dict(rule='lateral_extremes', at=2.0, programs=[dict(kind='constant', curvature=0.05),
                                                                     dict(kind='constant', curvature=-0.05)]),
             faults=[dict(at=14.0, kill='leader:0')],
             expect=dict(follows_program=dict(slot=0, **{'from': 16.0}, to=24.0, tolerance=0.3)))
EARLY['lambda'] = dict(kind='tanh_window', rise_at=8.0, fall_at=1000.0, tau=2.0)


@pytest.mark.parametrize('seed', [0, 1])
@pytest.mark.parametrize('failover', [True, False])
def test_lost_leaders_subswarm_follows_program_only_with_failover(seed, failover):
    """The split of Fig. 3 brought forward (λ up at t = 8, leaders ±0.05), the left leader killed
    at t = 14 after the split: with failover its subswarm keeps turning at +0.05."""
    scn = parse(dict(EARLY, seed=seed, **({'failover': {'timeout': 0.5}} if failover else {})), 'early')
    tr = simulate(scn)
    _, checks = analyse(tr, scenario=scn)
    fp = checks['follows_program']
    assert fp['passed'] is failover, fp
    if failover:
        ev = [e for e in tr.meta['events'] if e['kind'] == 'failover'][0]
        assert ev['t'] == pytest.approx(14.5) and ev['slot'] == 0 and ev['agent'] == fp['successor']
        assert tr.leader[-1, tr.names.index(ev['agent'])]
    else:
        assert fp['successor'] is None and abs(fp['turn_rate']) < 0.3 * 0.05


def test_follows_program_check_needs_a_constant_program():
    scn = scenario(leaders=dict(fixed={'agent_0': dict(kind='sinusoid')}))
    with pytest.raises(ValueError, match='constant'):
        outcomes.check_trajectory('follows_program', {'slot': 0, 'from': 0, 'to': 1}, simulate(scn), scn)


# ------------------------------------------------------------------ reunion

def two_groups(reunion):
    """Two groups of three under local coupling (homotopy q0 = 0, λ = 0), 20 apart and heading
    away from each other: without help they never meet."""
    d = dict(name='two_groups', seed=0, dt=0.1, duration=400.0, law=dict(kind='homotopy', q0=0.0),
             agents=dict(positions=[[0, 0], [0, 1.5], [1.5, 0.75], [0, 20], [0, 21.5], [1.5, 20.75]],
                         headings=[-0.2, -0.2, -0.2, 0.2, 0.2, 0.2]),
             expect=dict(split_at=5.0, one_cluster_from=215.0))
    if reunion:
        d['reunion'] = [dict(reunion, at=5.0, **{'for': 200.0})]
    return parse(d, 'two_groups')


@pytest.mark.parametrize('reunion,reunites', [(None, False), ({'gain': 0.05, 'coupling': 1.0}, True),
                                              ({'point': 'none', 'coupling': 1.0}, True)])
def test_reunion_brings_groups_together_and_local_coupling_keeps_them(reunion, reunites):
    scn = two_groups(reunion)
    tr = simulate(scn, record_every=10)
    series, checks = analyse(tr, scenario=scn)
    assert checks['split_at']['passed']
    assert checks['one_cluster_from']['passed'] is reunites, checks
    if reunion:
        on, off = [e for e in tr.meta['events'] if e['kind'].startswith('rendezvous')]
        assert (on['kind'], on['t'], off['kind'], off['t']) == ('rendezvous_on', 5.0, 'rendezvous_off', 205.0)
        assert on['coupling'] == 1.0 and (on['point'] is None) == (reunion.get('point') == 'none')


def test_rendezvous_point_is_the_centroid_at_switch_on_and_adds_the_target_term():
    scn = two_groups({'gain': 0.05})
    plan = scn.command_plan()
    c, s = heading_frame(scn.theta0)
    plan.update(4.9, scn.pos0, c, s)
    assert plan.rendezvous_now is None
    plan.update(5.0, scn.pos0, c, s)
    point, gain, normalised, coupling = plan.rendezvous_now
    np.testing.assert_allclose(point, scn.pos0.mean(axis=0))
    assert (gain, normalised, coupling) == (0.05, False, None)
    moved = scn.pos0 + 5.0
    plan.update(6.0, moved, c, s)
    np.testing.assert_allclose(plan.rendezvous_now[0], scn.pos0.mean(axis=0))    # fixed, not tracking
    from swarm_core.faults.agents import reunion_law
    law, target = reunion_law(scn.law, None, plan.rendezvous_now)
    from swarm_core.laws import target_term
    u = swarm_control(moved, c, s, np.arange(6), law, target=target)
    u0 = swarm_control(moved, c, s, np.arange(6), scn.law)
    np.testing.assert_allclose(u - u0, target_term(moved, c, s, target, law), atol=1e-15)
