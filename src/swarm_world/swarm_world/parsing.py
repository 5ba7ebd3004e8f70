"""The world's text inputs, parsed without ROS: the ``target`` and ``barrier`` parameters,
the ``/swarm/leaders`` names and the live requests on ``/swarm/fault_request``."""
from __future__ import annotations

import math

import numpy as np

from swarm_core.checks import PAUSE_BOUND, json_value
from swarm_core.faults.agents import FAULT_KINDS, Fault


def parse_point(text, dim=2):
    """``"x,y"`` (``"x,y,z"`` with dim 3) → array [x, y(, z)]; ``""`` → None."""
    text = text.strip()
    if not text:
        return None
    vals = [float(v) for v in text.split(',')]
    if len(vals) != dim or not all(math.isfinite(v) for v in vals):
        raise ValueError(f'{text!r} is not "{",".join("xyz"[:dim])}" with finite numbers')
    return np.array(vals)


def parse_points(text, dim=2):
    """``"x,y;x,y;…"`` → array (m, 2) (``"x,y,z;…"`` → (m, 3) with dim 3); ``""`` → None."""
    text = text.strip()
    if not text:
        return None
    pts = [parse_point(p, dim) for p in text.split(';') if p.strip()]
    return np.array(pts) if pts else None


def format_points(pts):
    """The inverse of `parse_points` (exact: floats as repr)."""
    return '' if pts is None else ';'.join(','.join(f'{float(v)!r}' for v in p) for p in np.atleast_2d(pts))


def parse_geometry(values, target, barrier, dim=2):
    """(target, barrier) after the parameter texts in ``values`` (``target`` and/or
    ``barrier`` → text); what ``values`` lacks is kept."""
    if 'target' in values:
        target = parse_point(values['target'], dim)
    if 'barrier' in values:
        barrier = parse_points(values['barrier'], dim)
    return target, barrier


def leader_flags(text, row):
    """Comma-separated names → (flags over the roster, the unknown names)."""
    names = [nm.strip() for nm in text.split(',') if nm.strip()]
    flags = np.zeros(len(row), bool)
    flags[[row[nm] for nm in names if nm in row]] = True
    return flags, [nm for nm in names if nm not in row]


#: longest ``/swarm/fault_request`` text (a request is a few dozen characters)
MAX_REQUEST_CHARS = 4096


def fault_request(text):
    """A ``/swarm/fault_request`` JSON text → a live `Fault` (its pause checked by
    `PAUSE_BOUND`); ValueError, KeyError or TypeError when it is not one."""
    req = json_value(text, MAX_REQUEST_CHARS)
    kind, agent = req['kind'], req['agent']
    if kind not in FAULT_KINDS:
        raise ValueError(f'kind must be one of {FAULT_KINDS}')
    if not isinstance(agent, str):
        raise TypeError(f'agent {agent!r} is not a name')
    if kind == 'freeze':
        if 'for' not in req:
            raise ValueError('freeze needs "for" seconds')
        return Fault(0.0, kind, agent, PAUSE_BOUND.check(req['for']), source='live')
    return Fault(0.0, kind, agent, source='live')
