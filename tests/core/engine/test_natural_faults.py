"""The 3D batch engine (engine/natural.py) with faults, failover, reunion, noise and replayed
commands: the planar rules, measured in space."""
import numpy as np
import pytest

from swarm_core.command.plan import check_command
from swarm_core.engine import reference as engine
from swarm_core.faults.agents import elect_successor, followers_of
from swarm_core.laws import natural_control
from swarm_core.scenario import parse

SIX = [[-1, 1, 0], [0, 1, 0.5], [1, 1, 0], [-1, 0, 0.5], [0, 0, 0], [1, 0, 0.5]]
LAW = dict(kind='homotopy', alpha=0.02, eta=0.02, mu=0.02, r0=1.5, cutoff_radius=4.0, leader_gain=30.0, q0=1.0)


def _scenario(**over):
    data = dict(name='f3', dim=3, dt=0.1, duration=20, law=LAW,
                agents=dict(positions=SIX, headings={'rule': 'cap', 'half_width': 0.7}))
    data.update(over)
    return parse(data, 'f3.yaml')


def _frames(traj, s, rows):
    return tuple(f[s][rows] for f in (traj.x, traj.y, traj.z))


def test_a_kill_drops_the_agent_from_every_table_and_its_rows_are_nan():
    scn = _scenario(faults=[{'at': 5, 'kill': 'agent_2'}])
    traj = engine.simulate(scn)
    k0 = 50
    assert np.isnan(traj.r[k0:, 2]).all() and np.isnan(traj.u[k0:, 2]).all() and np.isnan(traj.z[k0:, 2]).all()
    assert np.isfinite(traj.r[:k0]).all() and np.isfinite(np.delete(traj.r, 2, axis=1)).all()
    alive = np.array([0, 1, 3, 4, 5])
    for s in (k0, k0 + 37, len(traj.t) - 1):        # the others' (u, v) from a table without it
        uv = natural_control(traj.r[s][alive], _frames(traj, s, alive), np.arange(5), scn.law)
        np.testing.assert_array_equal(uv[:, 0], traj.u[s, alive])
        np.testing.assert_array_equal(uv[:, 1], traj.v[s, alive])
    assert [e['kind'] for e in traj.meta['events']] == ['kill']


def test_a_freeze_holds_the_agent_unheard_then_it_rejoins():
    scn = _scenario(faults=[{'at': 3, 'freeze': 'agent_4', 'for': 2.0}])
    traj = engine.simulate(scn)
    k0, k1 = 30, 50
    for key in ('r', 'x', 'y', 'z'):                  # it does not move while frozen
        rec = getattr(traj, key)
        assert np.all(rec[k0:k1 + 1, 4] == rec[k0, 4])
    assert np.any(traj.r[k1 + 1, 4] != traj.r[k1, 4])  # and moves again once back
    others = np.array([0, 1, 2, 3, 5])
    uv = natural_control(traj.r[k0 + 5][others], _frames(traj, k0 + 5, others), np.arange(5), scn.law)
    np.testing.assert_array_equal(uv[:, 0], traj.u[k0 + 5, others])
    full = natural_control(traj.r[k1 + 3], _frames(traj, k1 + 3, slice(None)), np.arange(6), scn.law)
    np.testing.assert_array_equal(full[:, 0], traj.u[k1 + 3])          # back in every table
    kinds = [(e['kind'], e['step']) for e in traj.meta['events']]
    assert kinds == [('freeze', k0), ('resume', k1)]


def test_failover_picks_the_follower_nearest_the_lost_leader_in_space():
    leaders = {'fixed': {'agent_1': {'kind': 'constant', 'curvature': [0.01, 0.0]},
                         'agent_4': {'kind': 'constant', 'curvature': [-0.01, 0.0]}}}
    scn = _scenario(leaders=leaders, faults=[{'at': 4, 'kill': 'leader:0'}], failover={'timeout': 1.0},
                    **{'lambda': {'kind': 'constant', 'value': 0.5}})
    traj = engine.simulate(scn)
    ev = next(e for e in traj.meta['events'] if e['kind'] == 'failover')
    assert ev['lost'] == 'agent_1' and ev['slot'] == 0 and ev['t'] == 5.0
    succ = scn.names.index(ev['agent'])
    last = 39                                          # the lost leader's last step heard
    eligible = followers_of(traj.r[last], np.ones(6, bool), [1, 4]) == 1      # l(k) = the lost leader
    assert eligible.sum() >= 2 and eligible[succ]
    assert succ == elect_successor(traj.r[last, 1], traj.r[50], eligible)     # nearest at the failover step
    assert traj.leader[-1, succ] and traj.leader[-1, 4] and not traj.leader[-1, 1]
    assert not traj.leader[49, succ] and traj.leader[50, succ]


def test_the_successor_is_nearest_in_space_not_from_above():
    pos = np.array([[0, 0, 0], [1, 0, 5], [2, 0, 0]], float)
    assert elect_successor(pos[0], pos, [False, True, True]) == 2       # from above agent 1 is nearer
    assert followers_of(pos, np.ones(3, bool), [1, 2]).tolist() == [2, -1, -1]


def test_a_3d_rendezvous_steers_to_its_point_in_space():
    scn = _scenario(reunion=[{'at': 2, 'for': 10, 'point': [3, -2, 4], 'coupling': 0.5}], duration=6)
    traj = engine.simulate(scn)
    ev = traj.meta['events'][0]
    assert ev['kind'] == 'rendezvous_on' and ev['point'] == [3.0, -2.0, 4.0]
    s = 30
    law = scn.law.with_parameters(target_gain=0.05, target_normalised=False, q0=0.5)
    uv = natural_control(traj.r[s], _frames(traj, s, slice(None)), np.arange(6), law, target=np.array([3., -2, 4]))
    np.testing.assert_array_equal(uv[:, 1], traj.v[s])
    centroid = engine.simulate(_scenario(reunion=[{'at': 2, 'for': 10}], duration=3)).meta['events'][0]
    start = engine.simulate(_scenario(duration=2)).r[-1]
    np.testing.assert_allclose(centroid['point'], start.mean(axis=0), atol=1e-12)


def test_noise_with_zero_sigma_equals_no_noise_bit_for_bit():
    a = engine.simulate(_scenario())
    b = engine.simulate(_scenario(noise={'position': 0.0, 'heading': 0.0}))
    for key in ('r', 'x', 'y', 'z', 'u', 'v'):
        assert np.array_equal(getattr(a, key), getattr(b, key))


def test_noise_moves_each_coordinate_and_turns_the_heading_in_its_normal_plane():
    one = dict(agents=dict(positions=[[0, 0, 0]], headings={'vectors': [[1, 0, 0]]}), duration=0.1, dt=0.1)
    still = engine.simulate(_scenario(**one))
    p = engine.simulate(_scenario(noise={'position': 0.01}, **one))
    kick = p.r[1, 0] - still.r[1, 0]
    assert np.all(np.abs(kick) <= 0.01) and np.all(kick != 0.0) and np.array_equal(p.x, still.x)
    h = engine.simulate(_scenario(noise={'heading': 0.02}, **one))
    assert np.array_equal(h.r, still.r)
    x0, x1, y0, z0 = h.x[0, 0], h.x[1, 0], h.y[0, 0], h.z[0, 0]
    turn = np.arccos(np.clip(x1 @ x0, -1, 1))
    assert 0 < turn <= 0.02 * np.sqrt(2) + 1e-12 and abs(x1 @ y0) <= np.sin(0.02) and abs(x1 @ z0) <= np.sin(0.02)
    F = np.stack([h.x[1, 0], h.y[1, 0], h.z[1, 0]])
    np.testing.assert_allclose(F @ F.T, np.eye(3), atol=1e-14)


def test_noise_is_seeded_per_agent_and_keeps_the_frames_orthonormal():
    spec = dict(noise={'position': 0.002, 'heading': 0.01}, duration=30)
    a, b = engine.simulate(_scenario(**spec)), engine.simulate(_scenario(**spec))
    c = engine.simulate(_scenario(seed=1, **spec))
    assert np.array_equal(a.r, b.r) and not np.array_equal(a.r, c.r)
    F = np.stack([a.x[-1], a.y[-1], a.z[-1]], axis=1)
    np.testing.assert_allclose(np.einsum('nij,nkj->nik', F, F), np.broadcast_to(np.eye(3), F.shape), atol=1e-12)


def test_a_frozen_agent_draws_no_noise():
    spec = dict(noise={'position': 0.01, 'heading': 0.01}, faults=[{'at': 1, 'freeze': 'agent_1', 'for': 1.0}])
    traj = engine.simulate(_scenario(**spec))
    assert np.all(traj.r[10:21, 1] == traj.r[10, 1])


def test_replayed_lambda_and_law_commands_apply_at_their_steps():
    scn = _scenario(duration=6)
    cmds = {20: [check_command({'command': 'lambda', 'value': 0.8, 'ramp': 0.0}, 6)],
            30: [check_command({'command': 'law', 'agent': 3, 'parameters': {'alpha': 0.5}}, 6)]}
    traj = engine.simulate(scn, commands=cmds)
    assert np.all(traj.lam[:20] == 0.0) and np.all(traj.lam[21:] == 0.8)
    base = engine.simulate(scn)
    assert np.array_equal(traj.r[:31], engine.simulate(scn, commands={20: cmds[20]}).r[:31])
    s = 30
    law = scn.law.with_parameters(alpha=0.5)
    uv = natural_control(traj.r[s], _frames(traj, s, slice(None)), np.array([3]), law, lambda_=0.8)
    np.testing.assert_array_equal(uv[0], [traj.u[s, 3], traj.v[s, 3]])
    assert not np.array_equal(traj.r, base.r)
    assert [e['command'] for e in traj.meta['events']] == ['lambda', 'law']


def test_a_steering_command_of_one_curvature_is_planar_and_one_of_s_u_s_v_replays():
    with pytest.raises(ValueError, match='one curvature is planar'):
        engine.simulate(_scenario(), commands={3: [check_command({'command': 'steer', 'agent': 0, 'value': 0.1}, 6)]})
    cmd = check_command({'command': 'steer', 'agent': 0, 'value': [0.0, 0.3]}, 6)
    assert cmd['value'] == (0.0, 0.3)
    traj = engine.simulate(_scenario(**{'lambda': {'kind': 'constant', 'value': 1.0}}), commands={3: [cmd]})
    assert not traj.leader[:3, 0].any() and traj.leader[3:, 0].all()     # it leads from step 3 on
    np.testing.assert_allclose(traj.v[3:, 0], 0.3) and np.testing.assert_allclose(traj.u[3:, 0], 0.0)
