"""The steering laws (no ROS): u_k for some receiving agents from a table of agent states.

A law is a `Law` (`base`: parameters declared with `param`, ``control(view)``), or the paper's
law of Morgan & Schwartz (`LawConfig`, eq. 4-16, with compiled paths).  `swarm_control` is the
one call every engine makes; `make_law` builds a scenario's law by kind (the paper's kinds,
`spl` laws, ``blend``, a user's ``FILE.py:Class``)."""
from swarm_core.laws.base import Law, LawError, LawFailed, View, failed_at, neighbours_within, param
from swarm_core.laws.blend import Blend
from swarm_core.laws.config import LAW_PARAMETERS, LawConfig, PairGains
from swarm_core.laws.control import swarm_control, target_term
from swarm_core.laws.parameters import DEFAULTS, LAW_KINDS, LAW_TABLE
from swarm_core.laws.plugins import (
                                     KINDS,
                                     default_law,
                                     flat_parameters,
                                     from_flat_parameters,
                                     law_mapping,
                                     make_law,
                                     parameter_specs,
)
from swarm_core.laws.spl import CircularFormation, ParallelFormation

__all__ = ['Blend', 'CircularFormation', 'DEFAULTS', 'KINDS', 'LAW_KINDS', 'LAW_PARAMETERS', 'LAW_TABLE', 'Law',
           'LawConfig', 'LawError', 'LawFailed', 'PairGains', 'ParallelFormation', 'View', 'default_law', 'failed_at',
           'flat_parameters', 'from_flat_parameters', 'law_mapping', 'make_law', 'neighbours_within', 'param',
           'parameter_specs', 'swarm_control', 'target_term']
