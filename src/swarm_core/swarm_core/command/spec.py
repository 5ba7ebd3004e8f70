"""The commander's part of a scenario (no ROS): the λ schedule (``lambda:``), the leaders and
their steering programs (``leaders:``), and the schedules and programs they build."""
from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import Field, field_validator, model_validator

from swarm_core.checks import DT_BOUND, MAX_GAIN, MAX_TIME, STEERING_BOUND, InputError
from swarm_core.command.schedules import (
    ConstantLambda,
    ConstantSteering,
    HelixSteering,
    RampSchedule,
    SinusoidSteering,
    TanhWindow,
    WaypointSteering,
)
from swarm_core.schema import Curvature, Finite, Gain, Lambda, NonNeg, Point, Positive, RampSeconds, SimTime, Strict

# ------------------------------------------------------------------ λ schedules

class ConstantLambdaSpec(Strict):
    kind: Literal['constant']
    value: Lambda = 0.0


class TanhWindowSpec(Strict):
    kind: Literal['tanh_window']
    rise_at: Finite = 400.0      # ('on'/'off' are booleans in YAML 1.1, hence these names)
    fall_at: Finite = 600.0
    tau: Positive = 30.0


class RampSpec(Strict):
    at: SimTime
    to: Lambda
    duration: RampSeconds = 20.0
    shape: Literal['smoothstep', 'linear', 'step', 'tanh'] = 'smoothstep'


class RampsSpec(Strict):
    kind: Literal['ramps']
    initial: Lambda = 0.0
    ramps: list[RampSpec] = Field(default_factory=list)


LambdaSpec = Annotated[Union[ConstantLambdaSpec, TanhWindowSpec, RampsSpec], Field(discriminator='kind')]


# ------------------------------------------------------------------ steering programs

class ConstantProgram(Strict):
    kind: Literal['constant']
    curvature: Curvature = 0.0


class SinusoidProgram(Strict):
    kind: Literal['sinusoid']
    amplitude: Curvature = 0.01
    period: Annotated[float, Field(ge=DT_BOUND.lo, le=MAX_TIME, allow_inf_nan=False)] = 200.0
    phase: Finite = 0.0
    offset: Curvature = 0.0

    @model_validator(mode='after')
    def _within_bound(self):
        if abs(self.offset) + abs(self.amplitude) > STEERING_BOUND.hi:
            raise ValueError(f'|offset| + |amplitude| must be at most {STEERING_BOUND.hi:g} (the steering bound)')
        return self


class WaypointProgram(Strict):
    kind: Literal['waypoint']
    point: Point
    gain: Gain = 0.05
    max_curvature: Annotated[float, Field(gt=0, le=MAX_GAIN, allow_inf_nan=False)] = 0.05


ProgramSpec = Annotated[Union[ConstantProgram, SinusoidProgram, WaypointProgram], Field(discriminator='kind')]


class ConstantProgram3(Strict):
    """A 3D leader's constant program s_k = (s_u, s_v), in its own (y, z)."""
    kind: Literal['constant']
    curvature: tuple[Curvature, Curvature] = (0.0, 0.0)

    @field_validator('curvature', mode='before')
    @classmethod
    def _pair(cls, v):
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise InputError('a 3D scenario (dim: 3) steers a leader by [s_u, s_v], two curvatures')
        return v


class HelixProgram(Strict):
    """s_k = κ (cos(τt + phase), sin(τt + phase)): a helix of curvature κ and torsion τ."""
    kind: Literal['helix']
    curvature: Curvature = 0.01
    torsion: Annotated[float, Field(ge=-MAX_GAIN, le=MAX_GAIN, allow_inf_nan=False)] = 0.01
    phase: Finite = 0.0


ProgramSpec3 = Annotated[Union[ConstantProgram3, HelixProgram], Field(discriminator='kind')]


class LeadersSpec(Strict):
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


class LeadersSpec3(LeadersSpec):
    """``leaders:`` of a 3D scenario: programs are `ProgramSpec3` (constant [s_u, s_v], helix)."""
    fixed: dict[str, ProgramSpec3] = Field(default_factory=dict)
    programs: list[ProgramSpec3] = Field(default_factory=list)

    @field_validator('fixed', 'programs', mode='before')
    @classmethod
    def _three_d(cls, v):
        for p in (v.values() if isinstance(v, dict) else v if isinstance(v, list) else ()):
            if isinstance(p, dict) and p.get('kind') in ('sinusoid', 'waypoint'):
                raise InputError(f'program {p["kind"]} is planar: a 3D scenario (dim: 3) takes constant or helix')
        return v


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
    if spec.kind == 'helix':
        return HelixSteering(spec.curvature, spec.torsion, spec.phase)
    if spec.kind == 'sinusoid':
        return SinusoidSteering(spec.amplitude, spec.period, spec.phase, spec.offset)
    return WaypointSteering(tuple(spec.point), spec.gain, spec.max_curvature)
