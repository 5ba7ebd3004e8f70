"""The Sepulchre-Paley-Leonard laws (no ROS): parallel and circular formations of unit-speed
agents, all-to-all or with the neighbours within w.

Sources: R. Sepulchre, D. A. Paley, N. E. Leonard, "Stabilization of planar collective
motion: all-to-all communication", IEEE TAC 52(5), 2007, and "... with limited communication",
IEEE TAC 53(3), 2008.  With the phase potential U_m = (N/2)|p_mθ|², p_mθ = (1/(mN)) Σ_j e^{imθ_j}:
∂U_m/∂θ_k = (1/(mN)) Σ_j sin(m(θ_j − θ_k)); u_k containing −K_m ∂U_m/∂θ_k balances the m-th
harmonic for K_m > 0 and synchronises it for K_m < 0.

Limited communication (``communication: 1``): sums run over the neighbours within w, and the
Laplacian of that graph replaces N·P in the circular law.  N stays the table size.
"""
from __future__ import annotations

import numpy as np

from swarm_core.laws.base import Law, View, neighbours_within, param

#: ``communication``: 0 all-to-all (2007), 1 the neighbours within w (2008)
ALL_TO_ALL, WITHIN_W = 0, 1


def _weights(view: View, communication: int) -> np.ndarray:
    """(K, N) weights of the sums: 1 for every row (all-to-all) or for the neighbours within w."""
    if communication == ALL_TO_ALL:
        return np.ones((view.receivers.size, len(view.pos)))
    return neighbours_within(view).astype(float)


def phase_gradient(view: View, m: int, weights: np.ndarray) -> np.ndarray:
    """∂U_m/∂θ_k = (1/(mN)) Σ_j w_kj sin(m(θ_j − θ_k)) of each receiver."""
    th = view.theta
    diff = th[None, :] - th[view.receivers, None]
    return (weights * np.sin(m * diff)).sum(axis=1) / (m * len(th))


class ParallelFormation(Law):
    """Parallel (K < 0) or balanced (K > 0) headings: u_k = ω0 − K ∂U_1/∂θ_k (SPL 2007)."""

    kind = 'spl_parallel'
    omega0 = param(0.0, lo=-10.0, hi=10.0, doc='turn rate ω0 every agent adds (rad per unit time)')
    phase_gain = param(-0.1, lo=-100.0, hi=100.0, doc='K: < 0 synchronises headings, > 0 balances them')
    communication = param(ALL_TO_ALL, lo=0, hi=1, integer=True,
                          doc='0: all-to-all (2007); 1: the neighbours within w (2008)')

    def couples_globally(self, lambda_: float) -> bool:
        return self.communication == ALL_TO_ALL

    def control(self, view: View) -> np.ndarray:
        grad = phase_gradient(view, 1, _weights(view, self.communication))
        return self.omega0 - self.phase_gain * grad


class CircularFormation(Law):
    """Agents on one circle of radius 1/ω0 about a common centre, placed by the phase terms:
    u_k = ω0 (1 + κ ⟨e^{iθ_k}, (Pc)_k⟩) − Σ_{m=1..M} K_m ∂U_m/∂θ_k, c_k = r_k + i e^{iθ_k}/ω0
    (SPL 2007; with limited communication (1/N) L c replaces P c, SPL 2008).  K_m is
    ``phase_gain`` for m < M and ``phase_gain_last`` for m = M; M = N with K_m > 0 for m < N
    and K_N < 0 stabilises the splay state."""

    kind = 'spl_circular'
    omega0 = param(0.2, lo=1e-6, hi=10.0, doc='turn rate ω0: the circle has radius 1/ω0')
    kappa = param(1.0, lo=0.0, hi=100.0, doc='κ > 0: gain of the centres to one point')
    harmonics = param(1, lo=1, hi=1000, integer=True, doc='M, the number of phase harmonics')
    phase_gain = param(0.05, lo=-100.0, hi=100.0, doc='K_m for m < M (> 0 balances the m-th harmonic)')
    phase_gain_last = param(0.0, lo=-100.0, hi=100.0, doc='K_M (< 0 synchronises the M-th harmonic)')
    communication = param(ALL_TO_ALL, lo=0, hi=1, integer=True,
                          doc='0: all-to-all (2007); 1: the neighbours within w (2008)')

    def couples_globally(self, lambda_: float) -> bool:
        return self.communication == ALL_TO_ALL

    def circle_turn_rate(self) -> float:
        """ω0, the turn rate of the circle the agents fly (radius 1/ω0): what the outcome
        ``circular_formation`` judges against (`analysis.outcomes`)."""
        return float(self.omega0)

    def centres(self, view: View) -> np.ndarray:
        """c_k = r_k + i e^{iθ_k}/ω0 of every table row, as complex numbers."""
        return view.pos[:, 0] + 1j * view.pos[:, 1] + 1j * (view.cos + 1j * view.sin) / self.omega0

    def control(self, view: View) -> np.ndarray:
        n, recv = len(view.pos), view.receivers
        w = _weights(view, self.communication)
        c = self.centres(view)
        if self.communication == ALL_TO_ALL:
            pc = c[recv] - c.mean()                                      # (P c)_k
        else:
            pc = (w.sum(axis=1) * c[recv] - w @ c) / n                   # (1/N) (L c)_k
        heading = view.cos[recv] + 1j * view.sin[recv]
        u = self.omega0 * (1.0 + self.kappa * (np.conj(heading) * pc).real)
        for m in range(1, self.harmonics + 1):
            gain = self.phase_gain_last if m == self.harmonics else self.phase_gain
            if gain != 0.0:
                u = u - gain * phase_gradient(view, m, w)
        return u
