"""The paper's world terms (no ROS): target seeking (eq. 15) and the sensed barrier (eq. 16),
added to a paper's law's u where the scenario has a target or a barrier and the gain is not 0
(`PaperLaw.evaluate`).  ``law`` is a `PaperLaw`: its gains, w and the terms' settings."""
from __future__ import annotations

import numpy as np


def target_term(pos_k, cos_k, sin_k, target, law):
    """γα(1 − (r0/|r̄_k|)²)(r̄_k·y_k), r̄_k = r̄ − r_k (eq. 15, second line); 0 at the target."""
    dx = target[0] - pos_k[:, 0]
    dy = target[1] - pos_k[:, 1]
    d2 = dx * dx + dy * dy
    inv_d2 = np.divide(1.0, d2, out=np.zeros_like(d2), where=d2 > 0.0)
    across = dy * cos_k - dx * sin_k
    if law.target_normalised:
        across = across * np.sqrt(inv_d2)
    return law.target_gain * law.alpha * (1.0 - law.r0 * law.r0 * inv_d2) * across * (d2 > 0.0)


def barrier_direction(pos_k, barrier, w):
    """Average barrier direction v_k (eq. 16, with b_i − r_k): unit vector, 0 if none sensed."""
    d = barrier[None, :, :] - pos_k[:, None, :]               # (K, m, 2)
    sensed = (d[..., 0] ** 2 + d[..., 1] ** 2) < w * w
    v = (d * sensed[..., None]).sum(axis=1)
    norm = np.hypot(v[:, 0], v[:, 1])
    return np.divide(v, norm[:, None], out=np.zeros_like(v), where=norm[:, None] > 0.0)


def barrier_term(pos_k, cos_k, sin_k, barrier, law):
    """Barrier avoidance (eq. 16): ±s_b (v_k·y_k).

    'ahead' (default): −s_b [v_k·x_k > 0] (v_k·y_k), steering away only while the barrier is
    ahead.  'literal': −s_b sign(v_k·x_k)(v_k·y_k), the paper's sign of v_k·y_k^⊥ with
    y^⊥ = −x."""
    v = barrier_direction(pos_k, barrier, law.cutoff_radius)
    ahead = v[:, 0] * cos_k + v[:, 1] * sin_k
    side = v[:, 1] * cos_k - v[:, 0] * sin_k
    if law.barrier_mode == 'ahead':
        gate = (ahead > 0.0).astype(float)
    else:
        gate = np.sign(ahead)
    return -law.barrier_gain * gate * side


def add_world_terms(u, pos, F, receivers, law, target, barrier):
    """u plus the target term (eq. 15) and the barrier term (eq. 16) where they apply;
    F (2, K): the receivers' (sin θ, cos θ)."""
    if target is not None and law.target_gain != 0.0:
        u = u + target_term(pos[receivers], F[1], F[0], np.asarray(target, float), law)
    if barrier is not None and law.barrier_gain != 0.0 and len(barrier):
        u = u + barrier_term(pos[receivers], F[1], F[0], np.asarray(barrier, float), law)
    return u
