"""One check per input value, used at every boundary that takes it (no ROS).

A value that reaches the swarm from outside (a scenario file, a CLI argument, a ROS topic or
parameter, a recorded bag) is checked by its one `Bound` here, so every boundary accepts the
same values and rejects the others with the same text; each caller decides only what a
rejection does there (refuse, log and drop, skip).  The scenario schema takes its type of the
value from the same object (`scenario_schema.checked`).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

#: largest |coordinate| of a position, target, barrier or waypoint (and largest length r0, w):
#: far from overflow, so distances, squares and sums of the law stay finite
MAX_COORD = 1e6
#: largest gain or curvature: u_k and dt·u_k stay finite
MAX_GAIN = 1e6


class InputError(ValueError):
    """A value outside its bounds; the message is the `Bound`'s one text."""


@dataclass(frozen=True)
class Bound:
    """A real input: a finite number (not a bool) in the closed range [lo, hi]."""

    name: str           # as error texts name it, e.g. 'λ'
    lo: float
    hi: float

    def ok(self, value) -> bool:
        """Whether ``value`` is accepted."""
        return (isinstance(value, numbers.Real) and not isinstance(value, bool)
                and math.isfinite(value) and self.lo <= value <= self.hi)

    def error(self, value) -> str:
        """The one text that rejects ``value``."""
        return f'{self.name}={value!r}: must be a finite number in [{self.lo:g}, {self.hi:g}]'

    def check(self, value) -> float:
        """``value`` as a float, or InputError with `error`."""
        if not self.ok(value):
            raise InputError(self.error(value))
        return float(value)


#: the homotopy parameter λ (eq. 12-14)
LAMBDA_BOUND = Bound('λ', 0.0, 1.0)
