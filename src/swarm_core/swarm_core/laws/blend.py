"""λ between two laws (no ROS): u = (1 − λ) u_from + λ u_to, with λ from the commander as the
paper's homotopy law has it (its schedule, `swarm lambda`, ``/swarm/lambda``)."""
from __future__ import annotations

import numpy as np

from swarm_core.laws.base import Law, LawError


class Blend(Law):
    """u = (1 − λ) u_from + λ u_to: the homotopy from one law to another.  Both laws see the
    same table and λ.  Its w (``cutoff_radius``) is the larger of the two laws' radii; each law
    still reads its own w in its own sums."""

    kind = 'blend'
    parts = ('from', 'to')
    #: a blend runs in the dimensions both its laws support (an instance's own)
    dims = (2, 3)

    def __init__(self, from_law, to_law):
        for side, law in (('from', from_law), ('to', to_law)):
            if not isinstance(law, Law) or law.parts:
                raise LawError(f'law blend: {side} must be a law other than a blend, got {law!r}')
        self.from_law, self.to_law = from_law, to_law
        self.cutoff_radius = max(from_law.cutoff_radius, to_law.cutoff_radius)
        self.dims = tuple(d for d in from_law.dims if d in to_law.dims)

    @classmethod
    def param_specs(cls):
        return {}

    def parameters(self) -> dict:
        return {}

    def __eq__(self, other):
        return type(other) is Blend and (other.from_law, other.to_law) == (self.from_law, self.to_law)

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
        u_from = self.from_law.evaluate(pos, cos_t, sin_t, receivers, **kw)
        u_to = self.to_law.evaluate(pos, cos_t, sin_t, receivers, **kw)
        return (1.0 - lam) * np.asarray(u_from) + lam * np.asarray(u_to)

    def evaluate_natural(self, pos, frames, receivers, *, lambda_=0.0, is_leader=None, steering=None, t=None,
                         **world):
        lam = float(lambda_)
        kw = dict(lambda_=lam, is_leader=is_leader, steering=steering, t=t, **world)
        uv_from = self.from_law.evaluate_natural(pos, frames, receivers, **kw)
        uv_to = self.to_law.evaluate_natural(pos, frames, receivers, **kw)
        return (1.0 - lam) * np.asarray(uv_from) + lam * np.asarray(uv_to)

    def with_world(self, world: dict) -> Blend:
        return Blend(self.from_law.with_world(world), self.to_law.with_world(world))

    def mapping(self) -> dict:
        return {'kind': self.kind, 'from': self.from_law.mapping(), 'to': self.to_law.mapping()}

    def flat(self, prefix: str = '') -> dict:
        return {prefix + 'law': self.kind, **self.from_law.flat(prefix + 'from.'), **self.to_law.flat(prefix + 'to.')}

    def flat_specs(self, prefix: str = '') -> dict:
        return {prefix + 'law': (self.kind, 'control law: blend of from and to, u = (1 − λ) u_from + λ u_to', None),
                **self.from_law.flat_specs(prefix + 'from.'), **self.to_law.flat_specs(prefix + 'to.')}
