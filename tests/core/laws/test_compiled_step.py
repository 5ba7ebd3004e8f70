"""The compiled lockstep step (`laws.paper.compiled_step`): on random tables it gives the bits of
the numpy step on the compiled sums (`step.alive_control` with ``pairs`` compiled, then
`integrate.zoh_step` and the new quaternions), for every paper law, with and without leaders
(ties included), a target, λ at 0, between and at 1, and any set of receivers; and it says
which steps it cannot take.  Pure: no ROS."""
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip('numba')

from swarm_core.laws.paper.compiled_step import CompiledStep, fits  # noqa: E402
from swarm_core.laws.paper.compiled_sums import COMPILED  # noqa: E402
from swarm_core.laws.paper.laws import PAPER_LAWS  # noqa: E402
from swarm_core.model.frenet import frame_from_quaternion, quaternion_from_heading  # noqa: E402
from swarm_core.model.integrate import zoh_step  # noqa: E402
from swarm_core.step import alive_control  # noqa: E402

LAWS = {kind: cls() for kind, cls in PAPER_LAWS.items()} | {
    'homotopy_gain': PAPER_LAWS['homotopy']().with_parameters(leader_gain=3.0, q0=0.5, cutoff_radius=1.2),
    'target_normalised': PAPER_LAWS['target']().with_parameters(target_normalised=True, target_gain=2.0),
}


def numpy_step(law, bank, rows, dt, lam, flags, steering, x, y, qz, qw, target):
    """The same step through numpy (what `ContainerCore.controls` and `advance` do)."""
    pos = np.stack([x, y], axis=1)
    cos_t, sin_t = frame_from_quaternion(qz, qw)
    pos[rows], cos_t[rows], sin_t[rows] = bank.pos, bank.cos, bank.sin
    u = alive_control(pos, cos_t, sin_t, rows, law, lam, flags, steering[rows], target, None,
                      pairs=lambda _pos: COMPILED)
    moved = np.where(np.isfinite(u), u, 0.0)
    p, th = zoh_step(bank.pos, bank.theta, moved, dt)
    qz_k, qw_k = quaternion_from_heading(th)
    return u, p, th, qz_k, qw_k, frame_from_quaternion(qz_k, qw_k)


def bank_of(rng, pos, theta):
    qz, qw = quaternion_from_heading(theta)
    c, s = frame_from_quaternion(qz, qw)
    return SimpleNamespace(pos=pos.copy(), theta=theta.copy(), qz=qz, qw=qw, cos=c, sin=s)


@pytest.mark.parametrize('kind', LAWS)
def test_random_tables_give_the_numpy_steps_bits(kind):
    law, rng = LAWS[kind], np.random.default_rng(sum(map(ord, kind)))
    step = CompiledStep()
    for trial in range(60):
        n = int(rng.integers(2, 40))
        spread = rng.choice([0.5, 3.0, 20.0])
        pos = rng.normal(size=(n, 2)) * spread
        if trial % 7 == 0:                          # two leaders at the same distance (a tie)
            pos[1] = -pos[0]
        theta = rng.uniform(-8, 8, n)
        qz, qw = quaternion_from_heading(theta)
        flags = np.zeros(n, bool) if trial % 5 == 0 else rng.random(n) < 0.3
        if trial % 7 == 0:
            flags[:2] = True
        steering = rng.normal(size=n) * 0.1
        lam = [0.0, 1.0, float(rng.random())][trial % 3]
        target = None if trial % 4 == 0 else rng.normal(size=2) * spread
        rows = np.sort(rng.choice(n, size=int(rng.integers(1, n + 1)), replace=False)).astype(np.intp)
        dt = [0.1, 0.05][trial % 2]
        own = bank_of(rng, pos[rows] + rng.normal(size=(rows.size, 2)) * 1e-3, theta[rows] + 1e-3)
        want = numpy_step(law, own, rows, dt, lam, flags, steering, pos[:, 0], pos[:, 1], qz, qw, target)
        bank = bank_of(rng, own.pos, own.theta)
        u, _ = step(law, bank, rows, dt, lam, flags, steering, pos[:, 0].copy(), pos[:, 1].copy(), qz, qw, target)
        got = (u, bank.pos, bank.theta, bank.qz, bank.qw, (bank.cos, bank.sin))
        for name, a, b in zip(('u', 'pos', 'theta', 'qz', 'qw', 'frame'), got, want):
            np.testing.assert_array_equal(a, b, err_msg=f'{kind}, trial {trial}: {name}')


def test_what_it_cannot_take():
    law = LAWS['homotopy'].with_parameters(barrier_gain=0.5)
    alive, some = np.ones(3, bool), np.array([True, False, True])
    assert fits(law, None, None, None, alive) and fits(law, None, None, None, np.zeros(0, bool))
    assert fits(law, np.zeros(2), np.zeros((0, 2)), None, alive)
    assert not fits(law, None, None, None, some)                              # a table of the alive
    assert not fits(law, None, None, ((0.0, 0.0), 1.0, False, None), alive)  # a rendezvous
    assert not fits(law, None, np.ones((3, 2)), None, alive)                  # a barrier sensed
    assert fits(law.with_parameters(barrier_gain=0.0), None, np.ones((3, 2)), None, alive)

    class Mine(PAPER_LAWS['homotopy']):             # a subclass may change the law: numpy runs it
        kind = 'mine'
    assert not fits(Mine(), None, None, None, alive)
