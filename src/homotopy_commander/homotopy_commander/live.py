"""Live λ set-points on top of a scenario's λ schedule (no ROS)."""
from __future__ import annotations

from swarm_core.schedules import LambdaSchedule, RampSchedule


class LiveSchedule(LambdaSchedule):
    """The scenario's schedule until the first set-point; from then on smooth ramps from
    the value reached to each new set-point (`RampSchedule` chains them)."""

    def __init__(self, base: LambdaSchedule):
        self.base = base
        self.override: RampSchedule | None = None

    def set_point(self, t: float, to: float, duration: float, shape: str = 'smoothstep'):
        if self.override is None:
            self.override = RampSchedule(initial=float(self.base.value(t)))
        self.override.then(t, to, duration, shape)

    def value(self, t):
        return self.base.value(t) if self.override is None else self.override.value(t)
