"""Tests of the steering laws.  `paper_law` builds one of the paper's laws by kind."""
from swarm_core.laws import law_class


class Gains(dict):
    """The pair term's gains (eq. 5-6): parameters of a paper's law, read as ``g.alpha`` too."""

    __getattr__ = dict.__getitem__


def gains(alpha=0.02, eta=0.02, mu=0.02, r0=1.5) -> Gains:
    return Gains(alpha=alpha, eta=eta, mu=mu, r0=r0)


def paper_law(kind='homotopy', gains=None, **values):
    """The paper's law ``kind`` with ``gains`` (`gains`) and other parameters."""
    return law_class(kind)(**(gains or {}), **values)
