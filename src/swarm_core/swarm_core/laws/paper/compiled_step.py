"""A whole lockstep step of an agent process's agents in one compiled call (no ROS): the paper's
law over the step's table, the move and the new quaternions, for runs whose pairs are summed
compiled (`compiled_sums.run_sums`).

`row_step` (numba, in `compiled_sums_kernels`) does what `step.alive_control` with the compiled
sums, `integrate.zoh_step` and `agent_core.States.refresh` do, operation for operation, and sums
the pairs with the very kernels the batch engine calls (`all_pairs`, `cell_pairs`).  So an
agent that steps this way holds the same bits as one that steps through numpy, and as
``swarm simulate --compiled on``; the tests compare them on random tables.

It covers the usual step only: the paper's own laws (`PAPER_LAWS`, not a subclass), planar,
the whole table alive, no rendezvous, no barrier term; without a radio, robot or noise
(`ContainerCore` looks at those).  Any other step goes through numpy, to the same bits.
"""
from __future__ import annotations

import numpy as np

from swarm_core.laws.paper.compiled_sums import all_pairs_wanted, warm_up
from swarm_core.laws.paper.laws import PAPER_LAWS

_CLASSES = frozenset(PAPER_LAWS.values())


def fits(law, target, barrier, rendezvous, alive) -> bool:
    """Can `CompiledStep` take this step (else numpy does, to the same bits)?  ``alive``: the step's alive mask
    (empty or all True: the whole table)."""
    return (type(law) in _CLASSES and rendezvous is None and (len(alive) == 0 or bool(alive.all()))
            and (barrier is None or law.barrier_gain == 0.0 or len(barrier) == 0))


def constants(law) -> np.ndarray:
    """The law's numbers as `row_step` reads them: (α, η, μ, r0, w², ℓc, α r0², target law,
    normalised, leader law, w), each formed as `compiled_sums.compiled_moments` forms it."""
    return np.array([law.alpha, law.eta, law.mu, law.r0, law.cutoff_radius ** 2, law.leader_gain,
                     law.alpha * law.r0 * law.r0, law.avoidance_only, law.target_normalised, law.uses_leaders,
                     float(law.cutoff_radius)], dtype=float)


class CompiledStep:
    """The compiled step of one bank of agents (`agent_core.States`) with one law."""

    def __init__(self):
        warm_up()
        from swarm_core.laws.paper.compiled_sums_kernels import row_step
        self.kernel = row_step
        self.law = self.consts = None

    def __call__(self, law, bank, rows, dt, lam, flags, steering, x, y, qz, qw, target):
        """Step the bank's agents (table rows ``rows``) once at the step's λ, flags, s_k, table and
        target; their pos, theta, qz, qw, cos, sin move in place.  Returns (u (K,) as the law
        gave it, the table (pos (N, 2), cos θ, sin θ) it came from)."""
        if law is not self.law:
            self.law, self.consts = law, constants(law)
        lam_e, q0 = law.effective_lambda_q0(lam)
        on = target is not None and law.target_gain != 0.0
        world = np.array([1.0, target[0], target[1], law.target_gain] if on else [0.0, 0.0, 0.0, 0.0])
        leaders = law.uses_leaders and bool(flags.any())
        u = np.empty(rows.size)
        table = self.kernel(x, y, qz, qw, rows, bank.pos, bank.theta, bank.cos, bank.sin, flags, steering, lam_e, q0,
                            self.consts, world, all_pairs_wanted(law, lam_e, q0, leaders), dt, u, bank.qz, bank.qw)
        return u, table
