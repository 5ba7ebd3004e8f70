"""A law's configuration (no ROS): which law, the gains of the Justh-Krishnaprasad pair term
(`PairGains`, eq. 5-6) and the law's constants (`LawConfig`), with defaults and ranges from
`swarm_core.laws.parameters`."""
from __future__ import annotations

from dataclasses import dataclass, field, fields

from swarm_core.laws.parameters import BARRIER_MODES, DEFAULTS, LAW_KINDS, LAW_TABLE


@dataclass(frozen=True)
class PairGains:
    """Constants of the pair term u_jk (eq. 5, 6): ``alpha`` (spacing), ``eta`` (baseline),
    ``mu`` (alignment) and the preferred spacing ``r0``; defaults, ranges: `swarm_core.laws.parameters`."""

    alpha: float = DEFAULTS['alpha']
    eta: float = DEFAULTS['eta']
    mu: float = DEFAULTS['mu']
    r0: float = DEFAULTS['r0']


@dataclass(frozen=True)
class LawConfig:
    """Which law and its constants (defaults, ranges and descriptions: `swarm_core.laws.parameters`).

    cutoff_radius  w, the communication/sensing radius of the cutoff c(ρ, q, w) (eq. 8)
    leader_gain    ℓc ≫ 1, the follower-to-leader coupling (eq. 10, 13)
    q0             far-coupling weight at λ = 0 (1: the paper's homotopy law, Fig. 3;
                   0: local coupling throughout, Fig. 4)
    target_gain    γ (eq. 15); target_normalised uses unit vectors in eq. 15
    barrier_gain   s_b (eq. 16); barrier_mode 'ahead' (default) or 'literal', see docs/model.md
    """

    kind: str = DEFAULTS['law']
    gains: PairGains = field(default_factory=PairGains)
    cutoff_radius: float = DEFAULTS['cutoff_radius']
    leader_gain: float = DEFAULTS['leader_gain']
    q0: float = DEFAULTS['q0']
    target_gain: float = DEFAULTS['target_gain']
    target_normalised: bool = DEFAULTS['target_normalised']
    barrier_gain: float = DEFAULTS['barrier_gain']
    barrier_mode: str = DEFAULTS['barrier_mode']

    def __post_init__(self):
        if self.kind not in LAW_KINDS:
            raise ValueError(f'law kind must be one of {LAW_KINDS}, got {self.kind!r}')
        if self.barrier_mode not in BARRIER_MODES:
            raise ValueError(f'barrier_mode must be one of {BARRIER_MODES}, got {self.barrier_mode!r}')

    def parameters(self) -> dict:
        """The law as flat parameters with the paper's names (an agent node's ROS parameters)."""
        return {p.name: getattr(self.gains if p.field in GAIN_FIELDS else self, p.field) for p in LAW_TABLE}

    @classmethod
    def from_parameters(cls, p: dict) -> 'LawConfig':
        """The inverse of `parameters`."""
        gains = PairGains(**{q.field: p[q.name] for q in LAW_TABLE if q.field in GAIN_FIELDS})
        return cls(gains=gains, **{q.field: p[q.name] for q in LAW_TABLE if q.field not in GAIN_FIELDS})

    @property
    def uses_leaders(self) -> bool:
        return self.kind in ('leader_following', 'homotopy')

    def effective_lambda_q0(self, lambda_: float) -> tuple[float, float]:
        """(λ, q0) at which the general homotopy form reproduces this law."""
        if self.kind == 'global':
            return 0.0, 1.0
        if self.kind == 'local':
            return 0.0, 0.0
        if self.kind == 'leader_following':
            return 1.0, 0.0
        return float(lambda_), float(self.q0)

    def couples_globally(self, lambda_: float) -> bool:
        """Whether pairs beyond w can carry weight (q(λ) > 0 or leaders with q0 > 0)."""
        if self.kind == 'target':
            return False
        lam, q0 = self.effective_lambda_q0(lambda_)
        return q0 > 0.0


GAIN_FIELDS = frozenset(f.name for f in fields(PairGains))

#: name → (description, range (lo, hi) | choices | None for a boolean) of each law parameter,
#: from `LAW_TABLE`; defaults: `LawConfig().parameters()`
LAW_PARAMETERS = {p.name: (p.description, p.choices or ((p.bound.lo, p.bound.hi) if p.bound else None))
                  for p in LAW_TABLE}
