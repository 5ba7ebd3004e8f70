"""Pair sums of large swarms, compiled (numba) and on every core (no ROS).

The moments (A, B, Hx, Hy, C, S) of `paper.pair_sums._pair_sums_sparse`, one receiver per
iteration of a ``prange`` loop (the receivers are shared among the cores): over every other
agent where pairs beyond w carry weight (eq. 4, 8, 13-14 with q > 0), or over the agents of
the 3 × 3 cells of side w around the receiver (a cell list; eq. 9-11, 15), where only pairs
within w do.  The same terms as the reference, summed in another order: the results equal
the reference to rounding (the tests ask for 1e-9), not bit for bit.  The self pair is left
out (its alignment term c·s_k − s·c_k is 0 up to rounding), and so are coincident pairs
(weight 0, as in the reference's careful pass).

One kernel serves every engine: a receiver's row is summed by the same compiled code in the
same order whichever receivers are asked with it, so an agent container that asks for its own
rows gets the batch engine's sums bit for bit (both with the compiled path on).

Chosen per run (`run_sums`: ``--compiled auto|on|off``): auto takes them from COMPILED_LIMIT
agents on, or where a run's pair work (agents² × steps) reaches COMPILED_WORK; short or small
runs keep the numpy reference.  numba is imported here only, on first use: a process that
never sums compiled never pays for it.
"""
from __future__ import annotations

import importlib.util
import time

import numpy as np

#: from this many receivers on, the batch engine sums pairs with the compiled kernels
COMPILED_LIMIT = 4096
#: from this much pair work on (agents² × steps), ``--compiled auto`` takes the compiled sums:
#: a 1,000-agent run of 50 steps, a 100-agent run of 5,000
COMPILED_WORK = 5e7
#: from this many steps on, ``--compiled auto`` takes the compiled path in lockstep at any n: each
#: agent process then steps in one compiled call (`compiled_step`), which pays for numba's import
#: and kernels (about 1 s of CPU per process) within a few thousand steps (BENCHMARKS.md)
LONG_RUN = 5000
#: what `PaperLaw.evaluate` takes as ``pairs`` for the compiled kernels
COMPILED = 'compiled'
#: the values of ``--compiled`` (swarm simulate, swarm run): auto (`run_sums`), on, off
CHOICES = ('auto', 'on', 'off')
#: the help of ``--compiled``, the same in every command that has it
HELP = ('the pair sums and the agents\' lockstep step in compiled kernels (numba): auto (default) from '
        '4,096 agents on, where agents² × steps reaches 5e7, or from 5,000 steps on; on; off (numpy).  '
        'swarm simulate and swarm run choose alike, so the batch engine and the ROS agents compute the same bits')


def run_sums(n: int, steps: int, choice: str = 'auto', lockstep: bool = True) -> str:
    """How a run of n agents and ``steps`` steps sums its pairs: 'compiled' or 'numpy'.  The
    batch engine and every agent process of a ROS run decide with this function (from the
    same n, steps and choice), so they sum alike.  auto: compiled from COMPILED_LIMIT agents,
    COMPILED_WORK pair work, or (``lockstep``, as the batch engine is) LONG_RUN steps on; a
    realtime run has no compiled step to pay for numba's import there.  on without numba
    installed: 'numpy' (`available`)."""
    if choice not in CHOICES:
        raise ValueError(f'compiled must be one of {", ".join(CHOICES)}, got {choice!r}')
    if choice == 'off' or not available():
        return 'numpy'
    if choice == 'on' or int(n) >= COMPILED_LIMIT or float(n) * float(n) * float(steps) >= COMPILED_WORK \
            or lockstep and int(steps) >= LONG_RUN:
        return 'compiled'
    return 'numpy'


def available() -> bool:
    """Whether numba is installed (without it the reference runs); looked up, not imported."""
    return importlib.util.find_spec('numba') is not None


_WARM = []


def warm_up() -> float:
    """Import numba and load (or compile) the kernels (both sums and `compiled_step`'s) on a
    table of two agents; returns the seconds it took (0 after the first call).  A process that will sum compiled does it
    before its first step, so that the first step is not the one that waits for it."""
    if _WARM:
        return 0.0
    _WARM.append(True)
    t0 = time.perf_counter()
    pos, c = np.array([[0.0, 0.0], [1.0, 0.5]]), np.ones(2)
    rows = np.arange(2)

    class Law:       # the attributes a kernel reads, both couplings
        avoidance_only, target_normalised, alpha, r0, cutoff_radius, leader_gain = False, False, 1.0, 1.0, 2.0, 1.0
    for q0 in (1.0, 0.0):
        compiled_moments(pos, c, c * 0.0, rows, Law, 0.0, q0, None, None)
    from swarm_core.laws.paper.compiled_sums_kernels import row_step  # `compiled_step`'s
    x, y, qz, qw, steering = (np.array(a, float) for a in (pos[:, 0], pos[:, 1], [0.0, 0.0], [1.0, 1.0], [0.0, 0.0]))
    for a in (x, y, qz, qw, steering):      # read-only, as a decoded step message's arrays are
        a.flags.writeable = False
    row_step(x, y, qz, qw, rows[:1], pos[:1].copy(), np.zeros(1), np.ones(1), np.zeros(1), np.zeros(2, bool),
             steering, 0.0, 1.0, np.ones(11), np.zeros(4), True, 0.1, np.empty(1), np.empty(1), np.empty(1))
    return time.perf_counter() - t0


def compiled_moments(pos, cos_t, sin_t, receivers, law, lam, q0, leaders, l_of_k):
    """The moments (6, K) of the receivers (table rows) over the whole table (see the module
    doc); l_of_k (K,): each receiver's nearest leader row, or None without leaders."""
    from swarm_core.laws.paper.compiled_sums_kernels import all_pairs, cell_pairs
    k = receivers.size
    g = law
    target = law.avoidance_only
    if leaders is None:
        far = np.full(k, 0.0 if target else q0 * (1.0 - lam))
        partner = np.full(k, -1, dtype=np.int64)
        gain = np.ones(k)
    else:                           # q0 beyond w for leaders, q0(1 − λ) for followers (eq. 13)
        recv_leader = leaders[receivers]
        far = np.where(recv_leader, q0, q0 * (1.0 - lam))
        partner = np.where(recv_leader, -1, l_of_k).astype(np.int64)
        gain = np.full(k, (law.leader_gain - 1.0) * lam + 1.0)
    x, y = np.ascontiguousarray(pos[:, 0]), np.ascontiguousarray(pos[:, 1])
    args = (np.ascontiguousarray(cos_t, dtype=float), np.ascontiguousarray(sin_t, dtype=float))
    consts = (far, partner, gain, g.alpha, g.alpha * g.r0 * g.r0, target, bool(law.target_normalised))
    rows = np.ascontiguousarray(receivers, dtype=np.int64)
    if all_pairs_wanted(law, lam, q0, leaders is not None):
        return all_pairs(x, y, *args, rows, law.cutoff_radius ** 2, *consts)
    return cell_pairs(x, y, *args, rows, float(law.cutoff_radius), *consts)


def all_pairs_wanted(law, lam, q0, leaders: bool) -> bool:
    """Sum over all pairs (`all_pairs`) rather than the cell list (`cell_pairs`): where a pair
    beyond w carries weight for some agent of the table (q0 (1 − λ) ≠ 0, or leaders and
    q0 ≠ 0).  Decided for the whole table, not for the receivers asked, so that every process
    sums a row the same way whichever of its agents it asks for."""
    if law.avoidance_only:
        return False
    return q0 * (1.0 - lam) != 0.0 or (leaders and q0 != 0.0)
