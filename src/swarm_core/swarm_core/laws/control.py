"""The one call every engine makes (no ROS): u_k of some receivers from a table of agent states,
by any law (the paper's, a shipped one, a blend, a user's); in three dimensions (u_k, v_k)."""
from __future__ import annotations

from swarm_core.laws.base import Law


def swarm_control(pos, cos_t, sin_t, receivers, law: Law, *, lambda_=0.0, is_leader=None, steering=None,
                  target=None, barrier=None, pairs=None, nearest=None, t=None):
    """Curvature controls u_k of the receivers: ``law.evaluate`` (`Law.evaluate`: a view for
    `control`, checked; the paper's laws: their own sums, `laws.paper`).

    pos (N, 2), cos_t, sin_t (N,): the table of agent states (frames from
    `swarm_core.model.frenet.heading_frame` or `frame_from_quaternion`).
    receivers (K,): table rows of the agents whose control is wanted.
    lambda_: the homotopy parameter λ; is_leader (N,) bool: leader flags; steering (K,): s_k of
    each receiver (read where the receiver is a leader).
    target (2,), barrier (m, 2): world geometry, or None (the paper's terms, eq. 15, 16).
    pairs: what the law sums over, from its `Law.pair_list` (None: the whole table).
    nearest (K,): with pairs, each receiver's nearest leader l(k) as a table row (−1: none),
    where the table is not one shared view of the swarm (a radio's beliefs).
    t: the sim time, for a law's view.
    The same inputs in the same mode give bit-identical results whatever K is, which is what
    makes an agent node's u equal the batch engine's.
    """
    return law.evaluate(pos, cos_t, sin_t, receivers, lambda_=lambda_, is_leader=is_leader, steering=steering,
                        target=target, barrier=barrier, pairs=pairs, nearest=nearest, t=t)


def natural_control(pos, frames, receivers, law: Law, *, lambda_=0.0, is_leader=None, steering=None,
                    target=None, barrier=None, ground=None, t=None):
    """(u_k, v_k) (K, 2) of the receivers in three dimensions: ``law.evaluate_natural``.

    pos (N, 3); frames (x, y, z), each (N, 3), from `swarm_core.model.natural`; steering (K, 2):
    s_k = (s_u, s_v) of each receiver; target (3,), barrier (m, 3), ground (the floor's height)
    or None.  The law must have 3 in its ``dims``."""
    return law.evaluate_natural(pos, frames, receivers, lambda_=lambda_, is_leader=is_leader, steering=steering,
                                target=target, barrier=barrier, ground=ground, t=t)
