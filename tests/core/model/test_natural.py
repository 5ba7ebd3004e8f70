"""The model in three dimensions (no ROS): the exact step, the frame, the planar reduction."""
import math

import numpy as np

from swarm_core.model.integrate import zoh_step
from swarm_core.model.natural import (
    ORTHONORMALISE_EVERY,
    initial_frames,
    natural_rk4_step,
    natural_step,
    orthonormalise,
)


def _frame_error(x, y, z):
    R = np.stack([x, y, z], axis=2)                     # (N, 3, 3), columns x, y, z
    eye = np.einsum('nji,njk->nik', R, R) - np.eye(3)
    return max(float(np.abs(eye).max()), float(np.abs(np.linalg.det(R) - 1.0).max()))


def test_one_step_matches_the_worked_numbers():
    r, x, y, z = natural_step(np.zeros((1, 3)), np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]),
                              np.array([[0, 0, 1.0]]), np.array([0.3]), np.array([-0.4]), 0.5)
    np.testing.assert_allclose(r[0], [0.494807918509046, 0.037305093947226, -0.049740125262968], atol=1e-14)
    np.testing.assert_allclose(x[0], [0.968912421710645, 0.148442375552714, -0.197923167403618], atol=1e-14)
    np.testing.assert_allclose(y[0], [-0.148442375552714, 0.988808471815832, 0.014922037578891], atol=1e-14)
    np.testing.assert_allclose(z[0], [0.197923167403618, 0.014922037578891, 0.980103949894813], atol=1e-14)


def test_initial_frame_rule():
    x, y, z = initial_frames([[2.0, 0, 0], [0, 0, 3.0], [0.6, 0.8, 0.0], [0, 0.6, 0.8]])
    np.testing.assert_allclose(y[0], [0, 1, 0])
    np.testing.assert_allclose(z[0], [0, 0, 1])
    np.testing.assert_allclose(y[1], [0, 1, 0])          # x ∥ e_z: y = e_y
    np.testing.assert_allclose(z[1], [-1, 0, 0])
    np.testing.assert_allclose(z[2], [0, 0, 1])          # a planar heading: z = e_z
    np.testing.assert_allclose(y[3], [-1, 0, 0])
    np.testing.assert_allclose(z[3], [0, -0.8, 0.6])
    assert _frame_error(x, y, z) < 1e-15


def test_constant_curvatures_fly_a_circle_about_the_stated_centre():
    rng = np.random.default_rng(3)
    n = 5
    x, y, z = initial_frames(rng.normal(size=(n, 3)))
    r = start = rng.uniform(-5, 5, (n, 3))
    u, v = rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n)
    u[0], v[0] = 1e-7, -2e-7                             # the small-κ series
    k2 = u * u + v * v
    centre = r + (u[:, None] * y + v[:, None] * z) / k2[:, None]
    normal = -v[:, None] * y + u[:, None] * z           # the fixed axis b κ
    for i in range(1, 4001):
        r, x, y, z = natural_step(r, x, y, z, u, v, 0.05)
        if i % 500 == 0:
            radius = np.linalg.norm(r - centre, axis=1)
            np.testing.assert_allclose(radius[1:], 1 / np.sqrt(k2[1:]), rtol=1e-9)
            np.testing.assert_allclose(np.einsum('nc,nc->n', r - centre, normal)[1:], 0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(r[0] - start[0]), 4000 * 0.05, rtol=1e-9)   # κ ≈ 2e-7: a line


def test_rotating_curvatures_fly_the_stated_helix():
    kappa, tau, dt, steps = 0.4, 0.3, 0.001, 40000
    x, y, z = initial_frames([[1.0, 0, 0]])
    r = np.zeros((1, 3))
    pts = [r[0]]
    for i in range(steps):
        t = (i + 0.5) * dt                               # the midpoint: second order in dt
        r, x, y, z = natural_step(r, x, y, z, [kappa * math.cos(tau * t)], [kappa * math.sin(tau * t)], dt)
        pts.append(r[0])
    pts = np.array(pts)
    # the axis of a helix of curvature κ, torsion τ: the Darboux vector (τ T + κ B)/√(κ² + τ²)
    axis = tau * x[0] + kappa * np.cross(x[0], kappa * math.cos(tau * steps * dt) * y[0]
                                         + kappa * math.sin(tau * steps * dt) * z[0]) / kappa
    axis /= np.linalg.norm(axis)
    radius, pitch = kappa / (kappa ** 2 + tau ** 2), 2 * math.pi * tau / (kappa ** 2 + tau ** 2)
    along = pts @ axis
    across = pts - along[:, None] * axis
    centre = (across.max(axis=0) + across.min(axis=0)) / 2
    np.testing.assert_allclose(np.linalg.norm(across - centre, axis=1), radius, atol=2e-3)
    speed_along = (along[-1] - along[0]) / (steps * dt)
    np.testing.assert_allclose(speed_along * 2 * math.pi / math.sqrt(kappa ** 2 + tau ** 2), pitch, rtol=1e-3)


def test_the_frame_stays_orthonormal_over_2e5_steps():
    rng = np.random.default_rng(1)
    x, y, z = initial_frames(rng.normal(size=(4, 3)))
    r = np.zeros((4, 3))
    for i in range(1, 200_001):
        u, v = 0.3 * np.sin(1e-3 * i + np.arange(4)), 0.2 * np.cos(7e-4 * i - np.arange(4))
        r, x, y, z = natural_step(r, x, y, z, u, v, 0.05)
        if i % ORTHONORMALISE_EVERY == 0:
            x, y, z = orthonormalise(x, y)
        if i == ORTHONORMALISE_EVERY - 1:
            assert 0 < _frame_error(x, y, z) < 1e-13    # rounding drifts; the projection removes it
    assert _frame_error(x, y, z) < 1e-9


def test_with_v_zero_and_a_planar_start_the_step_is_the_planar_arc():
    rng = np.random.default_rng(2)
    n = 6
    theta = rng.uniform(-3, 3, n)
    pos2 = rng.uniform(-4, 4, (n, 2))
    x, y, z = initial_frames(np.stack([np.cos(theta), np.sin(theta), np.zeros(n)], axis=1))
    r = np.concatenate([pos2, np.zeros((n, 1))], axis=1)
    u = rng.uniform(-0.4, 0.4, n)
    u[0] = 0.0
    for _ in range(2000):
        pos2, theta = zoh_step(pos2, theta, u, 0.05)
        r, x, y, z = natural_step(r, x, y, z, u, np.zeros(n), 0.05)
    np.testing.assert_allclose(r[:, :2], pos2, atol=1e-10)
    assert np.all(r[:, 2] == 0) and np.all(x[:, 2] == 0) and np.all(z[:, :2] == 0)     # stays in the plane
    np.testing.assert_allclose(z[:, 2], 1.0, atol=1e-15)
    np.testing.assert_allclose(x[:, :2], np.stack([np.cos(theta), np.sin(theta)], axis=1), atol=1e-11)


def test_rk4_is_fourth_order_and_agrees_with_the_exact_step():
    def control(t, r, x, y, z):
        return np.stack([0.3 + 0.1 * np.sin(t) + 0 * r[:, 0], -0.2 + 0 * r[:, 0]], axis=1)

    def run(dt, rk4):
        x, y, z = initial_frames([[1.0, 0.2, -0.3]])
        r = np.zeros((1, 3))
        for i in range(int(round(4.0 / dt))):
            if rk4:
                r, x, y, z = natural_rk4_step(r, x, y, z, i * dt, dt, control)
            else:
                uv = control((i + 0.5) * dt, r, x, y, z)
                r, x, y, z = natural_step(r, x, y, z, uv[:, 0], uv[:, 1], dt)
        return r
    ref = run(0.005, True)
    e1, e2 = (np.abs(run(dt, True) - ref).max() for dt in (0.1, 0.05))
    assert 12 < e1 / e2 < 20                              # 2⁴ = 16
    assert np.abs(run(0.005, False) - ref).max() < 1e-5   # the hold at the midpoint: second order
