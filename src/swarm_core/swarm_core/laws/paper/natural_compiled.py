"""The 3D pair sums of large swarms, compiled (numba) and on every core (no ROS).

Σ_j W_jk g_jk of `natural_sums.pair_sums_3d`, read in each receiver's (y, z) as there, one
receiver per iteration of a ``prange`` loop: over every other agent where pairs beyond w carry
weight (eq. 4, 8, 13-14 with q > 0), or over the agents of the 3 × 3 × 3 cells of side w around
the receiver (a 3D cell list; eq. 9-11, 15), where only pairs within w do.  The same terms as
the numpy sums, added in another order: equal to them to rounding (the tests ask for 1e-9), not
bit for bit.  The self pair and coincident pairs add 0, as there.

Taken by the paper's laws in 3D from `compiled_sums.COMPILED_LIMIT` agents on, the planar rule
(`use_compiled`); numba is imported here only, on first use.
"""
from __future__ import annotations

import numpy as np

from swarm_core.laws.paper import compiled_sums


def use_compiled(n: int, sums: str = 'auto') -> bool:
    """Whether the 3D sums of a table of n agents are compiled: ``sums`` 'compiled' or 'numpy'
    as a run chose (`compiled_sums.run_sums`, the planar rule), or 'auto': from
    `compiled_sums.COMPILED_LIMIT` agents on; never without numba."""
    if sums not in ('auto', 'compiled', 'numpy'):
        raise ValueError(f"sums must be auto, compiled or numpy, got {sums!r}")
    if sums == 'numpy' or sums == 'auto' and n < compiled_sums.COMPILED_LIMIT:
        return False                                # first: looking numba up costs ~0.1 ms
    return compiled_sums.available()


def compiled_controls_3d(law, pos, frames, receivers, lam, q0, leaders):
    """(Σ_j W_jk g_jk·y_k, Σ_j W_jk g_jk·z_k) (K, 2) of the receivers: the pair term of eq. 4, 8,
    9, 13-15 read in each receiver's normal plane.  leaders (N,) bool or None; l(k) is the
    nearest leader (Euclidean, ties to the lower row), as in `natural_sums.nearest_leader_3d`."""
    from swarm_core.laws.paper import natural_compiled_kernels as kernels
    k = receivers.size
    recv = receivers.astype(np.int64)
    coords = tuple(np.ascontiguousarray(a) for f in (pos, *frames) for a in f.T)
    target = bool(law.avoidance_only)
    if leaders is None:
        far = np.full(k, 0.0 if target else q0 * (1.0 - lam))
        partner = np.full(k, -1, dtype=np.int64)
    else:                           # q0 beyond w for leaders, q0 (1 − λ) for followers (eq. 13)
        recv_leader = leaders[receivers]
        far = np.where(recv_leader, q0, q0 * (1.0 - lam))
        partner = kernels.nearest_rows_3d(*coords[:3], recv, np.flatnonzero(leaders).astype(np.int64))
        partner[recv_leader] = -1
    gain = np.full(k, 1.0 if leaders is None else (law.leader_gain - 1.0) * lam + 1.0)
    c = (float(law.alpha), float(law.alpha * law.r0 * law.r0), float(law.eta), float(law.mu), target,
         bool(law.target_normalised))
    w = float(law.cutoff_radius)
    if np.any(far != 0.0) or float(np.prod(np.ptp(pos, axis=0) / w + 3.0)) > 2.0 ** 62:   # cells overflow int64
        return kernels.all_pairs_3d(*coords, recv, float(law.cutoff_radius * law.cutoff_radius), far, partner,
                                    gain, c)
    return kernels.cell_pairs_3d(*coords, recv, w, far, partner, gain, c)
