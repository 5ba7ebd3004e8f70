"""Who is in a scenario's swarm and where it starts (no ROS): agent names, the placement rules
of positions and headings (``agents:``), and the initial conditions they give for a seed; in a
3D scenario (``dim: 3``) positions are 3-vectors and headings are vectors or a cap
(`AgentsSpec3`, `initial_conditions_3d`)."""
from __future__ import annotations

import math
import re
from typing import Annotated, Literal, Optional, Union

import numpy as np
from pydantic import Field, field_validator, model_validator

from swarm_core.checks import InputError
from swarm_core.model.natural import initial_frames
from swarm_core.schema import Finite, Length, Point, Point3, Strict, three_vectors

#: largest number of agents a scenario may name (lists or ``count``)
MAX_AGENTS = 1_000_000
#: an agent name: one ROS name token (letters, digits, single underscores), at most 64 chars
AGENT_NAME = re.compile(r'[A-Za-z](?:_?[A-Za-z0-9])*_?')
AGENT_NAME_MAX = 64


class GridPositions(Strict):
    rule: Literal['grid']
    spacing: Length = 1.0
    center: Point = (0.0, 0.0)


class DiscPositions(Strict):
    rule: Literal['disc']
    radius: Length = 10.0
    center: Point = (0.0, 0.0)


class ConeHeadings(Strict):
    """θ_i uniform in (φ − half_width, φ + half_width), φ uniform in [0, 2π) (the paper's rule)."""
    rule: Literal['cone']
    half_width: Annotated[float, Field(ge=0, le=math.pi)] = math.pi / 4
    center: Optional[Finite] = None   # φ; random when omitted


class UniformHeadings(Strict):
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


class AgentsSpec(Strict):
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


def initial_conditions(spec):
    """Names, positions (N, 2) and headings (N,) of a `swarm_core.scenario.loader.ScenarioSpec` for its seed."""
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


# ------------------------------------------------------------------ three dimensions (dim: 3)

class GridPositions3(Strict):
    """A horizontal grid about ``center`` (x, y, z)."""
    rule: Literal['grid']
    spacing: Length = 1.0
    center: Point3 = (0.0, 0.0, 0.0)


class VectorHeadings(Strict):
    """Each agent's heading as a vector (normalised on load; zero or non-finite refused)."""
    vectors: Annotated[list[tuple[Finite, Finite, Finite]], Field(min_length=1, max_length=MAX_AGENTS)]

    @field_validator('vectors', mode='before')
    @classmethod
    def _three(cls, v):
        return three_vectors(v, 'a heading')

    @field_validator('vectors')
    @classmethod
    def _nonzero(cls, v):
        try:
            norms = np.linalg.norm(np.asarray(v, dtype=float), axis=1)
        except (TypeError, ValueError):
            return v                                    # not numbers: the schema says so
        bad = np.flatnonzero(~(norms > 0) | ~np.isfinite(norms))
        if bad.size:
            raise InputError(f'heading {int(bad[0])} {tuple(v[bad[0]])} has no direction (zero or not finite)')
        return v


class CapHeadings(Strict):
    """Headings uniform in the cap of half-angle ``half_width`` about ``axis`` (random when
    omitted), seeded: the 3D analogue of the paper's φ ± π/4."""
    rule: Literal['cap']
    half_width: Annotated[float, Field(ge=0, le=math.pi)] = math.pi / 4
    axis: Optional[tuple[Finite, Finite, Finite]] = None

    @field_validator('axis', mode='before')
    @classmethod
    def _three(cls, v):
        return three_vectors(v, 'the axis')

    @field_validator('axis')
    @classmethod
    def _nonzero(cls, v):
        if v is not None and not np.linalg.norm(v) > 0:
            raise InputError('the axis has no direction (zero or not finite)')
        return v


def _agents_3d(value, field: str):
    """A planar value where a 3D one belongs: InputError naming what a 3D scenario takes."""
    if field == 'positions' and isinstance(value, list):
        return three_vectors(value, 'a position')
    if field == 'headings' and (not isinstance(value, dict) or value.get('rule') in ('cone', 'uniform')):
        raise InputError('a 3D scenario (dim: 3) takes {vectors: [[hx, hy, hz], ...]} or '
                         '{rule: cap, half_width, axis}')
    if field == 'headings' and isinstance(value.get('vectors'), list):       # its errors, one line
        VectorHeadings._nonzero(VectorHeadings._three(value['vectors']))
    return value


class AgentsSpec3(AgentsSpec):
    """``agents:`` of a 3D scenario: positions are 3-vectors or a horizontal grid; headings are
    vectors or a cap."""
    positions: Union[Annotated[list[Point3], Field(min_length=1, max_length=MAX_AGENTS)],
                     GridPositions3] = Field(default_factory=lambda: GridPositions3(rule='grid'))
    headings: Union[VectorHeadings, CapHeadings] = Field(default_factory=lambda: CapHeadings(rule='cap'))

    @field_validator('positions', 'headings', mode='before')
    @classmethod
    def _three_d(cls, v, info):
        return _agents_3d(v, info.field_name)

    @model_validator(mode='after')
    def _count(self):
        if isinstance(self.headings, VectorHeadings):
            if isinstance(self.positions, list) and len(self.positions) != len(self.headings.vectors):
                raise ValueError(f'positions and headings disagree on the number of agents '
                                 f'{sorted({len(self.positions), len(self.headings.vectors)})}')
            self.count = self.count or len(self.headings.vectors)
        return AgentsSpec._count(self)


def _cap(rng, n, half_width, axis):
    """n unit vectors uniform in the cap of half-angle ``half_width`` about ``axis`` (random if None)."""
    a = rng.normal(size=3) if axis is None else np.asarray(axis, dtype=float)
    a, e1, e2 = (f[0] for f in initial_frames(a[None, :]))
    cos_t = 1.0 - rng.uniform(size=n) * (1.0 - math.cos(half_width))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = rng.uniform(0, 2 * math.pi, size=n)
    return cos_t[:, None] * a + sin_t[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)


def initial_conditions_3d(spec):
    """Names, positions (N, 3) and unit headings (N, 3) of a 3D scenario's spec for its seed."""
    a = spec.agents
    n = a.count
    rng = np.random.default_rng([spec.seed, 1])
    names = list(a.names) if a.names else [f'agent_{i}' for i in range(n)]
    if isinstance(a.positions, list):
        pos = np.array(a.positions, dtype=float)
    else:
        side = int(math.ceil(math.sqrt(n)))
        idx = np.arange(n)
        pos = np.stack([idx % side, idx // side, np.zeros(n)], axis=1) * a.positions.spacing
        pos = pos - pos.mean(axis=0) + np.array(a.positions.center)
    if isinstance(a.headings, VectorHeadings):
        heading = np.array(a.headings.vectors, dtype=float)
    else:
        heading = _cap(rng, n, a.headings.half_width, a.headings.axis)
    return names, pos, heading / np.linalg.norm(heading, axis=1, keepdims=True)
