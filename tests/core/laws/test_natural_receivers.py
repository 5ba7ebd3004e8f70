"""A receiver's (u, v) in 3D does not depend on which receivers are asked with it
(`natural_sums`: each receiver's sums reduce its own rows): alone, in any subset or order, or
with the whole table, the same bits.  Lockstep agents and containers rely on it."""
import numpy as np
import pytest

from swarm_core.laws import make_law, natural_control
from swarm_core.model.natural import initial_frames

KINDS = ('global', 'local', 'leader_following', 'homotopy', 'target')


@pytest.mark.parametrize('kind', KINDS)
@pytest.mark.parametrize('n', (2, 6, 13, 60))          # 60: the whole table summed by component
def test_each_receiver_alone_gives_its_row_of_the_whole_table(kind, n):
    rng = np.random.default_rng(n)
    law = make_law({'kind': kind, 'q0': 0.05}).with_parameters(target_gain=0.05, barrier_gain=5.0)
    for trial in range(20):
        pos = rng.uniform(-6, 6, (n, 3))
        if n > 4:
            pos[3] = pos[1]                                 # coincident agents add 0
        frames = initial_frames(rng.normal(size=(n, 3)))
        leaders = rng.random(n) < 0.3
        lam = float(rng.choice([0.0, 0.37, 1.0]))
        steer = rng.uniform(-0.02, 0.02, (n, 2))
        world = dict(target=rng.uniform(-5, 5, 3), barrier=rng.uniform(-3, 3, (5, 3)), ground=-2.0) if trial % 2 \
            else {}
        kw = dict(lambda_=lam, is_leader=leaders, **world)
        every = natural_control(pos, frames, np.arange(n), law, steering=steer, **kw)
        for k in range(n):
            one = natural_control(pos, frames, np.array([k]), law, steering=steer[k:k + 1], **kw)
            np.testing.assert_array_equal(one[0], every[k], err_msg=f'{kind} n={n} receiver {k}')
        some = rng.permutation(n)[:max(1, n // 3)]
        part = natural_control(pos, frames, some, law, steering=steer[some], **kw)
        np.testing.assert_array_equal(part, every[some])


def test_the_two_ways_of_summing_a_block_give_the_same_bits(monkeypatch):
    """`natural_sums._block_sum`: (b, 3, N) arrays for small blocks, one (b, N) array per
    component for large ones: the same products reduced in the same order."""
    from swarm_core.laws.paper import natural_sums
    rng = np.random.default_rng(11)
    for kind in KINDS:
        law = make_law({'kind': kind, 'q0': 0.05})
        for n in (3, 9, 50, 150):
            pos = rng.uniform(-6, 6, (n, 3))
            frames = initial_frames(rng.normal(size=(n, 3)))
            leaders = rng.random(n) < 0.2
            kw = dict(lambda_=0.6, is_leader=leaders, steering=np.zeros((n, 2)))
            out = []
            for limit in (0, 10 ** 9):
                monkeypatch.setattr(natural_sums, 'BY_COMPONENT', limit)
                out.append(natural_control(pos, frames, np.arange(n), law, **kw))
            np.testing.assert_array_equal(out[0], out[1], err_msg=f'{kind} n={n}')
