"""Engines by name (no ROS): the built-in ones, and those that other packages register.

An engine is a function ``simulate(scenario, *args) -> Trajectory``.  A package adds one under
the entry-point group ``swarm_core.engines`` (swarm_robots registers ``robots``), so that a
study can run on it while swarm_core imports no package that depends on it."""
from __future__ import annotations

import importlib
from importlib.metadata import entry_points

GROUP = 'swarm_core.engines'
#: the engines of swarm_core itself: name -> 'module:function' (imported on first use)
BUILT_IN = {'reference': 'swarm_core.engine.reference:simulate', 'fast': 'swarm_core.engine.fast:simulate'}


def names() -> list[str]:
    """Every engine's name: the built-in ones, then the registered ones."""
    return [*BUILT_IN, *sorted(ep.name for ep in entry_points(group=GROUP) if ep.name not in BUILT_IN)]


def engine(name: str):
    """The ``simulate`` function of the engine called ``name``; LookupError names the known ones."""
    if name in BUILT_IN:
        module, func = BUILT_IN[name].split(':')
        return getattr(importlib.import_module(module), func)
    found = entry_points(group=GROUP, name=name)
    if not found:
        raise LookupError(f'no engine {name!r}: known engines are {", ".join(names())} '
                          f'(a package registers one under the entry-point group {GROUP})')
    return next(iter(found)).load()
