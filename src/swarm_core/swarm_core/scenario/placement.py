"""Who is in a scenario's swarm and where it starts (no ROS): agent names, the placement rules
of positions and headings (``agents:``), and the initial conditions they give for a seed."""
from __future__ import annotations

import math
import re
from typing import Annotated, Literal, Optional, Union

import numpy as np
from pydantic import Field, field_validator, model_validator

from swarm_core.schema import Finite, Length, Point, Strict

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
