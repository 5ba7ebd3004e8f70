"""The compiled 3D pair sums of large swarms (swarm_core.laws.paper.natural_compiled) against the
numpy 3D sums (`natural_sums`) on n = 1,500 with the threshold forced (COMPILED_LIMIT lowered):
equal to 1e-9 for every coupling, all pairs and the 3D cell list (dense and sparse cells); a
receiver's numbers are its own whichever receivers are asked with it; and the 3D engine takes them
by the planar rule, from COMPILED_LIMIT agents on."""
import numpy as np
import pytest

from swarm_core.laws.paper import compiled_sums
from swarm_core.laws.paper.natural_compiled import use_compiled
from swarm_core.model.natural import initial_frames
from tests.core.laws import gains, paper_law

pytestmark = pytest.mark.skipif(not compiled_sums.available(), reason='numba is not installed')

N = 1500


def both(monkeypatch, law, *args, **kw):
    """(numpy, compiled) of ``law.evaluate_natural(*args, **kw)``, the compiled limit forced."""
    ref = law.evaluate_natural(*args, **kw)
    monkeypatch.setattr(compiled_sums, 'COMPILED_LIMIT', 1)
    fast = law.evaluate_natural(*args, **kw)
    monkeypatch.setattr(compiled_sums, 'COMPILED_LIMIT', 1 << 62)
    return ref, fast


def table(n=N, spacing=1.5, seed=0, spread=None):
    """A jittered cubic lattice (or n uniform points in a box of side ``spread``), one coincident
    pair, random 3D frames, three leaders and their programs (s_u, s_v)."""
    rng = np.random.default_rng(seed)
    if spread is None:
        side = int(np.ceil(n ** (1 / 3)))
        grid = np.stack(np.meshgrid(*(np.arange(side),) * 3), -1).reshape(-1, 3)[:n] * spacing
        pos = grid + rng.uniform(-0.4, 0.4, (n, 3))
    else:
        pos = rng.uniform(0, spread, (n, 3))
    pos[7] = pos[8]
    frames = initial_frames(rng.normal(size=(n, 3)))
    leaders = np.zeros(n, bool)
    leaders[[0, n // 2, n - 1]] = True
    return pos, frames, leaders, rng.uniform(-0.2, 0.2, (n, 2))


def world(law):
    """The law with the target and barrier terms on, and their geometry."""
    law = law.with_parameters(target_gain=0.05, barrier_gain=2.0)
    return law, dict(target=np.array([30.0, -4.0, 6.0]), barrier=np.array([[3.0, 3, 3], [4, 3, 3], [3, 4, 5]]),
                     ground=0.5)


@pytest.mark.parametrize('law, lam', [
    (paper_law(kind='global'), 0.0),
    (paper_law(kind='homotopy', q0=1.0), 0.4),
    (paper_law(kind='homotopy', q0=0.0), 1.0),
    (paper_law(kind='local'), 0.0),
    (paper_law(kind='leader_following'), 1.0),
    (paper_law(kind='target', target_normalised=True), 0.0),
    (paper_law(kind='target'), 0.0),
    (paper_law(kind='homotopy', q0=0.5, gains=gains(alpha=2.0, r0=0.7)), 0.7),
])
def test_compiled_equals_the_numpy_sums_to_1e_9(monkeypatch, law, lam):
    pos, frames, leaders, steer = table()
    law, geometry = world(law)
    recv = np.arange(N)
    ref, fast = both(monkeypatch, law, pos, frames, recv, lambda_=lam, is_leader=leaders, steering=steer, **geometry)
    assert np.isfinite(ref).all()
    assert np.abs(fast - ref).max() <= 1e-9 * max(1.0, np.abs(ref).max()), np.abs(fast - ref).max()
    assert np.abs(ref[:, 1]).max() > 1e-3                  # v is not trivially zero
    if law.uses_leaders and lam > 0:                       # drop the leaders: the sums differ
        _, plain = both(monkeypatch, law, pos, frames, recv, lambda_=lam, steering=steer, **geometry)
        assert np.abs(plain - ref).max() > 1e-6


def test_a_run_s_choice_is_taken():
    """sums='compiled' / 'numpy' (a run's `compiled_sums.run_sums`) whatever the table's size."""
    pos, frames, leaders, steer = table(n=300, seed=5)
    law = paper_law(kind='homotopy', q0=0.3)
    kw = dict(lambda_=0.5, is_leader=leaders, steering=steer)
    auto = law.evaluate_natural(pos, frames, np.arange(300), **kw)
    np.testing.assert_array_equal(law.evaluate_natural(pos, frames, np.arange(300), sums='numpy', **kw), auto)
    fast = law.evaluate_natural(pos, frames, np.arange(300), sums='compiled', **kw)
    assert 0 < np.abs(fast - auto).max() <= 1e-9 * np.abs(auto).max()


@pytest.mark.parametrize('kind', ('local', 'global'))
def test_sparse_cells_and_any_receivers(monkeypatch, kind):
    """Few agents in a large box (the cell list searches its keys); a shuffled subset of
    receivers, one twice, gets the same numbers, bit for bit, as the whole table's rows."""
    pos, frames, leaders, steer = table(n=400, spread=60.0, seed=3)
    law = paper_law(kind=kind)
    ref, fast = both(monkeypatch, law, pos, frames, np.arange(400), is_leader=leaders, steering=steer)
    assert np.abs(fast - ref).max() <= 1e-9 * max(1.0, np.abs(ref).max())
    assert np.count_nonzero(ref) > 100
    some = np.random.default_rng(1).permutation(400)[:37]
    some = np.append(some, some[5])                        # one receiver asked twice
    _, part = both(monkeypatch, law, pos, frames, some, is_leader=leaders, steering=steer[some])
    np.testing.assert_array_equal(part, fast[some])


def test_more_cells_than_int64_holds_sums_all_pairs(monkeypatch):
    """w = 1e-4 over 2e6 of space: no cell list (its keys would overflow), the same sums."""
    pos, frames, leaders, steer = table(n=60, spread=2e6, seed=6)
    pos[3] = pos[4] + 5e-5                                 # one pair within w
    law = paper_law(kind='local', cutoff_radius=1e-4)
    ref, fast = both(monkeypatch, law, pos, frames, np.arange(60))
    assert np.count_nonzero(ref[[3, 4]]) and np.abs(fast - ref).max() <= 1e-9 * np.abs(ref).max()


def test_the_3d_engine_takes_the_compiled_sums_from_the_planar_limit(monkeypatch):
    from swarm_core.engine.natural import NaturalStepper
    from swarm_core.scenario.loader import parse
    assert not use_compiled(compiled_sums.COMPILED_LIMIT - 1)
    assert use_compiled(compiled_sums.COMPILED_LIMIT)
    assert use_compiled(3, 'compiled') and not use_compiled(compiled_sums.COMPILED_LIMIT, 'numpy')
    with pytest.raises(ValueError):
        use_compiled(3, 'on')
    scn = parse(dict(name='big3d', dim=3, dt=0.05, duration=1.0, law=dict(kind='global'),
                     agents=dict(count=300, positions={'rule': 'grid', 'spacing': 1.5})))
    st = NaturalStepper(scn)
    t, lam, is_leader, steering = st.inputs()
    ref = st.control(t, st.pos, (st.x, st.y, st.z), lam, is_leader, steering)
    calls = []
    import swarm_core.laws.paper.natural_sums as sums
    real = sums.compiled_controls_3d
    monkeypatch.setattr(sums, 'compiled_controls_3d', lambda *a: calls.append(1) or real(*a))
    monkeypatch.setattr(compiled_sums, 'COMPILED_LIMIT', 300)
    fast = st.control(t, st.pos, (st.x, st.y, st.z), lam, is_leader, steering)
    assert calls and np.abs(fast - ref).max() <= 1e-9 * max(1.0, np.abs(ref).max())
