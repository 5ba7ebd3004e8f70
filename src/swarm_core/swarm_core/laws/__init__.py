"""The steering laws (no ROS): u_k for some receiving agents from a table of agent states.

Writing a law:  `Law` (its docstring holds the rules a law keeps), `param`, `View`,
                `neighbours_within`.
Calling a law:  `swarm_control`, the one call every engine makes (`natural_control` in 3D).
Laws by name:   `make_law`, `law_class`, `names` (`registry`: built-in, entry points
                ``swarm_core.laws``, ``FILE.py:Class``, ``module:Class``).
The shipped laws: the paper's (`paper`: `Global`, `Local`, `LeaderFollowing`, `Homotopy`,
                `Target`, with `target_term`), Sepulchre-Paley-Leonard's (`ParallelFormation`,
                `CircularFormation`), and `Blend`, λ between two laws.
A law as parameters: `flat_parameters`, `from_flat_parameters`, `default_law`,
                `parameter_specs`, `law_mapping` (agent nodes, metrics.json).
Errors:         `LawError`, `LawFailed`, `failed_at`.
"""
from swarm_core.laws.base import Law, LawError, LawFailed, View, failed_at, neighbours_within, param
from swarm_core.laws.blend import Blend
from swarm_core.laws.control import natural_control, swarm_control
from swarm_core.laws.paper import DEFAULTS, Global, Homotopy, LeaderFollowing, Local, PaperLaw, Target, target_term
from swarm_core.laws.registry import (
    default_law,
    flat_parameters,
    from_flat_parameters,
    law_class,
    law_mapping,
    make_law,
    names,
    parameter_specs,
)
from swarm_core.laws.spl import CircularFormation, ParallelFormation

__all__ = [
    # writing a law
    'Law', 'View', 'neighbours_within', 'param',
    # calling a law
    'natural_control', 'swarm_control',
    # laws by name
    'law_class', 'make_law', 'names',
    # the shipped laws
    'Blend', 'CircularFormation', 'Global', 'Homotopy', 'LeaderFollowing', 'Local', 'PaperLaw', 'ParallelFormation',
    'Target', 'target_term', 'DEFAULTS',
    # a law as parameters
    'default_law', 'flat_parameters', 'from_flat_parameters', 'law_mapping', 'parameter_specs',
    # errors
    'LawError', 'LawFailed', 'failed_at',
]
