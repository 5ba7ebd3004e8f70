"""A user's law: Kuramoto alignment with the neighbours within w (docs/laws.md).

    law: {kind: laws/alignment.py:Alignment, gain: 0.3}
"""
import numpy as np

from swarm_core.laws import Law, param


class Alignment(Law):
    """Kuramoto alignment with the neighbours within w."""
    gain = param(0.1, lo=0.0, hi=10.0, doc='coupling K')

    def control(self, view):
        # view.pos (N, 2), view.theta (N,), view.receivers (K,) rows of the table,
        # view.cutoff_radius, view.lam, view.t, view.is_leader (N,), view.steering (K,)
        d = view.pos[view.receivers, None, :] - view.pos[None, :, :]
        near = (d ** 2).sum(axis=2) < view.cutoff_radius ** 2          # (K, N), itself included
        diff = np.sin(view.theta[None, :] - view.theta[view.receivers, None])
        return self.gain * (near * diff).sum(axis=1)
