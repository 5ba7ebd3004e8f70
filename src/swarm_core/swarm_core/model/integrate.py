"""Integrators of the unit-speed Frenet-Serret system (eq. 3), no ROS.

`zoh_step` is the default and what every ROS agent runs: the control u is held over
[t, t + dt) and the agent moves on the exact circular arc.  `rk4_step` integrates the
continuous system (the paper's ODE) and is the reference the ZOH results are checked against.
"""
from __future__ import annotations

import numpy as np

#: the integrators a run may use: the exact zero-order-hold step, and RK4 as the reference
INTEGRATORS = ('zoh', 'rk4')


def chosen_integrator(name: str) -> str:
    """``name`` if it is one of `INTEGRATORS`; ValueError naming it otherwise."""
    if name not in INTEGRATORS:
        raise ValueError(f'integrator must be zoh or rk4, got {name!r}')
    return name


def noise_rng(seed: int, index: int) -> np.random.Generator:
    """Agent ``index``'s own noise stream of a run with ``seed`` (the same in the batch engine
    and its node): one place for its key."""
    return np.random.default_rng([seed, 7919, index])


def sinc(z):
    """sin(z)/z with sinc(0) = 1 (unnormalised), as (sin z + [z = 0]) / (z + [z = 0])."""
    z = np.asarray(z, dtype=float)
    if np.count_nonzero(z) == z.size:       # no zero: the same numbers in two numpy calls
        return np.sin(z) / z
    zero = z == 0.0
    return (np.sin(z) + zero) / (z + zero)


def zoh_step(pos, theta, u, dt):
    """One zero-order-hold step (exact arc for constant u, docs/model.md):

    θ' = θ + u dt,  r' = r + dt sinc(u dt/2) (cos(θ + u dt/2), sin(θ + u dt/2)).
    Works for any number of agents (arrays (N, 2), (N,), (N,)); returns new (pos, theta).
    """
    half = np.multiply(u, 0.5 * dt)                             # u dt/2
    mid = theta + half
    chord = sinc(half) * dt                                     # dt sinc(u dt/2)
    step = np.empty((len(half), 2))
    np.cos(mid, out=step[:, 0])
    np.sin(mid, out=step[:, 1])
    flat = step.reshape(-1)                                     # (cos, sin) · chord, without
    np.multiply(flat, chord.repeat(2), out=flat)                # numpy's broadcasting (n = 6)
    np.add(step, pos, out=step)
    return step, theta + 2.0 * half


def rk4_step(pos, theta, t, dt, control):
    """One classic RK4 step of dr/dt = (cos θ, sin θ), dθ/dt = u(t, r, θ).

    ``control(t, pos, theta)`` returns u for all agents."""
    def f(tt, p, th):
        return np.stack([np.cos(th), np.sin(th)], axis=1), control(tt, p, th)

    k1p, k1t = f(t, pos, theta)
    k2p, k2t = f(t + dt / 2, pos + dt / 2 * k1p, theta + dt / 2 * k1t)
    k3p, k3t = f(t + dt / 2, pos + dt / 2 * k2p, theta + dt / 2 * k2t)
    k4p, k4t = f(t + dt, pos + dt * k3p, theta + dt * k3t)
    new_pos = pos + dt / 6 * (k1p + 2 * k2p + 2 * k3p + k4p)
    new_theta = theta + dt / 6 * (k1t + 2 * k2t + 2 * k3t + k4t)
    return new_pos, new_theta
