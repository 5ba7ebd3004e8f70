"""The agent model in three dimensions (no ROS): unit-speed agents in natural frames.

Agent k has a position r_k and a right-handed orthonormal frame [x_k y_k z_k]: x_k is its
heading, y_k and z_k the two normals.  It steers by two curvatures (u_k, v_k):

    dr/dt = x,   dx/dt = u y + v z,   dy/dt = −u x,   dz/dt = −v x        (natural frames)

The frame never spins about x.  The planar model (eq. 3) is the case z = e_z, v = 0.
Arrays: r, x, y, z (N, 3); u, v (N,).  docs/model.md, "Three dimensions", states the model.
"""
from __future__ import annotations

import importlib.util

import numpy as np

from swarm_core.model.integrate import sinc

#: below this |κ dt| the step uses the series of sinc and (1 − cos)/κ² (no 0/0)
SMALL_TURN = 1e-4
#: the engine re-orthonormalises every frame (Gram-Schmidt from x) every this many steps
ORTHONORMALISE_EVERY = 100
#: from this many agents on the step's arithmetic is compiled (`natural_kernels`, the same bits)
COMPILED_STEP_LIMIT = 4096


def initial_frames(headings):
    """The initial-frame rule: x = unit(heading), y = unit(e_z × x) (e_y where x ∥ e_z),
    z = x × y.  A planar heading gives y in the plane and z = e_z.  headings (N, 3), nonzero."""
    x = np.asarray(headings, dtype=float)
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    y = np.stack([-x[:, 1], x[:, 0], np.zeros(len(x))], axis=1)           # e_z × x
    norm = np.linalg.norm(y, axis=1)
    vertical = norm < 1e-9
    if vertical.any():                                                     # x ∥ e_z: e_y
        ey = np.array([0.0, 1.0, 0.0])
        y[vertical] = ey - x[vertical] * (x[vertical] @ ey)[:, None]
        norm = np.linalg.norm(y, axis=1)
    y = y / norm[:, None]
    return x, y, np.cross(x, y)


def orthonormalise(x, y):
    """Gram-Schmidt from x: (x, y, z) orthonormal and right-handed, x and the plane (x, y) kept."""
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    y = y - x * np.einsum('nc,nc->n', x, y)[:, None]
    y = y / np.linalg.norm(y, axis=1, keepdims=True)
    return x, y, np.cross(x, y)


def _turn_factors(kappa, dt):
    """S = sin(κdt)/κ and C = (1 − cos κdt)/κ², each with its series for small κdt."""
    z = kappa * dt
    small = np.abs(z) < SMALL_TURN
    if not small.any():                                                    # no series, no zero: sinc inline
        half = 0.5 * z
        half = np.sin(half) / half
        return dt * (np.sin(z) / z), 0.5 * dt * dt * half * half
    S = dt * sinc(z)
    half = sinc(0.5 * z)
    C = 0.5 * dt * dt * half * half                                        # 2 sin²(κdt/2)/κ²
    z2 = z[small] * z[small]
    S[small] = dt * (1.0 - z2 / 6.0)
    C[small] = dt * dt * (0.5 - z2 / 24.0)
    return S, C


def natural_step(r, x, y, z, u, v, dt):
    """One exact zero-order-hold step: (u, v) held over dt, R' = R Exp(dt ω̂), ω = (0, −v, u).

    With κ = √(u² + v²), the turn n κ = u y + v z, S = sin(κdt)/κ, C = (1 − cos κdt)/κ²:
        r' = r + S x + C (u y + v z)
        x' = cos(κdt) x + S (u y + v z)
        y' = y − S u x − C u (u y + v z),   z' = z − S v x − C v (u y + v z)
    (an arc of the circle of radius 1/κ; the planar arc of `integrate.zoh_step` where v = 0).
    Returns (r', x', y', z')."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    S, C = _turn_factors(np.hypot(u, v), dt)
    if u.size >= COMPILED_STEP_LIMIT and importlib.util.find_spec('numba') is not None:
        from swarm_core.model.natural_kernels import frame_step
        f = [np.ascontiguousarray(a, dtype=float) for a in (r, x, y, z)]
        return tuple(frame_step(*f, np.ascontiguousarray(u), np.ascontiguousarray(v), S, C))
    turn = u[:, None] * y + v[:, None] * z                                 # κ n
    cos_k = 1.0 - C * (u * u + v * v)                                      # cos κdt
    r_new = r + S[:, None] * x + C[:, None] * turn
    x_new = cos_k[:, None] * x + S[:, None] * turn
    y_new = y - (S * u)[:, None] * x - (C * u)[:, None] * turn
    z_new = z - (S * v)[:, None] * x - (C * v)[:, None] * turn
    return r_new, x_new, y_new, z_new


def natural_rates(x, y, z, u, v):
    """(dr, dx, dy, dz)/dt of the natural-frame equations."""
    return x, u[:, None] * y + v[:, None] * z, -u[:, None] * x, -v[:, None] * x


def natural_rk4_step(r, x, y, z, t, dt, control):
    """One classic RK4 step of the natural-frame equations (the reference integrator), then
    Gram-Schmidt (`orthonormalise`).  ``control(t, r, x, y, z)`` returns (u, v) as (N, 2)."""
    state = (r, x, y, z)

    def f(tt, s):
        uv = np.asarray(control(tt, *s), dtype=float)
        return natural_rates(s[1], s[2], s[3], uv[:, 0], uv[:, 1])

    k1 = f(t, state)
    k2 = f(t + dt / 2, tuple(a + dt / 2 * b for a, b in zip(state, k1)))
    k3 = f(t + dt / 2, tuple(a + dt / 2 * b for a, b in zip(state, k2)))
    k4 = f(t + dt, tuple(a + dt * b for a, b in zip(state, k3)))
    r, x, y, z = (a + dt / 6 * (p + 2 * q + 2 * s + w) for a, p, q, s, w in zip(state, k1, k2, k3, k4))
    return (r, *orthonormalise(x, y))


def quaternion_from_frame(x, y, z):
    """(qx, qy, qz, qw) (N,) each of the rotations R = [x y z] (columns: the frames (N, 3)),
    qw ≥ 0 (Shepperd's method: the largest of 1 + trace, 1 + 2R_ii − trace first).  A planar
    frame (x = (cos θ, sin θ, 0), z = e_z) gives (0, 0, sin θ/2, cos θ/2) up to sign."""
    x, y, z = (np.asarray(f, float).reshape(-1, 3) for f in (x, y, z))
    m00, m10, m20 = x.T
    m01, m11, m21 = y.T
    m02, m12, m22 = z.T
    cand = np.stack([1.0 + m00 + m11 + m22, 1.0 + m00 - m11 - m22, 1.0 - m00 + m11 - m22, 1.0 - m00 - m11 + m22])
    best = cand.argmax(axis=0)
    s = 2.0 * np.sqrt(np.maximum(cand[best, np.arange(len(best))], 1e-300))
    q = np.empty((4, len(best)))                                           # qw, qx, qy, qz
    rows = (
        (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s),
        ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s),
        ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s),
        ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s),
    )
    for b, row in enumerate(rows):
        pick = best == b
        for i in range(4):
            q[i, pick] = row[i][pick]
    q *= np.where(q[0] < 0.0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=0)
    return q[1], q[2], q[3], q[0]


def frame_from_quaternion_3d(qx, qy, qz, qw):
    """The frames x, y, z (N, 3) each (the columns of R) of unit quaternions (N,): the inverse
    of `quaternion_from_frame` to rounding."""
    qx, qy, qz, qw = (np.asarray(q, float).reshape(-1) for q in (qx, qy, qz, qw))
    x = np.stack([1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy + qz * qw), 2 * (qx * qz - qy * qw)], axis=1)
    y = np.stack([2 * (qx * qy - qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz + qx * qw)], axis=1)
    z = np.stack([2 * (qx * qz + qy * qw), 2 * (qy * qz - qx * qw), 1 - 2 * (qx * qx + qy * qy)], axis=1)
    return x, y, z
