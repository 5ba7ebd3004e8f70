"""Frenet-Serret agent model and the Justh-Krishnaprasad pair term (no ROS).

The model is that of Morgan & Schwartz, "Dynamic coordinated control laws in multiple agent
models".  docs/model.md states it and lists the fixes applied to the paper's text.  Equation
numbers in these comments are the paper's.

Headings travel between agents as a planar quaternion (z = sin(θ/2), w = cos(θ/2)), the
orientation of a ``nav_msgs/Odometry`` pose.  Every frame vector in this package is computed
from that quaternion (`frame_from_quaternion`), in the batch engine and in the ROS agent node
alike, so both see bit-identical frames and their trajectories agree to rounding.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .law_parameters import DEFAULTS


@dataclass(frozen=True)
class PairGains:
    """Constants of the pair term u_jk (eq. 5, 6): ``alpha`` (spacing), ``eta`` (baseline),
    ``mu`` (alignment) and the preferred spacing ``r0``; defaults, ranges: `law_parameters`."""

    alpha: float = DEFAULTS['alpha']
    eta: float = DEFAULTS['eta']
    mu: float = DEFAULTS['mu']
    r0: float = DEFAULTS['r0']


def quaternion_from_heading(theta):
    """Planar unit quaternion (z, w) of heading θ: rotation by θ about the z axis."""
    half = 0.5 * np.asarray(theta, dtype=float)
    return np.sin(half), np.cos(half)


def frame_from_quaternion(qz, qw):
    """Frenet frame of eq. 3 from a planar quaternion: returns (cos θ, sin θ).

    x_k = (cos θ, sin θ), y_k = (−sin θ, cos θ).  cos θ = w² − z², sin θ = 2wz.
    """
    qz = np.asarray(qz, dtype=float)
    qw = np.asarray(qw, dtype=float)
    return qw * qw - qz * qz, 2.0 * qw * qz


def heading_frame(theta):
    """(cos θ, sin θ) of headings θ, computed through the quaternion as agents see it."""
    return frame_from_quaternion(*quaternion_from_heading(theta))


def yaw_from_quaternion(qz, qw):
    """Heading θ in (−π, π] of a planar quaternion (for display and metrics)."""
    return 2.0 * np.arctan2(qz, qw)


def cutoff(rho, q, w):
    """Cutoff function c(ρ, q, w) (eq. 8): 1 where ρ < w, q elsewhere."""
    return np.where(np.asarray(rho) < w, 1.0, q)


def pair_geometry(dx, dy, cos_k, sin_k):
    """Geometry of pairs with r_jk = r_k − r_j = (dx, dy) seen from agent k.

    Returns (ρ², 1/ρ² (0 where ρ = 0), r_jk·x_k, r_jk·y_k), elementwise on broadcastable arrays.
    """
    rho2 = dx * dx + dy * dy
    inv_rho2 = np.divide(1.0, rho2, out=np.zeros_like(rho2), where=rho2 > 0.0)
    along = dx * cos_k + dy * sin_k          # r_jk · x_k
    across = dy * cos_k - dx * sin_k         # r_jk · y_k
    return rho2, inv_rho2, along, across


def pair_terms(dx, dy, cos_k, sin_k, cos_j, sin_j, gains: PairGains):
    """The three terms of u_jk (eq. 5, 6) as (baseline, spacing, alignment).

    baseline  = −η (r̂·x_k)(r̂·y_k)
    spacing   = −f(ρ)(r̂·y_k),  f(ρ) = α(1 − (r0/ρ)²)
    alignment =  μ (x_j·y_k)
    A coincident pair (ρ = 0) contributes 0 in every term, never a NaN.
    """
    rho2, inv_rho2, along, across = pair_geometry(dx, dy, cos_k, sin_k)
    inv_rho = np.sqrt(inv_rho2)
    baseline = -gains.eta * along * across * inv_rho2
    spacing = -gains.alpha * (1.0 - gains.r0 * gains.r0 * inv_rho2) * across * inv_rho
    alignment = gains.mu * (sin_j * cos_k - cos_j * sin_k) * (rho2 > 0.0)
    return baseline, spacing, alignment


def pair_control(dx, dy, cos_k, sin_k, cos_j, sin_j, gains: PairGains):
    """u_jk (eq. 5): the Justh-Krishnaprasad steering of agent k due to agent j.

    The per-pair reference form; `laws.swarm_control` sums the same terms over all pairs
    through per-receiver moments of the pair geometry (`laws._pair_sums_dense`)."""
    baseline, spacing, alignment = pair_terms(dx, dy, cos_k, sin_k, cos_j, sin_j, gains)
    return baseline + spacing + alignment


def avoidance_control(dx, dy, cos_k, sin_k, gains: PairGains, normalised: bool = False):
    """Collision-avoidance pair term of the target law (eq. 15).

    −α(1 − (r0/ρ)²)(r_jk·y_k), with r_jk unnormalised as the paper writes it; with
    ``normalised`` the unit vector r̂ is used instead.  0 for coincident agents.
    """
    rho2, inv_rho2, _, across = pair_geometry(dx, dy, cos_k, sin_k)
    if normalised:
        across = across * np.sqrt(inv_rho2)
    return -gains.alpha * (1.0 - gains.r0 * gains.r0 * inv_rho2) * across * (rho2 > 0.0)
