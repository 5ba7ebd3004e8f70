"""Integrator, two-agent theory, neighbour search and determinism (no ROS)."""
import math

import numpy as np
import pytest

from swarm_core.engine import reference as engine
from swarm_core.laws import swarm_control
from swarm_core.laws.paper.pair_sums import neighbour_pairs
from swarm_core.model.frenet import heading_frame
from swarm_core.model.integrate import rk4_step, zoh_step
from swarm_core.scenario import loader as scenario


def test_zoh_is_exact_for_constant_curvature():
    u = np.array([0.3, -0.05, 0.0])
    th0 = np.array([0.2, 2.0, -1.0])
    pos = np.array([[1.0, -2.0], [0.0, 0.0], [5.0, 5.0]])
    r0 = pos.copy()
    dt, steps = 0.05, 4000
    th = th0.copy()
    for _ in range(steps):
        pos, th = zoh_step(pos, th, u, dt)
    t = dt * steps
    exact = r0.copy()
    for i in range(2):      # circle of radius 1/u
        exact[i] += np.array([math.sin(th0[i] + u[i] * t) - math.sin(th0[i]),
                              -math.cos(th0[i] + u[i] * t) + math.cos(th0[i])]) / u[i]
    exact[2] += t * np.array([math.cos(th0[2]), math.sin(th0[2])])   # straight line
    np.testing.assert_allclose(pos, exact, atol=1e-9)
    np.testing.assert_allclose(th, th0 + u * t, atol=1e-12)


def test_rk4_is_fourth_order():
    def control(t, p, th):
        return 0.2 * np.sin(th) + 0.05 * np.cos(t) + 0.0 * p[:, 0]
    p0, th0 = np.array([[0.0, 0.0]]), np.array([0.4])

    def run(dt):
        p, th = p0.copy(), th0.copy()
        for i in range(int(round(10 / dt))):
            p, th = rk4_step(p, th, i * dt, dt, control)
        return p[0]
    ref = run(0.005)
    e1, e2 = np.abs(run(0.2) - ref).max(), np.abs(run(0.1) - ref).max()
    assert 12 < e1 / e2 < 20     # 2^4 = 16


def _two_agents(seed, duration, integrator='zoh', dt=0.1, eta=0.02, mu=0.02):
    return scenario.parse(dict(
        name='two', seed=seed, dt=dt, duration=duration, integrator=integrator,
        agents=dict(positions=[[0, 0], [3, 1]], headings={'rule': 'uniform'}),
        law=dict(kind='global', eta=eta, mu=mu)))


def test_two_agent_equilibrium_is_reached_and_stable():
    """Justh-Krishnaprasad: aligned, abreast (perpendicular to the baseline) at ρ = r0."""
    scn = _two_agents(seed=1, duration=1600)
    tr = engine.simulate(scn)
    d = tr.r[:, 0] - tr.r[:, 1]
    rho = np.hypot(*d.T)
    along = (d[:, 0] * np.cos(tr.theta[:, 0]) + d[:, 1] * np.sin(tr.theta[:, 0])) / rho
    assert abs(rho[-1] - 1.5) < 1e-8
    assert abs(along[-1]) < 1e-8
    assert math.cos(tr.theta[-1, 0] - tr.theta[-1, 1]) > 1 - 1e-12
    # stability: perturb the equilibrium and it comes back
    pert = scenario.parse(dict(name='two', dt=0.1, duration=1200,
                               agents=dict(positions=(tr.r[-1] + [[0.3, -0.2], [0, 0]]).tolist(),
                                           headings=(tr.theta[-1] + [0.3, -0.1]).tolist()),
                               law=dict(kind='global')))
    tr2 = engine.simulate(pert)
    d2 = tr2.r[-1, 0] - tr2.r[-1, 1]
    assert abs(np.hypot(*d2) - 1.5) < 1e-6
    assert abs(math.cos(tr2.theta[-1, 0] - tr2.theta[-1, 1]) - 1) < 1e-10


@pytest.mark.parametrize('seed', [0, 5])
def test_two_agent_lyapunov_function_never_increases(seed):
    """V = −ln(1 + x1·x2) + α(ρ + r0²/ρ) has dV/dt ≤ 0 when η < 2μ (docs/model.md)."""
    scn = _two_agents(seed=seed, duration=200, integrator='rk4', dt=0.05, eta=0.02, mu=0.02)
    tr = engine.simulate(scn)
    rho = np.hypot(*(tr.r[:, 0] - tr.r[:, 1]).T)
    V = -np.log(1 + np.cos(tr.theta[:, 0] - tr.theta[:, 1])) + 0.02 * (rho + 1.5 ** 2 / rho)
    assert V[-1] < V[0] - 1e-3              # it does decrease…
    assert np.max(np.diff(V)) <= 1e-12      # …and never increases


def test_kdtree_neighbour_search_equals_all_pairs():
    rng = np.random.default_rng(4)
    n = 300
    pos = rng.uniform(-25, 25, (n, 2))
    th = rng.uniform(-3, 3, n)
    c, s = heading_frame(th)
    scn = scenario.parse(dict(name='big', agents=dict(positions=pos.tolist(), headings=th.tolist()),
                              law=dict(kind='local')))
    pairs = neighbour_pairs(pos, scn.law.cutoff_radius)
    u_tree = swarm_control(pos, c, s, np.arange(n), scn.law, pairs=pairs)
    u_all = swarm_control(pos, c, s, np.arange(n), scn.law)
    np.testing.assert_allclose(u_tree, u_all, rtol=0, atol=1e-14)   # other summation order
    assert len(pairs[0]) < n * (n - 1) / 5
    # one agent with its own neighbour list adds the same terms in the same order
    from swarm_core.laws.paper.pair_sums import sparse_coupling
    from tests.helpers import pairs_of_one
    assert sparse_coupling(n, scn.law, 0.0)
    for k in (0, 17, 299):
        one = swarm_control(pos, c, s, np.array([k]), scn.law, pairs=pairs_of_one(pairs, k))
        assert one[0] == u_tree[k]


def _per_agent_run(scn, steps):
    """What a swarm of agent nodes does: each agent computes only its own u from the table of
    states it received (frames through the quaternion) and integrates only itself."""
    from swarm_core.model.frenet import frame_from_quaternion, quaternion_from_heading
    pos, th = scn.pos0.copy(), scn.theta0.copy()
    plan = scn.command_plan()
    n = len(th)
    rngs = [scn.noise_rng(i) for i in range(n)]
    scale = np.array([scn.spec.noise.position] * 2 + [scn.spec.noise.heading])
    for step in range(steps):
        t = step * scn.dt
        qz, qw = quaternion_from_heading(th)        # what goes on the wire
        c, s = frame_from_quaternion(qz, qw)
        lam, leaders, steering = plan.update(t, pos, c, s)
        is_leader = np.zeros(n, bool)
        is_leader[leaders] = True
        new_pos, new_th = pos.copy(), th.copy()
        for k in range(n):
            u = swarm_control(pos, c, s, np.array([k]), scn.law, lambda_=lam, is_leader=is_leader,
                              steering=steering[[k]], target=scn.target, barrier=scn.barrier)
            p1, t1 = zoh_step(pos[k:k + 1], th[k:k + 1], u, scn.dt)
            if scale.any():
                nz = rngs[k].uniform(-1.0, 1.0, size=3) * scale
                p1, t1 = p1 + nz[:2], t1 + nz[2]
            new_pos[k], new_th[k] = p1[0], t1[0]
        pos, th = new_pos, new_th
    return pos, th


@pytest.mark.parametrize('name,extra', [('homotopy_global', {}),
                                        ('target_barrier', {}),
                                        ('homotopy_local', {'noise': {'position': 0.01, 'heading': 0.01}})])
def test_agent_by_agent_equals_batch_exactly(name, extra):
    """The premise of lockstep determinism: agents computing alone reproduce the batch run."""
    import yaml

    from swarm_core.scenario.loader import resolve
    data = yaml.safe_load(resolve(name)[0])
    data.update(extra)
    data['leaders'] = data.get('leaders') or {}
    if 'rule' in data['leaders']:
        data['leaders']['at'] = 5.0
        data['lambda'] = {'kind': 'tanh_window', 'rise_at': 10, 'fall_at': 30, 'tau': 3}
    scn = scenario.parse(data, duration=40.0)
    steps = scn.steps
    tr = engine.simulate(scn)
    pos, th = _per_agent_run(scn, steps)
    np.testing.assert_array_equal(pos, tr.r[-1])
    np.testing.assert_array_equal(th, tr.theta[-1])


def test_realtime_catch_up_moves_by_the_elapsed_periods():
    """A realtime agent integrates floor((now − t)/dt) periods (u held), the periods begun,
    none when no period has passed (a second timer call for the same /clock time), and at
    most `limit` after a long gap (a stopped process), restarting its time at now; no
    rounding drift, and never a state stamped ahead of the clock."""
    from swarm_agent.agent_core import catch_up
    dt = 0.05
    assert catch_up(0.1, 0.0, dt, 4) == (2, 0.1)
    assert catch_up(0.1, 0.1, dt, 4) == (0, 0.1)            # same time again: nothing moves
    assert catch_up(0.12, 0.1, dt, 4) == (0, 0.1)           # less than half a period
    assert catch_up(0.14, 0.1, dt, 4) == (0, 0.1)           # more than half, less than one
    assert catch_up(0.17, 0.1, dt, 4) == (1, pytest.approx(0.15))   # late in its period: that period's state
    assert catch_up(0.3, 0.1 + 0.05 + 0.05, dt, 4)[0] == 2     # on the boundary, dt summed in floats
    assert catch_up(5.1, 0.1, dt, 4) == (4, 5.1)            # a freeze: limit periods, time reset
    t, periods = 0.0, 0
    for now in np.cumsum(np.random.default_rng(0).uniform(0.02, 0.11, 2000)):   # clock jitter
        k, t = catch_up(float(now), t, dt, 4)
        periods += k
        assert t <= now + 1e-9                              # never ahead of the clock
    assert 0 <= now - periods * dt < dt                     # the agent kept up with the clock


def test_realtime_table_holds_the_fresh_neighbours_and_self_in_roster_order():
    from swarm_agent.agent_core import known_table
    roster = ['a', 'b', 'c', 'd']
    newest = {'a': (9.0, 1.0, 2.0, 0.0, 1.0, 0.1),        # fresh
              'b': (6.9, 5.0, 5.0, 0.0, 1.0, 0.0),        # 2.1 s old: stale
              'd': (7.0, 3.0, 4.0, 0.6, 0.8, 0.0)}        # exactly stale_after old: kept
    own, rows, flags = known_table(roster, 'c', (0.5, 0.5, 0.0, 1.0), newest, {'d'}, 9.0, 2.0)
    assert own == 1
    np.testing.assert_array_equal(rows, [[1.0, 2.0, 0.0, 1.0], [0.5, 0.5, 0.0, 1.0], [3.0, 4.0, 0.6, 0.8]])
    assert flags.tolist() == [False, False, True]
    own, rows, _ = known_table(roster, 'c', (0.5, 0.5, 0.0, 1.0), {}, set(), 9.0, 2.0)
    assert own == 0 and rows.shape == (1, 4)                # alone: its own row


@pytest.mark.parametrize('roster,name,index,want', [
    ([''], 'agent_3', -1, (['agent_3'], 0)),
    (['a', 'b', 'c'], 'c', -1, (['a', 'b', 'c'], 2)),
    (['a', 'b', 'c'], 'b', 1, (['a', 'b', 'c'], 1)),
    (['a', 'b', 'a'], 'b', -1, 'parameter agent_names: names must be unique'),
    (['a', 'b'], 'c', -1, "parameter agent_name: 'c' is not in agent_names"),
    (['a', 'b'], 'b', 0, "parameter agent_index: 0 does not name 'b' in agent_names"),
    (['a', 'b'], 'b', 2, "parameter agent_index: 2 does not name 'b' in agent_names"),
])
def test_roster_index(roster, name, index, want):
    from swarm_agent.agent_core import roster_index
    if isinstance(want, str):
        with pytest.raises(ValueError, match=want):
            roster_index(roster, name, index)
    else:
        assert roster_index(roster, name, index) == want
