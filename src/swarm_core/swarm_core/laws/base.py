"""The law interface (no ROS): a steering law of unit-speed planar agents as a class.

A law declares its parameters as class attributes (`param`: default, closed range, text) and
computes the curvature u of some receiving agents from a table of agent states (`View`)::

    class Alignment(Law):
        '''Kuramoto alignment with the neighbours within w.'''
        gain = param(0.1, lo=0.0, hi=10.0, doc='coupling K')

        def control(self, view):
            return u          # (K,), one u per receiver

`Law`'s docstring holds the rules a law keeps.  Every engine calls a law through
`swarm_control` (`laws.control`), which asks the law to `evaluate` itself; a `Law` hands
`control` a view and checks what it returns, and a law with a faster path of its own (the
paper's, `laws.paper`) overrides `evaluate`.
"""
from __future__ import annotations

import math
import re
import threading
from dataclasses import dataclass

import numpy as np

from swarm_core.laws import guards

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
    """One parameter of a law: its default, closed range [lo, hi] and description.  A default
    that is a bool makes a yes/no parameter; one that is a str, a choice among ``choices``."""

    default: object
    lo: float = -1e6
    hi: float = 1e6
    doc: str = ''
    integer: bool = False
    choices: tuple = ()

    @property
    def limits(self):
        """(lo, hi), the choices, or None for a yes/no parameter (as an agent node declares it)."""
        if isinstance(self.default, bool):
            return None
        return self.choices if isinstance(self.default, str) else (self.lo, self.hi)

    def check(self, law: str, name: str, value):
        """``value`` as the parameter's type; LawError naming the law and the parameter if it
        is not a number in [lo, hi] (a bool; one of the choices)."""
        if isinstance(self.default, bool):
            if not isinstance(value, (bool, np.bool_)):
                raise LawError(f'law {law}: parameter {name} must be true or false, got {value!r}')
            return bool(value)
        if isinstance(self.default, str):
            if value not in self.choices:
                raise LawError(f'law {law}: parameter {name} must be one of {", ".join(self.choices)}, got {value!r}')
            return str(value)
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
    leader programs s_k.

    In three dimensions (`Law.evaluate_natural`): pos (N, 3), the frames x, y, z (N, 3) each,
    steering (K, 2): s_k = (s_u, s_v); theta, cos and sin are None."""

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
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    z: np.ndarray | None = None


class Law:
    """A steering law: subclass it, declare `param`s, write `control`.

    The rules a law keeps (the engines and the ROS nodes rely on them, as an ODE solver relies
    on its right-hand side):

    - **No state between calls.**  `control` reads its view and its parameters only.  The batch
      engine, every agent node and every agent container call it on their own tables, as often
      as they need (RK4 at its stage times too); a law that keeps state answers each differently.
    - **One receiver's u does not depend on which others are asked.**  ``view.receivers`` may
      be the whole table (the batch engine), one agent (an agent node) or a few (a container):
      receiver k's u must be the same in each.  Then ``swarm run`` lockstep equals ``swarm
      simulate``, to rounding; bit for bit where each receiver's row is computed on its own.
    - **couples_globally(λ)**: whether agents beyond w may weigh in at λ.  True (the default):
      every agent the caller knows is in the table.  False: only agents within w carry weight,
      and a caller may leave the others out (a neighbour list, a radio's range).
    - **uses_leaders**: True if the law reads each receiver's nearest leader l(k) (eq. 10).  A
      caller whose table is not one shared view (a radio model's beliefs) then gives each
      receiver's l(k) as ``nearest``.  ``view.is_leader`` and ``view.steering`` reach every law.
    - **Target and barrier terms** (eq. 15, 16) belong to the paper's laws: their gains come
      from the scenario's ``target:`` and ``barrier:`` sections (`with_world`); no other law's
      view holds the target or the barrier.
    - **dims**: the dimensions the law supports, ``(2,)`` (planar) by default.  A law with 3 in
      its dims runs in 3D scenarios: its view then holds the frames x, y, z (N, 3) and
      `control` returns (K, 2), (u, v) per receiver (`evaluate_natural`).

    The rest is the framework's: `evaluate` (what every engine calls), `believed_controls` (on
    a radio's beliefs), `pair_list` (what the law sums over), `compiled_run` (a whole run in
    compiled code, for the fast engine) and the law as a scenario mapping or as flat
    parameters (`mapping`, `flat`, `flat_specs`, `from_mapping`).  A law with faster paths of
    its own overrides `evaluate`, `pair_list` and `compiled_run` (the paper's laws,
    `laws.paper`); a law made of laws names them in ``parts`` (`Blend`).
    """

    #: what a scenario calls the law (``law: {kind: ...}``); a user law's is its file or module path
    kind: str = ''
    #: the dimensions of the agents' space the law supports
    dims = (2,)
    #: the laws this law is made of, by key (a blend's ``from``, ``to``); () for a law of its own
    parts = ()
    #: whether the law reads each receiver's nearest leader l(k) (eq. 10)
    uses_leaders = False
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

    @classmethod
    def summary(cls) -> str:
        """The first sentence of the class's docstring, on one line."""
        text = ' '.join((cls.__doc__ or '').split('\n\n')[0].split())
        end = re.search(r'\.(?=\s+[A-Z`])', text)          # not "eq. 4"
        return text if end is None else text[:end.end()]

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

    def couples_globally(self, lambda_: float) -> bool:
        """Whether agents beyond w may weigh in (then every engine sums over the whole table)."""
        return True

    def control(self, view: View) -> np.ndarray:
        """u of each receiver, (K,)."""
        raise NotImplementedError

    # ------------------------------------------------------------ what the engines call
    def evaluate(self, pos, cos_t, sin_t, receivers, *, lambda_=0.0, is_leader=None, steering=None,
                 t=None, **world) -> np.ndarray:
        """`control` on a view of the table, checked: LawError naming the law if it raises or
        returns anything but K finite numbers.  ``world`` (target, barrier, pairs, nearest) is
        the paper's laws' and not part of the view."""
        pos = np.asarray(pos, dtype=float)
        receivers = np.asarray(receivers, dtype=np.intp)
        cos_t, sin_t = np.asarray(cos_t, dtype=float), np.asarray(sin_t, dtype=float)
        n, k = len(pos), receivers.size
        view = View(pos=pos, theta=np.arctan2(sin_t, cos_t), cos=cos_t, sin=sin_t, receivers=receivers,
                    cutoff_radius=self.cutoff_radius, lam=float(lambda_), t=t,
                    is_leader=np.zeros(n, bool) if is_leader is None else np.asarray(is_leader, bool),
                    steering=np.zeros(k) if steering is None else np.asarray(steering, float))
        return self._guarded_control(view, (k,), 'one u per receiver')

    def evaluate_natural(self, pos, frames, receivers, *, lambda_=0.0, is_leader=None, steering=None,
                         t=None, **world) -> np.ndarray:
        """(u, v) (K, 2) of the receivers in three dimensions: `control` on a view with the
        frames (`View`), checked as `evaluate` checks u.  pos (N, 3); frames (x, y, z), (N, 3)
        each; steering (K, 2).  ``world`` (target, barrier, ground) is the paper's laws'."""
        pos = np.asarray(pos, dtype=float)
        receivers = np.asarray(receivers, dtype=np.intp)
        x, y, z = (np.asarray(f, dtype=float) for f in frames)
        n, k = len(pos), receivers.size
        view = View(pos=pos, theta=None, cos=None, sin=None, receivers=receivers, cutoff_radius=self.cutoff_radius,
                    lam=float(lambda_), t=t, is_leader=np.zeros(n, bool) if is_leader is None else
                    np.asarray(is_leader, bool), steering=np.zeros((k, 2)) if steering is None else
                    np.asarray(steering, float), x=x, y=y, z=z)
        return self._guarded_control(view, (k, 2), '(u, v) per receiver')

    def _guarded_control(self, view, shape, what) -> np.ndarray:
        """`control` of ``view``: LawError naming the law if it raises, leaves a thread running or
        returns anything but finite numbers of ``shape`` (``what`` they are)."""
        sigints, threads = guards.watch_interrupts(), threading.active_count()
        before = {t.ident for t in threading.enumerate()} if threads > 1 else {threading.get_ident()}
        try:
            u = self.control(view)
            u = self._as_numbers(u)
        except LawError:
            raise
        except KeyboardInterrupt as err:    # the user's Ctrl-C goes on; the law's own is its error
            if guards.user_interrupted(sigints):
                raise
            raise LawError(f'law {self.kind} raised KeyboardInterrupt (its own: no Ctrl-C came)') from err
        except BaseException as err:        # any error of a user's law, SystemExit too, is named
            raise LawError(f'law {self.kind} raised {type(err).__name__}: {err}') from err
        finally:
            left = guards.left_threads(before) if threading.active_count() > threads else ()
        if left:
            raise LawError(f'law {self.kind} left a thread running ({left[0].name}): a law may not start '
                           'threads that outlive its call')
        if u.shape != shape:
            want = f'({shape[0]},)' if len(shape) == 1 else str(shape)
            raise LawError(f'law {self.kind} returned shape {u.shape}, want {want}: {what}')
        if not np.all(np.isfinite(u)):
            raise LawError(f'law {self.kind} returned a non-finite u ({float(u[~np.isfinite(u)][0])!r})')
        return u

    def _as_numbers(self, u) -> np.ndarray:
        """``u`` as real numbers: LawError naming the law for anything else (a complex u, an
        object whose conversion raises)."""
        try:
            arr = np.asarray(u)
        except Exception as err:
            raise LawError(f'law {self.kind} returned {type(u).__name__}, which raised {type(err).__name__} '
                           f'when read as numbers: {err}') from err
        if arr.dtype.kind == 'c' or arr.dtype == object and any(isinstance(v, complex) for v in arr.flat):
            raise LawError(f'law {self.kind} returned a complex u: a curvature is a real number')
        try:
            return arr.astype(float, copy=False)
        except (TypeError, ValueError):
            raise LawError(f'law {self.kind} returned {type(u).__name__}, not numbers') from None

    def pair_list(self, pos, lambda_: float, search: str = 'auto'):
        """What `evaluate` sums over for a table at ``pos`` (``pairs``): None, the whole table
        (a `Law` reads its whole view).  ``search``: the engine's neighbour search (auto, all,
        kdtree)."""
        return None

    @classmethod
    def compiled_run(cls):
        """The module of the law's compiled whole run (``fallback_reason``, ``run``, ``warm_up``),
        which the fast engine (`engine.fast`) takes where it covers a run; None: the fast
        engine hands the law's runs to the reference engine."""
        return None

    def believed_controls(self, pos, cos_t, sin_t, a, m, *, lambda_, is_leader, steering, target, barrier,
                          nearest, t) -> np.ndarray:
        """u (m,) of the receivers of a radio's belief table (`step.belief_controls`: rows 0 … m−1
        the receivers' own states, row m + i what receiver a[i] believes of one sender): one
        call per receiver on its own rows (its own state, then its believed senders in index
        order), so a receiver's view is what it believes, whichever receivers are asked with it."""
        u = np.empty(m)
        for i in range(m):
            p = np.flatnonzero(a == i)
            rows = np.concatenate(([i], m + p))
            near = None
            if nearest is not None:     # a table row m + pair → the row in this receiver's view
                near = np.array([-1 if nearest[i] < 0 else 1 + int(np.searchsorted(p, nearest[i] - m))], np.intp)
            u[i] = self.evaluate(pos[rows], cos_t[rows], sin_t[rows], np.zeros(1, np.intp), lambda_=lambda_,
                                 is_leader=None if is_leader is None else is_leader[rows], steering=steering[i:i + 1],
                                 target=target, barrier=barrier, nearest=near, t=t,
                                 pairs=(np.zeros(p.size, np.intp), 1 + np.arange(p.size)))[0]
        return u

    # ------------------------------------------------------------ the law as a scenario and a node have it
    def with_world(self, world: dict) -> Law:
        """The law with the scenario's target and barrier gains (`laws.paper`'s names); a law
        without those terms is itself."""
        return self

    def mapping(self) -> dict:
        """The law as a scenario's ``law:`` section, as metrics.json records it."""
        return {'kind': self.kind, **self.parameters()}

    def flat(self, prefix: str = '') -> dict:
        """The law as flat parameters ``{law: kind, name: value...}``: an agent node's."""
        return {prefix + 'law': self.kind, **{prefix + k: v for k, v in self.parameters().items()}}

    def flat_specs(self, prefix: str = '') -> dict:
        """name → (default, description, range, choices or None) of every flat parameter."""
        out = {prefix + 'law': (self.kind, f'control law: {self.kind}', None)}
        for name, spec in self.param_specs().items():
            out[prefix + name] = (int(spec.default) if spec.integer else spec.default, spec.doc, spec.limits)
        return out

    @classmethod
    def from_mapping(cls, values: dict, base_dir=None, where: str = 'law') -> Law:
        """The law of a ``law:`` section's values (its kind left out), checked."""
        try:
            return cls(**values)
        except LawError:
            raise
        except Exception as err:   # a user's __init__
            raise LawError(f'law {cls.kind}: {type(err).__name__}: {err}') from None


def neighbours_within(view: View) -> np.ndarray:
    """(K, N) bool: table row j is within w of receiver k (itself excluded), a helper for laws."""
    d = view.pos[view.receivers, None, :] - view.pos[None, :, :]
    near = np.einsum('knc,knc->kn', d, d) < view.cutoff_radius ** 2
    near[np.arange(view.receivers.size), view.receivers] = False
    return near
