"""The compiled natural-frame step of large swarms (swarm_core.model.natural_kernels) against the
numpy step: the same numbers, bit for bit, with turns large, small (the series) and zero; taken
from COMPILED_STEP_LIMIT agents on."""
import numpy as np
import pytest

from swarm_core.laws.paper import compiled_sums
from swarm_core.model import natural

pytestmark = pytest.mark.skipif(not compiled_sums.available(), reason='numba is not installed')


def test_the_compiled_step_is_the_numpy_step_bit_for_bit(monkeypatch):
    rng = np.random.default_rng(4)
    n = 5000
    pos = rng.normal(size=(n, 3)) * 40
    frames = natural.initial_frames(rng.normal(size=(n, 3)))
    u = rng.uniform(-1, 1, n) * 10 ** rng.uniform(-8, 0.5, n)
    v = rng.uniform(-1, 1, n) * 10 ** rng.uniform(-8, 0.5, n)
    u[:3] = v[:3] = 0.0
    v[3:9] = 0.0                                            # planar turns
    uv = np.stack([u, v], axis=1)                           # strided columns, as the engine passes them
    monkeypatch.setattr(natural, 'COMPILED_STEP_LIMIT', 1 << 62)
    ref = natural.natural_step(pos, *frames, uv[:, 0], uv[:, 1], 0.05)
    monkeypatch.setattr(natural, 'COMPILED_STEP_LIMIT', n)
    fast = natural.natural_step(pos, *frames, uv[:, 0], uv[:, 1], 0.05)
    for a, b in zip(ref, fast):
        assert a.shape == b.shape == (n, 3)
        np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64))
