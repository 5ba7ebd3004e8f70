"""The compiled natural-frame step of large swarms (numba; imported only from
`model.natural.natural_step`, on first use).  The same IEEE operations in the same order as the
numpy step, no fast-math (no fused products): the same numbers, bit for bit."""
import numba as nb
import numpy as np


@nb.njit(parallel=True, cache=True)
def frame_step(r, x, y, z, u, v, S, C):
    """r', x', y', z' (N, 3) of `natural.natural_step`, given S and C (N,) of each agent."""
    n = r.shape[0]
    out = np.empty((4, n, 3))
    for k in nb.prange(n):
        s, c, uk, vk = S[k], C[k], u[k], v[k]
        cos_k = 1.0 - c * (uk * uk + vk * vk)
        su, cu, sv, cv = s * uk, c * uk, s * vk, c * vk
        for i in range(3):
            xi = x[k, i]
            turn = uk * y[k, i] + vk * z[k, i]
            out[0, k, i] = r[k, i] + s * xi + c * turn
            out[1, k, i] = cos_k * xi + s * turn
            out[2, k, i] = y[k, i] - su * xi - cu * turn
            out[3, k, i] = z[k, i] - sv * xi - cv * turn
    return out
