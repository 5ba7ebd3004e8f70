"""One check per input value, used at every boundary that takes it (no ROS).

A value that reaches the swarm from outside (a scenario file, a CLI argument, a ROS topic or
parameter, a recorded bag) is checked by its one `Bound` here, so every boundary accepts the
same values and rejects the others with the same text; each caller decides only what a
rejection does there (refuse, log and drop, skip).  The scenario schema takes its type of the
value from the same object (`swarm_core.schema.checked`).
"""
from __future__ import annotations

import json
import math
import numbers
import re
from dataclasses import dataclass

#: largest |coordinate| of a position, target, barrier or waypoint (and largest length r0, w):
#: far from overflow, so distances, squares and sums of the law stay finite
MAX_COORD = 1e6
#: largest gain or curvature: u_k and dt·u_k stay finite
MAX_GAIN = 1e6
#: longest sim time (s) of a run, a pause or a ramp: step numbers stay exact integers
MAX_TIME = 1e7
#: most steps of a run (its step count is checked before anything is allocated)
MAX_STEPS = 10_000_000
#: most recorded values a run may hold: (steps + 1) × agents (`check_run_size`; about 40 bytes each)
MAX_AGENT_SAMPLES = 50_000_000


class InputError(ValueError):
    """A value outside its bounds; the message is the `Bound`'s one text."""


@dataclass(frozen=True)
class Bound:
    """A real input: a finite number (not a bool) in the closed range [lo, hi]."""

    name: str           # as error texts name it, e.g. 'λ'
    lo: float
    hi: float
    open_lo: bool = False   # lo itself is refused: the range is (lo, hi]

    def ok(self, value) -> bool:
        """Whether ``value`` is accepted."""
        return (isinstance(value, numbers.Real) and not isinstance(value, bool)
                and math.isfinite(value) and self.hi >= value
                and (value > self.lo if self.open_lo else value >= self.lo))

    def error(self, value) -> str:
        """The one text that rejects ``value``."""
        return (f'{self.name}={value!r}: must be a finite number in '
                f'{"(" if self.open_lo else "["}{self.lo:g}, {self.hi:g}]')

    def check(self, value) -> float:
        """``value`` as a float, or InputError with `error`."""
        if not self.ok(value):
            raise InputError(self.error(value))
        return float(value)


#: the homotopy parameter λ (eq. 12-14)
LAMBDA_BOUND = Bound('λ', 0.0, 1.0)
#: a leader's steering curvature s_k (eq. 11, 14)
STEERING_BOUND = Bound('steering', -MAX_GAIN, MAX_GAIN)
#: how long a paused (frozen) agent stays paused, sim s
PAUSE_BOUND = Bound('pause seconds', 0.0, MAX_TIME, open_lo=True)
#: the duration of a λ ramp, sim s (0: a jump)
RAMP_BOUND = Bound('ramp', 0.0, MAX_TIME)
#: the control period / integration step, sim s
DT_BOUND = Bound('dt', 1e-6, 10.0)
#: the length of a run, sim s
DURATION_BOUND = Bound('duration', 0.0, MAX_TIME, open_lo=True)


def check_run_size(steps: int, agents: int) -> None:
    """InputError unless a run of ``steps`` steps of ``agents`` agents is within `MAX_STEPS`
    and `MAX_AGENT_SAMPLES` (the world records every step): checked when the scenario is
    validated, before a run allocates its records, so an absurd one is one line, not a
    MemoryError."""
    if steps > MAX_STEPS:
        raise InputError(f'{steps} steps: a run has at most {MAX_STEPS} (raise dt or shorten the duration)')
    samples = (steps + 1) * agents
    if samples > MAX_AGENT_SAMPLES:
        raise InputError(f'{steps} steps of {agents} agents: {samples} recorded values, at most '
                         f'{MAX_AGENT_SAMPLES} (shorten the run or raise dt)')


#: deepest nesting of [ and { a JSON input may have (a command or request has 2 or 3)
MAX_JSON_DEPTH = 32
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_NOT_BRACKET = re.compile(r'[^\[\]{}]+')


def _number(text):
    x = float(text)
    if not math.isfinite(x):
        raise ValueError(f'{text} is not a finite number')
    return x


def _no_constant(name):
    raise ValueError(f'{name} is not a number')


def json_value(text: str, max_chars: int):
    """The value of a JSON text from outside (a request, an announcement, a replayed event, a
    cache row); ValueError for one longer than ``max_chars``, nested deeper than
    `MAX_JSON_DEPTH`, not JSON, or holding a number that is not finite (NaN, 1e999).  The
    nesting is measured before parsing (strings out, brackets counted), so ``[[[[…`` is
    refused without recursion."""
    if len(text) > max_chars:
        raise ValueError(f'{len(text)} characters: at most {max_chars}')
    brackets = _NOT_BRACKET.sub('', _JSON_STRING.sub('', text))
    if len(brackets) > MAX_JSON_DEPTH:
        depth = 0
        for ch in brackets:
            depth += 1 if ch in '[{' else -1
            if depth > MAX_JSON_DEPTH:
                raise ValueError(f'nested deeper than {MAX_JSON_DEPTH} levels')
    return json.loads(text, parse_float=_number, parse_constant=_no_constant)
