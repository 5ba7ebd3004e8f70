"""Scenario files (YAML): everything a run needs, validated before anything runs (no ROS).

A bad file raises `ScenarioError` with one line naming the field, e.g.
``scenario.yaml: law.alpha: Input should be greater than or equal to 0 (got -1)``.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal, Optional, Union, get_args

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .faults import Fault, FaultTimeline, Rendezvous
from .laws import LawConfig
from .frenet import PairGains
from .schedules import (ConstantLambda, ConstantSteering, RampSchedule, SinusoidSteering, TanhWindow,
                        WaypointSteering)
from .command_plan import CommandPlan

#: largest scenario file read (bytes), checked before parsing
MAX_FILE_BYTES = 2 * 1024 * 1024
#: largest number of agents a scenario may name (lists or ``count``)
MAX_AGENTS = 1_000_000
#: largest |coordinate| of a position, target, barrier or waypoint: far from overflow, so
#: distances, squares and sums of the law stay finite
MAX_COORD = 1e6
#: an agent name: one ROS name token (letters, digits, single underscores), at most 64 chars
AGENT_NAME = re.compile(r'[A-Za-z](?:_?[A-Za-z0-9])*_?')
AGENT_NAME_MAX = 64

Finite = Annotated[float, Field(allow_inf_nan=False)]
NonNeg = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Coord = Annotated[float, Field(ge=-MAX_COORD, le=MAX_COORD, allow_inf_nan=False)]
Point = tuple[Coord, Coord]
#: a gain or curvature: bounded so that u_k and dt·u_k stay finite
MAX_GAIN = 1e6
Gain = Annotated[float, Field(ge=0, le=MAX_GAIN, allow_inf_nan=False)]
Curvature = Annotated[float, Field(ge=-MAX_GAIN, le=MAX_GAIN, allow_inf_nan=False)]
Length = Annotated[float, Field(gt=0, le=MAX_COORD, allow_inf_nan=False)]


class ScenarioError(ValueError):
    """A scenario that cannot run; the message names the file and the field."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra='forbid')


# ------------------------------------------------------------------ agents

class GridPositions(_Strict):
    rule: Literal['grid']
    spacing: Length = 1.0
    center: Point = (0.0, 0.0)


class DiscPositions(_Strict):
    rule: Literal['disc']
    radius: Length = 10.0
    center: Point = (0.0, 0.0)


class ConeHeadings(_Strict):
    """θ_i uniform in (φ − half_width, φ + half_width), φ uniform in [0, 2π) (the paper's rule)."""
    rule: Literal['cone']
    half_width: Annotated[float, Field(ge=0, le=math.pi)] = math.pi / 4
    center: Optional[Finite] = None   # φ; random when omitted


class UniformHeadings(_Strict):
    rule: Literal['uniform']


def check_agent_name(name: str) -> str:
    """``name`` if it is a valid agent name (one ROS name token: it becomes the agent's
    namespace), else ValueError saying why."""
    if not isinstance(name, str) or not name:
        raise ValueError(f'agent name {name!r}: must not be empty')
    if len(name) > AGENT_NAME_MAX:
        raise ValueError(f'agent name {name[:20]!r}...: longer than {AGENT_NAME_MAX} characters')
    if not AGENT_NAME.fullmatch(name):
        raise ValueError(f'agent name {name!r}: not a ROS name token (a letter, then letters, '
                         'digits and single underscores)')
    return name


AgentName = Annotated[str, Field(max_length=AGENT_NAME_MAX)]


class AgentsSpec(_Strict):
    count: Optional[Annotated[int, Field(ge=1, le=MAX_AGENTS)]] = None
    names: Optional[Annotated[list[AgentName], Field(min_length=1, max_length=MAX_AGENTS)]] = None
    positions: Union[Annotated[list[Point], Field(min_length=1, max_length=MAX_AGENTS)],
                     GridPositions, DiscPositions] = Field(default_factory=lambda: GridPositions(rule='grid'))
    headings: Union[Annotated[list[Finite], Field(min_length=1, max_length=MAX_AGENTS)],
                    ConeHeadings, UniformHeadings] = Field(default_factory=lambda: ConeHeadings(rule='cone'))

    @field_validator('names')
    @classmethod
    def _names(cls, v):
        for nm in v or ():
            check_agent_name(nm)
        return v

    @model_validator(mode='after')
    def _count(self):
        sizes = {len(x) for x in (self.names, self.positions, self.headings) if isinstance(x, list)}
        if self.count is not None:
            sizes.add(self.count)
        if len(sizes) > 1:
            raise ValueError(f'count, names, positions and headings disagree on the number of agents {sorted(sizes)}')
        if not sizes:
            raise ValueError('give count, or positions / headings / names as lists')
        n = sizes.pop()
        self.count = n
        if self.names is not None and len(set(self.names)) != n:
            raise ValueError('agent names must be unique')
        return self


# ------------------------------------------------------------------ law

class LawSpec(_Strict):
    kind: Literal['global', 'local', 'leader_following', 'homotopy', 'target'] = 'homotopy'
    alpha: Gain = PairGains.alpha          # defaults: the core's config types (laws.py, frenet.py)
    eta: Gain = PairGains.eta
    mu: Gain = PairGains.mu
    r0: Length = PairGains.r0
    cutoff_radius: Length = LawConfig.cutoff_radius
    leader_gain: Annotated[float, Field(ge=1, le=MAX_GAIN, allow_inf_nan=False)] = LawConfig.leader_gain
    q0: Annotated[float, Field(ge=0, le=1)] = LawConfig.q0


# ------------------------------------------------------------------ λ schedules

class ConstantLambdaSpec(_Strict):
    kind: Literal['constant']
    value: Annotated[float, Field(ge=0, le=1)] = 0.0


class TanhWindowSpec(_Strict):
    kind: Literal['tanh_window']
    rise_at: Finite = 400.0      # ('on'/'off' are booleans in YAML 1.1, hence these names)
    fall_at: Finite = 600.0
    tau: Positive = 30.0


class RampSpec(_Strict):
    at: NonNeg
    to: Annotated[float, Field(ge=0, le=1)]
    duration: NonNeg = 20.0
    shape: Literal['smoothstep', 'linear', 'step', 'tanh'] = 'smoothstep'


class RampsSpec(_Strict):
    kind: Literal['ramps']
    initial: Annotated[float, Field(ge=0, le=1)] = 0.0
    ramps: list[RampSpec] = Field(default_factory=list)


LambdaSpec = Annotated[Union[ConstantLambdaSpec, TanhWindowSpec, RampsSpec], Field(discriminator='kind')]


# ------------------------------------------------------------------ steering programs

class ConstantProgram(_Strict):
    kind: Literal['constant']
    curvature: Curvature = 0.0


class SinusoidProgram(_Strict):
    kind: Literal['sinusoid']
    amplitude: Curvature = 0.01
    period: Positive = 200.0
    phase: Finite = 0.0
    offset: Curvature = 0.0


class WaypointProgram(_Strict):
    kind: Literal['waypoint']
    point: Point
    gain: Gain = 0.05
    max_curvature: Annotated[float, Field(gt=0, le=MAX_GAIN, allow_inf_nan=False)] = 0.05


ProgramSpec = Annotated[Union[ConstantProgram, SinusoidProgram, WaypointProgram], Field(discriminator='kind')]


class LeadersSpec(_Strict):
    """Fixed leaders (agent name → program) or a rule that chooses them at time ``at``."""
    fixed: dict[str, ProgramSpec] = Field(default_factory=dict)
    rule: Optional[Literal['lateral_extremes']] = None
    at: NonNeg = 0.0
    programs: list[ProgramSpec] = Field(default_factory=list)

    @model_validator(mode='after')
    def _one_way(self):
        if self.fixed and self.rule:
            raise ValueError('give either fixed leaders or a rule, not both')
        if self.rule and not self.programs:
            raise ValueError('a leader rule needs programs (left leader first, right leader second)')
        return self


# ------------------------------------------------------------------ world

class TargetSpec(_Strict):
    position: Point
    gain: Gain = 0.05            # γ
    normalised: bool = False


#: most barrier points (the law visits every point for every agent)
MAX_BARRIER_POINTS = 1000


class BarrierSpec(_Strict):
    """A convex polygon: at least 3 points, not all on one line, each a corner of the hull
    (the intrusion check uses the hull; a point inside it would be silently ignored there)."""
    points: list[Point] = Field(min_length=3, max_length=MAX_BARRIER_POINTS)
    gain: Gain = 5.0             # s_b
    mode: Literal['ahead', 'literal'] = 'ahead'

    @field_validator('points')
    @classmethod
    def _convex(cls, pts):
        p = np.asarray(pts, dtype=float)
        span = float(np.ptp(p, axis=0).max())
        d = p[1:] - p[0]
        cross = d[:, 0, None] * d[None, :, 1] - d[:, 1, None] * d[None, :, 0]
        if span == 0 or np.abs(cross).max() <= 1e-12 * span * span:
            raise ValueError('the barrier points are identical or on one line: a barrier needs an area')
        from scipy.spatial import ConvexHull
        corners = set(ConvexHull(p).vertices.tolist())
        inner = [i for i in range(len(p)) if i not in corners]
        if inner:
            raise ValueError(f'not a convex polygon: point {inner[0]} {tuple(pts[inner[0]])} is not a corner of '
                             f'the hull ({len(inner)} such point{"s" if len(inner) > 1 else ""}); '
                             'give the corners of a convex barrier')
        return pts


class NoiseSpec(_Strict):
    position: NonNeg = 0.0       # half-width of uniform noise on each coordinate, per step
    heading: NonNeg = 0.0        # half-width of uniform noise on θ, per step


# ------------------------------------------------------------------ faults, failover, reunion

class FaultSpec(_Strict):
    """``{at: 450, kill: agent_2}`` or ``{at: 300, freeze: leader:0, for: 5.0}`` (faults.py)."""
    at: NonNeg
    kill: Optional[str] = None
    freeze: Optional[str] = None
    for_: Optional[Positive] = Field(default=None, alias='for')
    model_config = ConfigDict(extra='forbid', populate_by_name=True)

    @model_validator(mode='after')
    def _one(self):
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


class FailoverSpec(_Strict):
    """Leader failover (faults.py): a leader not heard for ``timeout`` sim s is replaced."""
    timeout: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 1.0


class ReunionSpec(_Strict):
    """Over [at, at + for): a shared rendezvous target (eq. 15; point: [x, y], centroid or none)
    and/or far coupling q0 = ``coupling`` (faults.py)."""
    at: NonNeg
    for_: Positive = Field(alias='for')
    point: Union[Literal['centroid', 'none'], Point] = 'centroid'
    coupling: Optional[Annotated[float, Field(ge=0, le=1)]] = None
    gain: Gain = 0.05
    normalised: bool = False
    track: bool = False          # point: centroid re-taken at every step (moves with the swarm)
    model_config = ConfigDict(extra='forbid', populate_by_name=True)
# ------------------------------------------------------------------ communication (comms.py)

Probability = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]
NameOrNames = Union[str, list[str]]


class LinkSpec(_Strict):
    """Per-agent or per-link values: links from ``sender`` to ``receiver`` (a name or a list of
    names; omitted = every agent) get these values instead of the base ones."""
    sender: Optional[NameOrNames] = None
    receiver: Optional[NameOrNames] = None
    loss: Optional[Probability] = None
    latency: Optional[NonNeg] = None
    jitter: Optional[NonNeg] = None


class CommsEventSpec(_Strict):
    """A change of the radio at sim time ``at`` (from the first step n with n·dt ≥ at)."""
    at: NonNeg
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


class CommsSpec(_Strict):
    """The communication model (see swarm_core.comms); the defaults are a perfect radio."""
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


class PolarisationAbove(_Strict):
    at: NonNeg
    value: Annotated[float, Field(ge=0, le=1)]


class FollowsProgram(_Strict):
    slot: Annotated[int, Field(ge=0, le=1000)] = 0
    from_: NonNeg = Field(alias='from')
    to: NonNeg
    tolerance: Annotated[float, Field(gt=0, le=10)] = 0.3
    model_config = ConfigDict(extra='forbid', populate_by_name=True)


class ExpectSpec(_Strict):
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

    @model_validator(mode='after')
    def _windows(self):
        for k in ('one_cluster_at', 'split_between', 'split_near_x', 'rejoins_after_x'):
            w = getattr(self, k)
            if w is not None and w[0] > w[1]:
                raise ValueError(f'{k}: [{w[0]:g}, {w[1]:g}] is empty (a > b)')
        return self


class ScenarioSpec(_Strict):
    name: str
    description: str = ''
    seed: Annotated[int, Field(ge=0)] = 0
    dt: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] = 0.05
    duration: Positive = 1000.0
    integrator: Literal['zoh', 'rk4'] = 'zoh'
    agents: AgentsSpec
    law: LawSpec = Field(default_factory=LawSpec)
    lambda_: LambdaSpec = Field(default_factory=lambda: ConstantLambdaSpec(kind='constant'), alias='lambda')
    leaders: LeadersSpec = Field(default_factory=LeadersSpec)
    target: Optional[TargetSpec] = None
    barrier: Optional[BarrierSpec] = None
    noise: NoiseSpec = Field(default_factory=NoiseSpec)
    faults: list[FaultSpec] = Field(default_factory=list)
    failover: Optional[FailoverSpec] = None
    reunion: list[ReunionSpec] = Field(default_factory=list)
    comms: Optional[CommsSpec] = None
    expect: dict = Field(default_factory=dict)   # what `swarm sweep` checks (see outcomes.py)
    model_config = ConfigDict(extra='forbid', populate_by_name=True)

    @field_validator('name')
    @classmethod
    def _name(cls, v):
        if not v.strip():
            raise ValueError('must not be empty')
        if len(v) > 200:
            raise ValueError('longer than 200 characters')
        return v

    @field_validator('expect', mode='before')
    @classmethod
    def _expect(cls, v):
        """Checked against `ExpectSpec`, kept as the plain mapping outcomes.py reads."""
        if v is None:
            return {}
        if not isinstance(v, dict):
            raise ValueError('expect is a mapping of checks (see outcomes.py)')
        spec = ExpectSpec.model_validate(v)
        return {k: (list(x) if isinstance(x, tuple) else x)
                for k, x in spec.model_dump(by_alias=True, exclude_unset=True).items()}

    @model_validator(mode='after')
    def _steps(self):
        if round(self.duration / self.dt) < 1:
            raise ValueError(f'duration {self.duration:g} is shorter than one step (dt {self.dt:g}): '
                             'nothing would run')
        return self

    @model_validator(mode='after')
    def _reunion_vs_target(self):
        if self.reunion and self.target is not None:
            raise ValueError('reunion: a scenario with a target cannot also have a rendezvous '
                             '(both use the target term of eq. 15)')
        return self


# ------------------------------------------------------------------ runtime scenario

@dataclass
class Scenario:
    """A validated scenario with its initial conditions drawn for one seed."""

    spec: ScenarioSpec
    names: list
    pos0: np.ndarray
    theta0: np.ndarray
    law: LawConfig
    source: str = ''

    # -- convenience views of the spec
    @property
    def name(self):
        return self.spec.name

    @property
    def label(self) -> str:
        """The name made safe as one file-name component (`safe_label`)."""
        return safe_label(self.spec.name)

    @property
    def seed(self):
        return self.spec.seed

    @property
    def dt(self):
        return self.spec.dt

    @property
    def duration(self):
        return self.spec.duration

    @property
    def steps(self) -> int:
        return int(round(self.spec.duration / self.spec.dt))

    @property
    def target(self):
        return None if self.spec.target is None else np.array(self.spec.target.position, float)

    @property
    def barrier(self):
        return None if self.spec.barrier is None else np.array(self.spec.barrier.points, float)

    def command_plan(self) -> CommandPlan:
        """A fresh commander plan (λ schedule and leaders) for this scenario."""
        return CommandPlan(schedule=build_schedule(self.spec.lambda_),
                           fixed_leaders={self.names.index(n): build_program(p)
                                          for n, p in self.spec.leaders.fixed.items()},
                           rule=self.spec.leaders.rule, choose_at=self.spec.leaders.at,
                           rule_programs=[build_program(p) for p in self.spec.leaders.programs],
                           failover_timeout=self.spec.failover.timeout if self.spec.failover else None,
                           rendezvous=[Rendezvous(r.at, r.for_, None if r.point == 'centroid' else
                                                  r.point if r.point == 'none' else tuple(r.point),
                                                  r.gain, r.normalised, r.track, r.coupling)
                                       for r in self.spec.reunion])

    def fault_timeline(self) -> FaultTimeline:
        """A fresh timeline of the scenario's faults (faults.py)."""
        return FaultTimeline([Fault(f.at, f.kind, f.agent, f.for_ or 0.0) for f in self.spec.faults],
                             self.names, self.spec.dt)

    def comms_config(self) -> dict | None:
        """The ``comms`` section as a plain mapping (what `comms.CommModel.from_config` and
        the agents' ``comms`` parameter take), None without one."""
        return None if self.spec.comms is None else self.spec.comms.model_dump(mode='json')

    def comm_model(self):
        """A fresh `comms.CommModel` of this scenario, or None if its radio is perfect."""
        from .comms import CommModel
        m = CommModel.from_config(self.comms_config(), self.names, self.dt, self.seed)
        return None if m.perfect else m

    def noise_rng(self, index: int) -> np.random.Generator:
        """Agent ``index``'s own noise stream (the same in the batch engine and its node)."""
        return noise_rng(self.spec.seed, index)


def noise_rng(seed: int, index: int) -> np.random.Generator:
    """Agent ``index``'s own noise stream of a run with ``seed``: one place for its key."""
    return np.random.default_rng([seed, 7919, index])


def build_schedule(spec):
    if spec.kind == 'constant':
        return ConstantLambda(spec.value)
    if spec.kind == 'tanh_window':
        return TanhWindow(spec.rise_at, spec.fall_at, spec.tau)
    sched = RampSchedule(initial=spec.initial)
    for r in spec.ramps:
        sched.then(r.at, r.to, r.duration, r.shape)
    return sched


def build_program(spec):
    if spec.kind == 'constant':
        return ConstantSteering(spec.curvature)
    if spec.kind == 'sinusoid':
        return SinusoidSteering(spec.amplitude, spec.period, spec.phase, spec.offset)
    return WaypointSteering(tuple(spec.point), spec.gain, spec.max_curvature)


def _kinds(union) -> str:
    """'a, b, c': the ``kind`` tags of a discriminated union such as `LambdaSpec`."""
    return ', '.join(get_args(m.model_fields['kind'].annotation)[0] for m in get_args(get_args(union)[0]))


#: top-level field → the discriminated union found under it (for "no kind given" errors)
_UNION_OF = {'lambda': LambdaSpec, 'leaders': ProgramSpec}


def _format_error(err: ValidationError) -> str:
    e = err.errors()[0]
    loc = '.'.join(str(p) for p in e['loc'] if not str(p).startswith('function-')) or '(top level)'
    if e['type'] == 'union_tag_not_found' and e['loc']:
        union = _UNION_OF.get(str(e['loc'][0]))
        kinds = f' (one of: {_kinds(union)})' if union is not None else ''
        return f'{loc}: needs a `kind:` field{kinds}'
    # discriminated unions put the tag in the path: keep it readable
    got = e.get('input')
    got_s = '' if isinstance(got, (dict, list)) or got is None else f' (got {got!r})'
    more = len(err.errors()) - 1
    tail = f' [+{more} more problem{"s" if more > 1 else ""}]' if more else ''
    return f'{loc}: {e["msg"]}{got_s}{tail}'


def initial_conditions(spec: ScenarioSpec):
    """Names, positions (N, 2) and headings (N,) for the scenario's seed."""
    a = spec.agents
    n = a.count
    rng = np.random.default_rng([spec.seed, 1])
    names = list(a.names) if a.names else [f'agent_{i}' for i in range(n)]
    if isinstance(a.positions, list):
        pos = np.array(a.positions, dtype=float)
    elif a.positions.rule == 'grid':
        side = int(math.ceil(math.sqrt(n)))
        idx = np.arange(n)
        pos = np.stack([idx % side, idx // side], axis=1) * a.positions.spacing
        pos = pos - pos.mean(axis=0) + np.array(a.positions.center)
    else:
        rr = a.positions.radius * np.sqrt(rng.uniform(size=n))
        ph = rng.uniform(0, 2 * math.pi, size=n)
        pos = np.stack([rr * np.cos(ph), rr * np.sin(ph)], axis=1) + np.array(a.positions.center)
    if isinstance(a.headings, list):
        theta = np.array(a.headings, dtype=float)
    elif a.headings.rule == 'cone':
        phi = rng.uniform(0, 2 * math.pi) if a.headings.center is None else a.headings.center
        hw = a.headings.half_width
        theta = phi + rng.uniform(-hw, hw, size=n)
    else:
        theta = rng.uniform(0, 2 * math.pi, size=n)
    return names, pos.astype(float), theta.astype(float)


def safe_label(name: str) -> str:
    """``name`` as one file-name component: anything but letters, digits, ``-``, ``_`` and
    single dots becomes ``_``; leading and trailing dots and underscores go.  So ``../x`` or
    ``/etc/x`` stays inside the output directory (the name itself is only a label)."""
    out = re.sub(r'[^A-Za-z0-9_.-]+', '_', name)
    out = re.sub(r'_+', '_', re.sub(r'\.{2,}', '_', out)).strip('._')
    return out[:100] or 'scenario'


SCENARIO_DIR = 'scenarios'


def shipped_scenarios() -> list[str]:
    """Names of the scenarios shipped with swarm_core."""
    root = resources.files('swarm_core') / SCENARIO_DIR
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith('.yaml'))


def resolve(name_or_path: str) -> tuple[str, str]:
    """(text, source) of a shipped scenario name or a YAML file path."""
    p = Path(name_or_path)
    if p.suffix in ('.yaml', '.yml') or p.exists():
        if not p.is_file():
            raise ScenarioError(f'{name_or_path}: no such scenario file')
        try:
            size = p.stat().st_size
            if size > MAX_FILE_BYTES:
                raise ScenarioError(f'{name_or_path}: {size} bytes; a scenario file is at most '
                                    f'{MAX_FILE_BYTES} bytes (give large swarms a placement rule)')
            with open(p, 'rb') as fh:          # read at most the limit (a file may grow)
                raw = fh.read(MAX_FILE_BYTES + 1)
        except OSError as err:
            raise ScenarioError(f'{name_or_path}: cannot read: {err.strerror or err}') from None
        if len(raw) > MAX_FILE_BYTES:
            raise ScenarioError(f'{name_or_path}: more than {MAX_FILE_BYTES} bytes')
        try:
            return raw.decode('utf-8'), str(p)
        except UnicodeDecodeError as err:
            raise ScenarioError(f'{name_or_path}: not UTF-8 text ({err.reason} at byte {err.start})') from None
    res = resources.files('swarm_core') / SCENARIO_DIR / f'{name_or_path}.yaml'
    if not res.is_file():
        raise ScenarioError(f'{name_or_path}: not a shipped scenario ({", ".join(shipped_scenarios())}) '
                            'nor a .yaml file')
    return res.read_text(), f'{name_or_path} (shipped)'


def parse(data: dict, source: str = '<dict>', **overrides) -> Scenario:
    """Validate a scenario mapping; ``overrides`` (seed, duration, dt) replace its fields."""
    if not isinstance(data, dict):
        raise ScenarioError(f'{source}: a scenario is a YAML mapping, got {type(data).__name__}')
    data = dict(data)
    for key, val in overrides.items():
        if val is not None:
            data[key] = val
    try:
        spec = ScenarioSpec.model_validate(data)
        law = LawConfig(kind=spec.law.kind,
                        gains=PairGains(spec.law.alpha, spec.law.eta, spec.law.mu, spec.law.r0),
                        cutoff_radius=spec.law.cutoff_radius, leader_gain=spec.law.leader_gain,
                        q0=spec.law.q0,
                        target_gain=spec.target.gain if spec.target else 0.0,
                        target_normalised=spec.target.normalised if spec.target else False,
                        barrier_gain=spec.barrier.gain if spec.barrier else 0.0,
                        barrier_mode=spec.barrier.mode if spec.barrier else 'ahead')
    except ValidationError as err:
        raise ScenarioError(f'{source}: {_format_error(err)}') from None
    names = list(spec.agents.names) if spec.agents.names else None
    for who in spec.leaders.fixed:
        known = names or [f'agent_{i}' for i in range(spec.agents.count)]
        if who not in known:
            raise ScenarioError(f'{source}: leaders.fixed.{who}: unknown agent (agents are {", ".join(known[:8])}'
                                f'{", ..." if len(known) > 8 else ""})')
    known = names or [f'agent_{i}' for i in range(spec.agents.count)]
    for i, f in enumerate(spec.faults):
        if not f.agent.startswith('leader:') and f.agent not in known:
            raise ScenarioError(f'{source}: faults.{i}.{f.kind}: unknown agent {f.agent!r} (agents are '
                                f'{", ".join(known[:8])}{", ..." if len(known) > 8 else ""})')
    names, pos0, theta0 = initial_conditions(spec)
    if spec.comms is not None:
        from .comms import CommModel
        try:
            CommModel.from_config(spec.comms.model_dump(mode='json'), names, spec.dt, spec.seed)
        except ValueError as err:
            raise ScenarioError(f'{source}: {err}') from None
        if spec.integrator != 'zoh' and spec.comms.model_dump() != CommsSpec().model_dump():
            raise ScenarioError(f'{source}: comms: a communication model needs integrator zoh')
    return Scenario(spec=spec, names=names, pos0=pos0, theta0=theta0, law=law, source=source)


_Loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)     # libyaml when there (4x faster)


def safe_yaml(text: str):
    """Parse YAML text with the safe loader, refusing anchors and aliases (``&a`` / ``*a``):
    an alias bomb (a few lines that expand to billions of values) is refused before anything
    is built from it.  The node graph is composed, checked (an alias is a node met twice),
    then constructed."""
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        seen, stack = set(), [node]
        while stack:
            nd = stack.pop()
            if id(nd) in seen:
                mark = nd.start_mark
                raise yaml.composer.ComposerError(None, None, 'YAML aliases (*name) are not allowed in a scenario',
                                                  mark)
            seen.add(id(nd))
            if isinstance(nd, yaml.SequenceNode):
                stack.extend(nd.value)
            elif isinstance(nd, yaml.MappingNode):
                for k, v in nd.value:
                    stack.extend((k, v))
        return loader.construct_document(node)
    finally:
        loader.dispose()


def load(name_or_path: str, **overrides) -> Scenario:
    """Load a shipped scenario by name, or a YAML file, with optional overrides."""
    text, source = resolve(name_or_path)
    if len(text) > MAX_FILE_BYTES:
        raise ScenarioError(f'{source}: more than {MAX_FILE_BYTES} bytes')
    try:
        data = safe_yaml(text)
    except yaml.YAMLError as err:
        msg = ' '.join(str(err).split())
        raise ScenarioError(f'{source}: not valid YAML: {msg[:300]}') from None
    return parse(data, source, **overrides)
