"""The steering laws (no ROS): u_k for some receiving agents from a table of agent states.

`swarm_control` is the law of Morgan & Schwartz (eq. 4-16) for every kind in `LAW_KINDS`;
`LawConfig` and `PairGains` hold its constants, declared once in `parameters.LAW_TABLE`."""
from swarm_core.laws.config import LAW_PARAMETERS, LawConfig, PairGains
from swarm_core.laws.control import swarm_control, target_term
from swarm_core.laws.parameters import DEFAULTS, LAW_KINDS, LAW_TABLE

__all__ = ['DEFAULTS', 'LAW_KINDS', 'LAW_PARAMETERS', 'LAW_TABLE', 'LawConfig', 'PairGains', 'swarm_control',
           'target_term']
