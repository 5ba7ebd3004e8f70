"""λ schedules and leader steering programs (no ROS): λ(t) and s_k(t).

The commander's decisions that use them are in `swarm_core.command.plan`.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np

RAMP_SHAPES = ('smoothstep', 'linear', 'step', 'tanh')


def ramp_shape(x, shape: str):
    """Normalised ramp profile on x ∈ [0, 1] → [0, 1] (C¹ 'smoothstep' 3x² − 2x³ by default)."""
    x = np.clip(x, 0.0, 1.0)
    if shape == 'smoothstep':
        return x * x * (3.0 - 2.0 * x)
    if shape == 'linear':
        return x
    if shape == 'step':
        return np.where(x > 0.0, 1.0, 0.0)
    if shape == 'tanh':  # tanh profile rescaled to hit 0 and 1 exactly at the ends
        return 0.5 * (np.tanh(6.0 * (x - 0.5)) / math.tanh(3.0) + 1.0)
    raise ValueError(f'ramp shape must be one of {RAMP_SHAPES}, got {shape!r}')


class LambdaSchedule:
    """λ(t) ∈ [0, 1]; subclasses implement `value`."""

    def value(self, t: float) -> float:  # pragma: no cover - interface
        raise NotImplementedError


@dataclass(frozen=True)
class ConstantLambda(LambdaSchedule):
    level: float = 0.0

    def value(self, t):
        return self.level


@dataclass(frozen=True)
class TanhWindow(LambdaSchedule):
    """λ(t) = low + (high − low)·½[tanh((t − rise_at)/τ) − tanh((t − fall_at)/τ)]: smooth,
    up near t = rise_at, down near t = fall_at (docs/model.md: τ = 30 gives a clean split)."""

    rise_at: float = 400.0
    fall_at: float = 600.0
    tau: float = 30.0
    low: float = 0.0
    high: float = 1.0

    def value(self, t):
        bump = 0.5 * (math.tanh((t - self.rise_at) / self.tau) - math.tanh((t - self.fall_at) / self.tau))
        return self.low + (self.high - self.low) * bump


@dataclass(frozen=True)
class Ramp:
    """From whatever λ is at ``start``, go to ``to`` over ``duration`` with ``shape``."""

    start: float
    to: float
    duration: float = 20.0
    shape: str = 'smoothstep'


@dataclass
class RampSchedule(LambdaSchedule):
    """Piecewise ramps from an initial level; a ramp that starts before the previous one has
    finished starts from the value reached then (so live set-points chain smoothly).

    Linear time over a run: a ramp is inserted in start order (after those with the same
    start), and `value` keeps the level reached when the next ramp took over (``_done`` ramps
    folded into ``_level``), so a run with many set-points does not re-walk them all at every
    step; the same sums in the same order as walking from the first ramp."""

    initial: float = 0.0
    ramps: list = field(default_factory=list)
    _done: int = field(default=0, init=False, repr=False, compare=False)
    _level: float = field(default=math.nan, init=False, repr=False, compare=False)

    def then(self, start: float, to: float, duration: float = 20.0, shape: str = 'smoothstep'):
        """Append a ramp (the commander's live set-point) and return self."""
        ramp_shape(0.0, shape)  # validates the shape name
        i = bisect.bisect_right(self.ramps, float(start), key=lambda r: r.start)
        self.ramps.insert(i, Ramp(float(start), float(to), float(duration), shape))
        if i <= self._done:
            self._done = 0               # inserted before what is folded: fold again
        return self

    def value(self, t):
        ramps = self.ramps
        if self._done == 0 or t < ramps[self._done].start:
            self._done, self._level = 0, self.initial
        level = self._level
        for i in range(self._done, len(ramps)):
            r = ramps[i]
            if t < r.start:
                break
            nxt = ramps[i + 1].start if i + 1 < len(ramps) else math.inf
            upto = min(t, nxt)
            x = 1.0 if r.duration <= 0 else (upto - r.start) / r.duration
            level = level + (r.to - level) * float(ramp_shape(x, r.shape))
            if t >= nxt:                 # ramp i is over for every later t: fold it
                self._done, self._level = i + 1, level
        return level


class LiveSchedule(LambdaSchedule):
    """A schedule with live set-points: the base schedule until the first set-point; from
    then on smooth ramps from the value reached to each new set-point (`RampSchedule`)."""

    def __init__(self, base: LambdaSchedule):
        self.base = base
        self.override: RampSchedule | None = None

    def set_point(self, t: float, to: float, duration: float, shape: str = 'smoothstep'):
        if self.override is None:
            self.override = RampSchedule(initial=float(self.base.value(t)))
        self.override.then(t, to, duration, shape)

    def value(self, t):
        return self.base.value(t) if self.override is None else self.override.value(t)


class SteeringProgram:
    """A leader's explicit steering program s_k (eq. 11, 14): curvature as a function of
    time and of the leader's own state."""

    def value(self, t: float, pos, heading: float) -> float:  # pragma: no cover - interface
        """s_k at time t for a leader at ``pos`` with ``heading`` = atan2(sin θ, cos θ)."""
        raise NotImplementedError


@dataclass(frozen=True)
class ConstantSteering(SteeringProgram):
    """Constant curvature, e.g. the paper's s1 = 0.01, s2 = −0.01."""

    curvature: float = 0.0

    def value(self, t, pos=None, heading=None):
        return self.curvature


@dataclass(frozen=True)
class SinusoidSteering(SteeringProgram):
    """s(t) = offset + amplitude · sin(2π t / period + phase)."""

    amplitude: float = 0.01
    period: float = 200.0
    phase: float = 0.0
    offset: float = 0.0

    def value(self, t, pos=None, heading=None):
        return self.offset + self.amplitude * math.sin(2.0 * math.pi * t / self.period + self.phase)


@dataclass(frozen=True)
class HelixSteering(SteeringProgram):
    """A 3D leader's program s = κ (cos(τt + phase), sin(τt + phase)) in its own (y, z): the
    curvatures rotate at rate τ, so the leader alone flies a helix of curvature κ, torsion τ."""

    curvature: float = 0.01
    torsion: float = 0.01
    phase: float = 0.0

    def value(self, t, pos=None, heading=None):
        a = self.torsion * t + self.phase
        return (self.curvature * math.cos(a), self.curvature * math.sin(a))


@dataclass(frozen=True)
class WaypointSteering(SteeringProgram):
    """Pursuit of a point: s = clip(gain · bearing error, ±max_curvature), the bearing error
    being the angle from the heading x_k to the direction of the waypoint."""

    point: tuple = (0.0, 0.0)
    gain: float = 0.05
    max_curvature: float = 0.05

    def value(self, t, pos, heading):
        bearing = math.atan2(self.point[1] - pos[1], self.point[0] - pos[0])
        err = math.remainder(bearing - heading, 2.0 * math.pi)
        return max(-self.max_curvature, min(self.max_curvature, self.gain * err))
