"""The law interface (no ROS): a steering law of unit-speed planar agents as a class.

A law declares its parameters as class attributes (`param`: default, closed range, text) and
computes the curvature u of some receiving agents from a table of agent states (`View`)::

    class Alignment(Law):
        '''Kuramoto alignment with the neighbours within w.'''
        gain = param(0.1, lo=0.0, hi=10.0, doc='coupling K')

        def control(self, view):
            return u          # (K,), one u per receiver

Every engine calls a law through `swarm_control` (`laws.control`), which hands a `Law` the
view and checks what it returns (`Law.evaluate`); the paper's laws keep their compiled paths
there.  Every law has the cutoff radius w (``cutoff_radius``), the range of the radio and the
sensing, which the engines use to choose neighbours.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: w's range, as the paper's law has it (`laws.parameters`)
CUTOFF_RANGE = (1e-9, 1e6)


class LawError(ValueError):
    """A law that cannot be used or that misbehaved; the message names the law and the problem."""


class LawFailed(LawError):
    """A law failed during a run: its `LawError` and the sim time, e.g. ``law x.py:A raised
    RuntimeError: boom (at t = 5.1, step 51)``.  ``trajectory``: the steps done before it (the
    batch engine's `Trajectory`), which a caller saves; it stays behind when the error is
    pickled (a sweep's worker process, a Dask worker)."""

    def __init__(self, message: str, trajectory=None, t: float | None = None):
        super().__init__(message)
        self.trajectory, self.t = trajectory, t

    def __reduce__(self):
        return type(self), (str(self), None, self.t)


def failed_at(err: LawError, t: float | None) -> LawFailed:
    """``err`` as a `LawFailed` at sim time ``t`` (an agent's u of that time)."""
    if isinstance(err, LawFailed):
        return err
    return LawFailed(str(err) if t is None else f'{err} (at t = {float(t):g})', t=t)


# lower case: it is used like a field declaration, ``gain = param(0.1, lo=0, hi=1)``
@dataclass(frozen=True)
class param:
    """One real parameter of a law: its default, closed range [lo, hi] and description."""

    default: float
    lo: float = -1e6
    hi: float = 1e6
    doc: str = ''
    integer: bool = False

    def check(self, law: str, name: str, value) -> float:
        """``value`` as the parameter's type; LawError naming the law and the parameter if it
        is not a number in [lo, hi]."""
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise LawError(f'law {law}: parameter {name} must be a number, got {value!r}')
        if self.integer and float(value) != int(value):
            raise LawError(f'law {law}: parameter {name} must be an integer, got {value!r}')
        v = int(value) if self.integer else float(value)
        if not math.isfinite(v) or not self.lo <= v <= self.hi:
            raise LawError(f'law {law}: parameter {name} = {value!r} is outside [{self.lo:g}, {self.hi:g}]')
        return v


@dataclass
class View:
    """What a law reads: the table of agent states and the inputs of the step.

    pos (N, 2), theta (N,), cos/sin (N,) of θ (from the planar quaternions agents exchange),
    receivers (K,): rows of the table whose u is wanted, cutoff_radius: w, lam: λ, t: the sim
    time (None where the caller has none), is_leader (N,) bool, steering (K,): the receivers'
    leader programs s_k."""

    pos: np.ndarray
    theta: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    receivers: np.ndarray
    cutoff_radius: float
    lam: float
    t: float | None
    is_leader: np.ndarray
    steering: np.ndarray


class Law:
    """A steering law: subclass it, declare `param`s, write `control`."""

    #: what a scenario calls the law (``law: {kind: ...}``); a user law's is its file or module path
    kind: str = ''
    cutoff_radius = param(4.0, lo=CUTOFF_RANGE[0], hi=CUTOFF_RANGE[1],
                          doc='cutoff (communication and sensing) radius w (eq. 8)')

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        if not cls.kind:
            cls.kind = f'{cls.__module__}:{cls.__qualname__}'

    def __init__(self, **values):
        specs = self.param_specs()
        unknown = sorted(set(values) - set(specs))
        if unknown:
            raise LawError(f'law {self.kind}: unknown parameter {unknown[0]!r} '
                           f'(its parameters: {", ".join(specs)})')
        for name, spec in specs.items():
            object.__setattr__(self, name, spec.check(self.kind, name, values.get(name, spec.default)))

    @classmethod
    def param_specs(cls) -> dict[str, param]:
        """name → `param` of every parameter, the cutoff radius first."""
        out = {}
        for klass in reversed(cls.__mro__):
            out.update({k: v for k, v in vars(klass).items() if isinstance(v, param)})
        return {'cutoff_radius': out.pop('cutoff_radius'), **out}

    def parameters(self) -> dict:
        """The law's parameter values by name."""
        return {name: getattr(self, name) for name in self.param_specs()}

    def with_parameters(self, **changes) -> Law:
        """A copy with some parameters changed (checked as at construction)."""
        return type(self)(**{**self.parameters(), **changes})

    def __repr__(self):
        return f'{type(self).__name__}({", ".join(f"{k}={v!r}" for k, v in self.parameters().items())})'

    def __eq__(self, other):
        return type(other) is type(self) and other.parameters() == self.parameters()

    def __hash__(self):
        return hash((type(self), tuple(self.parameters().items())))

    # what the engines ask of any law: no leader rule, no target or barrier term of the paper's
    uses_leaders = False
    target_gain = 0.0
    barrier_gain = 0.0

    def couples_globally(self, lambda_: float) -> bool:
        """Whether agents beyond w may weigh in (then every engine sums over the whole table)."""
        return True

    def control(self, view: View) -> np.ndarray:
        """u of each receiver, (K,)."""
        raise NotImplementedError

    def evaluate(self, pos, cos_t, sin_t, receivers, *, lambda_=0.0, is_leader=None, steering=None,
                 t=None, **world) -> np.ndarray:
        """`control` on a view of the table, checked: LawError naming the law if it raises or
        returns anything but K finite numbers.  ``world`` (target, barrier, pairs...) is the
        paper's law's own and not part of the view."""
        pos = np.asarray(pos, dtype=float)
        receivers = np.asarray(receivers, dtype=np.intp)
        cos_t, sin_t = np.asarray(cos_t, dtype=float), np.asarray(sin_t, dtype=float)
        n, k = len(pos), receivers.size
        view = View(pos=pos, theta=np.arctan2(sin_t, cos_t), cos=cos_t, sin=sin_t, receivers=receivers,
                    cutoff_radius=self.cutoff_radius, lam=float(lambda_), t=t,
                    is_leader=np.zeros(n, bool) if is_leader is None else np.asarray(is_leader, bool),
                    steering=np.zeros(k) if steering is None else np.asarray(steering, float))
        try:
            u = self.control(view)
        except LawError:
            raise
        except Exception as err:   # any error of a user's law is named, not a traceback
            raise LawError(f'law {self.kind} raised {type(err).__name__}: {err}') from err
        try:
            u = np.asarray(u, dtype=float)
        except (TypeError, ValueError):
            raise LawError(f'law {self.kind} returned {type(u).__name__}, not numbers') from None
        if u.shape != (k,):
            raise LawError(f'law {self.kind} returned shape {u.shape}, want ({k},): one u per receiver')
        if not np.all(np.isfinite(u)):
            raise LawError(f'law {self.kind} returned a non-finite u ({float(u[~np.isfinite(u)][0])!r})')
        return u


def neighbours_within(view: View) -> np.ndarray:
    """(K, N) bool: table row j is within w of receiver k (itself excluded), a helper for laws."""
    d = view.pos[view.receivers, None, :] - view.pos[None, :, :]
    near = np.einsum('knc,knc->kn', d, d) < view.cutoff_radius ** 2
    near[np.arange(view.receivers.size), view.receivers] = False
    return near
