"""The building blocks of the scenario schema (no ROS): the strict base model and the bounded
number types.  A bound declared elsewhere (`inputs`, `law_parameters`) becomes a type here, so
the schema and the other boundaries accept the same values."""
from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from swarm_core.checks import (
    DT_BOUND,
    DURATION_BOUND,
    LAMBDA_BOUND,
    MAX_COORD,
    MAX_GAIN,
    MAX_TIME,
    PAUSE_BOUND,
    RAMP_BOUND,
    STEERING_BOUND,
    Bound,
    InputError,
)

Finite = Annotated[float, Field(allow_inf_nan=False)]
NonNeg = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Coord = Annotated[float, Field(ge=-MAX_COORD, le=MAX_COORD, allow_inf_nan=False)]
Point = tuple[Coord, Coord]
#: a point of a 3D scenario (``dim: 3``)
Point3 = tuple[Coord, Coord, Coord]
#: a gain or curvature: bounded so that u_k and dt·u_k stay finite
Gain = Annotated[float, Field(ge=0, le=MAX_GAIN, allow_inf_nan=False)]
Length = Annotated[float, Field(gt=0, le=MAX_COORD, allow_inf_nan=False)]


def bounded(bound: Bound):
    """A `Bound` as pydantic constraints (pydantic's error texts, as for the other fields)."""
    lo = dict(gt=bound.lo) if bound.open_lo else dict(ge=bound.lo)
    return Annotated[float, Field(le=bound.hi, allow_inf_nan=False, **lo)]


def checked(bound: Bound):
    """A number checked by the `Bound`'s own check, so the schema rejects it with the text of
    every other boundary (`swarm_core.scenario.loader._format_error` shows it as it is)."""
    return Annotated[float, AfterValidator(bound.check)]


#: λ (eq. 12-14), checked as on every other boundary
Lambda = checked(LAMBDA_BOUND)
#: the values a live command or parameter also sets, bounded as on every other boundary
Curvature = bounded(STEERING_BOUND)
PauseSeconds = bounded(PAUSE_BOUND)
RampSeconds = bounded(RAMP_BOUND)
StepSeconds = bounded(DT_BOUND)
RunSeconds = bounded(DURATION_BOUND)
#: a time within a run (sim s)
SimTime = Annotated[float, Field(ge=0, le=MAX_TIME, allow_inf_nan=False)]


def three_vectors(value, what: str = 'a point'):
    """``value`` (a 3-vector, or a list of them) as it is if each item has 3 numbers; else
    InputError saying that a 3D scenario takes [x, y, z] (a planar value in ``dim: 3``)."""
    items = value if isinstance(value, list) and value and isinstance(value[0], (list, tuple)) else [value]
    for i, item in enumerate(items):
        if isinstance(item, (list, tuple)) and len(item) != 3:
            at = f' (item {i})' if items is value else ''
            raise InputError(f'{what} of a 3D scenario (dim: 3) has 3 coordinates [x, y, z], '
                             f'got {len(item)}{at}')
    return value


class Strict(BaseModel):
    model_config = ConfigDict(extra='forbid')
