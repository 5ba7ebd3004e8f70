"""The compiled pair sums of large swarms (swarm_core.laws.paper.compiled_sums) against the reference
(`laws.swarm_control` dense/sparse numpy paths) on n = 3,000, where the reference is still
affordable: equal to 1e-9 (they add the same terms in another order), for every coupling;
and the batch engine takes them only from COMPILED_LIMIT agents on."""
import subprocess
import sys

import numpy as np
import pytest

from swarm_core.laws import swarm_control
from swarm_core.laws.paper import compiled_sums as large_swarms
from swarm_core.model.frenet import heading_frame
from tests.core.laws import gains, paper_law

pytestmark = pytest.mark.skipif(not large_swarms.available(), reason='numba is not installed')

N = 3000


def table(n=N, spacing=1.5, seed=0):
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n] * spacing
    pos = grid + rng.uniform(-0.4, 0.4, (n, 2))
    pos[7] = pos[8]                                      # one coincident pair
    c, s = heading_frame(rng.uniform(-np.pi, np.pi, n))
    leaders = np.zeros(n, bool)
    leaders[[0, n // 2, n - 1]] = True
    return pos, c, s, leaders, rng.uniform(-0.2, 0.2, n)


@pytest.mark.parametrize('law, lam', [
    (paper_law(kind='global'), 0.0),
    (paper_law(kind='homotopy', q0=1.0), 0.4),
    (paper_law(kind='homotopy', q0=0.0), 1.0),
    (paper_law(kind='local'), 0.0),
    (paper_law(kind='leader_following'), 1.0),
    (paper_law(kind='target', target_normalised=True), 0.0),
    (paper_law(kind='homotopy', q0=0.5, gains=gains(alpha=2.0, r0=0.7)), 0.7),
])
def test_compiled_equals_the_reference_to_1e_9(law, lam):
    pos, c, s, leaders, steer = table()
    recv = np.arange(N)
    kw = dict(lambda_=lam, is_leader=leaders, steering=steer)
    ref = swarm_control(pos, c, s, recv, law, **kw)
    fast = swarm_control(pos, c, s, recv, law, pairs=large_swarms.COMPILED, **kw)
    assert np.isfinite(ref).all()
    err = np.abs(fast - ref)
    assert err.max() <= 1e-9 * max(1.0, np.abs(ref).max()), err.max()
    assert np.abs(ref).max() > 1e-3                      # not trivially zero
    # a wrong term would show: drop the leader gain and the sums differ
    if law.uses_leaders and lam > 0:
        plain = swarm_control(pos, c, s, recv, law, pairs=large_swarms.COMPILED, lambda_=lam, steering=steer)
        assert np.abs(plain - ref).max() > 1e-6


def test_engine_takes_the_compiled_path_only_for_large_swarms():
    from swarm_core.engine.reference import SwarmStepper
    from swarm_core.scenario.loader import parse
    def stepper(n, **kw):
        return SwarmStepper(parse(dict(name='big', dt=0.05, duration=1.0, law=dict(kind='global'),
                                       agents=dict(count=n, positions={'rule': 'grid', 'spacing': 1.5}))), **kw)
    small = stepper(2000)
    assert small._pairs(small.pos, 0.0) is None
    big = stepper(large_swarms.COMPILED_LIMIT)
    assert big._pairs(big.pos, 0.0) == large_swarms.COMPILED
    assert stepper(large_swarms.COMPILED_LIMIT, neighbour_search='all')._pairs(big.pos, 0.0) is None


def test_agent_processes_do_not_import_numba():
    """What an agent process imports (its core, the laws, the radio, faults) leaves numba out."""
    code = ('import sys, swarm_agent.agent_core, swarm_core.laws.control, swarm_core.radio, '
            'swarm_core.engine.reference; print("numba" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == 'False'


def test_a_row_is_summed_alike_whichever_receivers_are_asked():
    """The kernel sums each receiver's row on its own: an agent container asking for its rows
    gets the bits of the batch engine asking for all (global all pairs, local cell list)."""
    pos, c, s, leaders, steer = table(n=800)
    for law, lam in ((paper_law(kind='homotopy', q0=1.0), 0.4), (paper_law(kind='local'), 0.0)):
        kw = dict(lambda_=lam, is_leader=leaders, pairs=large_swarms.COMPILED)
        every = swarm_control(pos, c, s, np.arange(800), law, steering=steer, **kw)
        for rows in (np.arange(100, 200), np.array([799]), np.array([0, 7, 8, 400])):
            part = swarm_control(pos, c, s, rows, law, steering=steer[rows], **kw)
            np.testing.assert_array_equal(part, every[rows])


def test_the_run_chooses_compiled_sums_by_size_and_length():
    """`run_sums` (``--compiled``): auto keeps numpy for short small runs (nearly every test
    run), takes the kernels for long large ones, from COMPILED_LIMIT agents on, and in
    lockstep from LONG_RUN steps on at any size (the compiled step), not in realtime; on and
    off force it; the batch engine follows the same choice."""
    from swarm_core.engine.reference import run_search
    run_sums, long = large_swarms.run_sums, large_swarms.LONG_RUN
    assert run_sums(6, long - 1) == 'numpy' and run_sums(100, 1000) == 'numpy'
    assert run_sums(6, long) == 'compiled' and run_sums(6, 10000, lockstep=False) == 'numpy'
    assert run_search(6, long) == 'compiled'
    assert run_sums(1000, 200) == 'compiled' and run_sums(large_swarms.COMPILED_LIMIT, 1) == 'compiled'
    assert run_sums(6, 10, 'on') == 'compiled' and run_sums(5000, 10 ** 6, 'off') == 'numpy'
    with pytest.raises(ValueError, match='compiled must be one of auto, on, off'):
        run_sums(6, 10, 'yes')
    assert run_search(1000, 200) == 'compiled' and run_search(6, 100) == 'numpy'
    assert run_search(1000, 200, 'all') == 'all' and run_search(1000, 200, compiled='off') == 'numpy'
