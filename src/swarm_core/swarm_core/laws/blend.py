"""λ between two laws (no ROS): u = (1 − λ) u_from + λ u_to, with λ from the commander as the
paper's homotopy law has it (its schedule, `swarm lambda`, ``/swarm/lambda``)."""
from __future__ import annotations

import numpy as np

from swarm_core.laws.base import Law, LawError
from swarm_core.laws.control import swarm_control


class Blend(Law):
    """u = (1 − λ) u_from + λ u_to: the homotopy from one law to another.  Both laws see the
    same table and λ; w is the larger of the two laws' (``cutoff_radius`` of the blend is the
    from-law's, for the engines' neighbour search the laws' own radii apply)."""

    kind = 'blend'

    def __init__(self, from_law, to_law):
        for side, law in (('from', from_law), ('to', to_law)):
            if not hasattr(law, 'kind') or isinstance(law, Blend):
                raise LawError(f'law blend: {side} must be a law other than a blend, got {law!r}')
        self.from_law, self.to_law = from_law, to_law
        self.cutoff_radius = max(from_law.cutoff_radius, to_law.cutoff_radius)

    @classmethod
    def param_specs(cls):
        return {}

    def parameters(self) -> dict:
        return {}

    def __eq__(self, other):
        return isinstance(other, Blend) and (other.from_law, other.to_law) == (self.from_law, self.to_law)

    def __hash__(self):
        return hash(('blend', self.from_law, self.to_law))

    def __repr__(self):
        return f'Blend({self.from_law!r}, {self.to_law!r})'

    @property
    def uses_leaders(self):
        return self.from_law.uses_leaders or self.to_law.uses_leaders

    def couples_globally(self, lambda_: float) -> bool:
        return self.from_law.couples_globally(lambda_) or self.to_law.couples_globally(lambda_)

    def evaluate(self, pos, cos_t, sin_t, receivers, *, lambda_=0.0, is_leader=None, steering=None, t=None,
                 **world):
        lam = float(lambda_)
        kw = dict(lambda_=lam, is_leader=is_leader, steering=steering, t=t, **world)
        u_from = swarm_control(pos, cos_t, sin_t, receivers, self.from_law, **kw)
        u_to = swarm_control(pos, cos_t, sin_t, receivers, self.to_law, **kw)
        return (1.0 - lam) * np.asarray(u_from) + lam * np.asarray(u_to)
