"""The sections of a scenario file other than agents, law, lambda and leaders: the world
(target, barrier, noise), faults, failover, reunion, the radio (comms) and the checks of a
sweep (expect).  Each is a pydantic model with its fields' defaults and bounds; `loader`
puts them together in `ScenarioSpec`."""
from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

import numpy as np
from pydantic import ConfigDict, Field, field_validator, model_validator

from swarm_core.laws.paper.parameters import LAW_PARAMETER
from swarm_core.schema import (
    Coord,
    Finite,
    NonNeg,
    PauseSeconds,
    Point,
    Point3,
    Positive,
    SimTime,
    Strict,
    bounded,
    three_vectors,
)

# ------------------------------------------------------------------ world

class TargetSpec(Strict):
    position: Point
    gain: bounded(LAW_PARAMETER['target_gain'].bound) = 0.05      # γ
    normalised: bool = False


#: most barrier points (the law visits every point for every agent)
MAX_BARRIER_POINTS = 1000


class BarrierSpec(Strict):
    """A convex polygon: at least 3 points, not all on one line, each a corner of the hull
    (the intrusion check uses the hull; a point inside it would be silently ignored there)."""
    points: list[Point] = Field(min_length=3, max_length=MAX_BARRIER_POINTS)
    gain: bounded(LAW_PARAMETER['barrier_gain'].bound) = 5.0      # s_b
    mode: Literal[LAW_PARAMETER['barrier_mode'].choices] = LAW_PARAMETER['barrier_mode'].default

    @field_validator('points')
    @classmethod
    def _convex(cls, pts):
        from scipy.spatial import ConvexHull
        p = np.asarray(pts, dtype=float)
        span = float(np.ptp(p, axis=0).max())
        d = p[1:] - p[0]
        cross = d[:, 0, None] * d[None, :, 1] - d[:, 1, None] * d[None, :, 0]
        if span == 0 or np.abs(cross).max() <= 1e-12 * span * span:
            raise ValueError('the barrier points are identical or on one line: a barrier needs an area')
        corners = set(ConvexHull(p).vertices.tolist())
        inner = [i for i in range(len(p)) if i not in corners]
        if inner:
            raise ValueError(f'not a convex polygon: point {inner[0]} {tuple(pts[inner[0]])} is not a corner of '
                             f'the hull ({len(inner)} such point{"s" if len(inner) > 1 else ""}); '
                             'give the corners of a convex barrier')
        return pts


class TargetSpec3(TargetSpec):
    """The target of a 3D scenario: a point [x, y, z]."""
    position: Point3

    @field_validator('position', mode='before')
    @classmethod
    def _three(cls, v):
        return three_vectors(v, 'the target')


class BarrierSpec3(Strict):
    """The barrier of a 3D scenario: the convex hull of 3D points (at least 4, not in one
    plane), a ``ground`` floor z = ground that no agent may cross, or both."""
    points: list[Point3] = Field(default_factory=list, max_length=MAX_BARRIER_POINTS)
    ground: Optional[Coord] = None
    gain: bounded(LAW_PARAMETER['barrier_gain'].bound) = 5.0      # s_b
    mode: Literal[LAW_PARAMETER['barrier_mode'].choices] = LAW_PARAMETER['barrier_mode'].default

    @field_validator('points', mode='before')
    @classmethod
    def _three(cls, v):
        return three_vectors(v, 'a barrier point')

    @field_validator('points')
    @classmethod
    def _convex(cls, pts):
        if not pts:
            return pts
        from scipy.spatial import ConvexHull, QhullError
        try:
            corners = set(ConvexHull(np.asarray(pts, dtype=float)).vertices.tolist())
        except (QhullError, ValueError):
            raise ValueError('the barrier points do not span a volume: a 3D barrier needs at least 4 points '
                             'not in one plane') from None
        inner = [i for i in range(len(pts)) if i not in corners]
        if inner:
            raise ValueError(f'not a convex polyhedron: point {inner[0]} {tuple(pts[inner[0]])} is not a corner '
                             'of the hull; give the corners of a convex barrier')
        return pts

    @model_validator(mode='after')
    def _something(self):
        if not self.points and self.ground is None:
            raise ValueError('a 3D barrier needs points, a ground, or both')
        return self


class NoiseSpec(Strict):
    position: NonNeg = 0.0       # half-width of uniform noise on each coordinate, per step
    heading: NonNeg = 0.0        # half-width of uniform noise on θ, per step


# ------------------------------------------------------------------ faults, failover, reunion

class FaultSpec(Strict):
    """``{at: 450, kill: agent_2}`` or ``{at: 300, freeze: leader:0, for: 5.0}`` (faults.py)."""
    at: SimTime
    kill: Optional[str] = None
    freeze: Optional[str] = None
    for_: Optional[PauseSeconds] = Field(default=None, alias='for')
    model_config = ConfigDict(extra='forbid', populate_by_name=True)

    @model_validator(mode='after')
    def _exactly_one(self):
        if (self.kill is None) == (self.freeze is None):
            raise ValueError('give exactly one of kill: AGENT or freeze: AGENT')
        if self.freeze is not None and self.for_ is None:
            raise ValueError('freeze needs for: SECONDS')
        if self.kill is not None and self.for_ is not None:
            raise ValueError('for: is only for freeze')
        who = self.kill or self.freeze
        if who.startswith('leader:') and not who[7:].isdigit():
            raise ValueError(f'{who!r}: leader slots are leader:0, leader:1, ...')
        return self

    @property
    def kind(self):
        return 'kill' if self.kill is not None else 'freeze'

    @property
    def agent(self):
        return self.kill if self.kill is not None else self.freeze


class FailoverSpec(Strict):
    """Leader failover (faults.py): a leader not heard for ``timeout`` sim s is replaced."""
    timeout: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 1.0


class ReunionSpec(Strict):
    """Over [at, at + for): a shared rendezvous target (eq. 15; point: [x, y], centroid or none)
    and/or far coupling q0 = ``coupling`` (faults.py)."""
    at: SimTime
    for_: Positive = Field(alias='for')
    point: Union[Literal['centroid', 'none'], Point] = 'centroid'
    coupling: Optional[bounded(LAW_PARAMETER['q0'].bound)] = None
    gain: bounded(LAW_PARAMETER['target_gain'].bound) = 0.05
    normalised: bool = False
    track: bool = False          # point: centroid re-taken at every step (moves with the swarm)
    model_config = ConfigDict(extra='forbid', populate_by_name=True)


class ReunionSpec3(ReunionSpec):
    """The reunion of a 3D scenario: its point is [x, y, z] (or centroid, or none)."""
    point: Union[Literal['centroid', 'none'], Point3] = 'centroid'

    @field_validator('point', mode='before')
    @classmethod
    def _three(cls, v):
        return v if isinstance(v, str) else three_vectors(v, 'the rendezvous point')


# ------------------------------------------------------------------ communication (comms.py)

Probability = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]
NameOrNames = Union[str, list[str]]


class LinkSpec(Strict):
    """Per-agent or per-link values: links from ``sender`` to ``receiver`` (a name or a list of
    names; omitted = every agent) get these values instead of the base ones."""
    sender: Optional[NameOrNames] = None
    receiver: Optional[NameOrNames] = None
    loss: Optional[Probability] = None
    latency: Optional[NonNeg] = None
    jitter: Optional[NonNeg] = None


class CommsEventSpec(Strict):
    """A change of the radio at sim time ``at`` (from the first step n with n·dt ≥ at)."""
    at: SimTime
    loss: Optional[Probability] = None
    latency: Optional[NonNeg] = None
    jitter: Optional[NonNeg] = None
    drop: Optional[Probability] = None        # burst loss on top of ``loss`` (0 ends a burst)
    duration: Optional[Positive] = None       # of the burst (omitted: until the next drop)
    partition: Optional[list[list[str]]] = None   # new groups; [] heals

    @model_validator(mode='after')
    def _something(self):
        if all(getattr(self, k) is None for k in ('loss', 'latency', 'jitter', 'drop', 'partition')):
            raise ValueError('a comms event needs one of loss, latency, jitter, drop, partition')
        if self.duration is not None and self.drop is None:
            raise ValueError('duration belongs to a drop (burst loss)')
        return self


class CommsSpec(Strict):
    """The communication model (see swarm_core.radio); the defaults are a perfect radio."""
    seed: Optional[Annotated[int, Field(ge=0)]] = None     # default: the scenario's seed
    radio_range: Optional[Positive] = None                  # None: unlimited (w still applies)
    loss: Probability = 0.0
    latency: NonNeg = 0.0                                   # sim s
    jitter: NonNeg = 0.0                                    # sim s, delay = latency + U[0,1)·jitter
    timeout: Positive = 2.0                                 # forget senders silent this long (sim s)
    dead_reckoning: bool = True
    links: list[LinkSpec] = Field(default_factory=list)
    partition: list[list[str]] = Field(default_factory=list)
    events: list[CommsEventSpec] = Field(default_factory=list)


# ------------------------------------------------------------------ expect (outcomes.py)

Window = tuple[NonNeg, NonNeg]
XWindow = tuple[Finite, Finite]


class PolarisationAbove(Strict):
    at: NonNeg
    value: Annotated[float, Field(ge=0, le=1)]


class FollowsProgram(Strict):
    slot: Annotated[int, Field(ge=0, le=1000)] = 0
    from_: NonNeg = Field(alias='from')
    to: NonNeg
    tolerance: Annotated[float, Field(gt=0, le=10)] = 0.3
    model_config = ConfigDict(extra='forbid', populate_by_name=True)


class CircularFormationAt(Strict):
    """Sepulchre-Paley-Leonard circular formation at ``at`` (outcomes.py): centres within
    spread_below/ω0 of their mean, every |u_k − ω0| < turn_rate_within; ω0: the law's if omitted."""
    at: NonNeg
    omega0: Optional[Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)]] = None
    spread_below: Positive
    turn_rate_within: Positive


class SplayStateAt(Strict):
    """The splay state at ``at`` (outcomes.py): max_{1≤m<N} |(1/N) Σ_j e^{imθ_j}| < below."""
    at: NonNeg
    below: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)]


class ExpectSpec(Strict):
    """The checks of outcomes.py, each with its argument's type (a window is [a, b], a ≤ b)."""
    one_cluster_at: Optional[Window] = None
    polarisation_above: Optional[PolarisationAbove] = None
    split_between: Optional[Window] = None
    one_cluster_at_end: Optional[bool] = None
    stays_split_from: Optional[NonNeg] = None
    no_intrusion: Optional[bool] = None
    split_near_x: Optional[XWindow] = None
    rejoins_after_x: Optional[XWindow] = None
    arrives_within: Optional[Positive] = None
    split_at: Optional[NonNeg] = None
    one_cluster_from: Optional[NonNeg] = None
    follows_program: Optional[FollowsProgram] = None
    circular_formation: Optional[CircularFormationAt] = None
    splay_state: Optional[SplayStateAt] = None

    @model_validator(mode='after')
    def _windows(self):
        for k in ('one_cluster_at', 'split_between', 'split_near_x', 'rejoins_after_x'):
            w = getattr(self, k)
            if w is not None and w[0] > w[1]:
                raise ValueError(f'{k}: [{w[0]:g}, {w[1]:g}] is empty (a > b)')
        return self
