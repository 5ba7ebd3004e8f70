"""The paper's laws (no ROS): Morgan & Schwartz's global, local, leader-following, homotopy and
target laws as `Law`s (`laws`), their world terms, target and barrier (`terms`, eq. 15-16),
their parameters (`parameters`) and their fast paths beside them: the pair sums (`pair_sums`),
compiled pair sums for large swarms (`compiled_sums`) and a whole run in compiled code for
the fast engine (`fast_run`, `fast_run_kernels`)."""
from swarm_core.laws.paper.laws import (
    PAPER_LAWS,
    WORLD_KEYS,
    Global,
    Homotopy,
    LeaderFollowing,
    Local,
    PaperLaw,
    Target,
)
from swarm_core.laws.paper.parameters import DEFAULTS, LAW_KINDS, LAW_TABLE
from swarm_core.laws.paper.terms import barrier_term, target_term

__all__ = ['DEFAULTS', 'Global', 'Homotopy', 'LAW_KINDS', 'LAW_TABLE', 'LeaderFollowing', 'Local', 'PAPER_LAWS',
           'PaperLaw', 'Target', 'WORLD_KEYS', 'barrier_term', 'target_term']
