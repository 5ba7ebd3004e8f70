"""The paper's law's parameters, declared once (no ROS): name, default, description, bounds or choices.

Everything else is derived from `LAW_TABLE`: the `param`s of the paper's laws
(`paper.laws.PaperLaw`) and so their flat form and the agent node's ROS parameters with
descriptions and ranges, and the scenario schema (the ``law:`` section, `scenario.LawSpec`,
and the gains of ``target:`` and ``barrier:``), so a scenario and a ROS parameter accept the
same values.  Ranges are closed, as a ROS FloatingPointRange is.  Equation numbers are the paper's.
"""
from __future__ import annotations

from dataclasses import dataclass

from swarm_core.checks import MAX_COORD, MAX_GAIN, Bound

LAW_KINDS = ('global', 'local', 'leader_following', 'homotopy', 'target')
BARRIER_MODES = ('ahead', 'literal')

#: least length (r0, w): positive, in a closed range
MIN_LENGTH = 1e-9


@dataclass(frozen=True)
class LawParameter:
    """One law parameter.  Its type is that of its default (float, bool or str)."""

    name: str                   # the flat (ROS parameter) name, the paper's
    default: object             # the law's (a scenario's target / barrier gain has its own)
    description: str
    bound: Bound | None = None  # a real parameter's range
    choices: tuple = ()         # a choice parameter's values
    section: str = 'law'        # the scenario section that sets it
    key: str = ''               # its key there ('' = name)

    @property
    def scenario_key(self) -> str:
        return self.key or self.name


def _real(name, default, description, lo, hi, **kw) -> LawParameter:
    return LawParameter(name, default, description, Bound(name, lo, hi), **kw)


LAW_TABLE = (
    LawParameter('law', 'homotopy', 'control law: global (eq. 4), local (eq. 9), leader_following '
                 '(eq. 10-11), homotopy (eq. 12-14), target (eq. 15)', choices=LAW_KINDS, key='kind'),
    _real('alpha', 0.02, 'spacing gain α of the pair term (eq. 5)', 0.0, MAX_GAIN),
    _real('eta', 0.02, 'baseline gain η of the pair term (eq. 5)', 0.0, MAX_GAIN),
    _real('mu', 0.02, 'alignment gain μ of the pair term (eq. 5)', 0.0, MAX_GAIN),
    _real('r0', 1.5, 'preferred spacing r0 in f(ρ) (eq. 6)', MIN_LENGTH, MAX_COORD),
    _real('cutoff_radius', 4.0, 'cutoff (communication and sensing) radius w (eq. 8)', MIN_LENGTH, MAX_COORD),
    _real('leader_gain', 30.0, 'leader coupling ℓc ≫ 1 (eq. 10, 13)', 1.0, MAX_GAIN),
    _real('q0', 1.0, 'far-coupling weight q0 at λ = 0 (eq. 12-14)', 0.0, 1.0),
    _real('target_gain', 0.0, 'target gain γ (eq. 15); 0: no target term', 0.0, MAX_GAIN,
          section='target', key='gain'),
    LawParameter('target_normalised', False, 'use unit vectors in the target term (eq. 15)',
                 section='target', key='normalised'),
    _real('barrier_gain', 0.0, 'barrier gain s_b (eq. 16); 0: no barrier term', 0.0, MAX_GAIN,
          section='barrier', key='gain'),
    LawParameter('barrier_mode', 'ahead', 'barrier term reading (eq. 16): ahead or literal (docs/model.md)',
                 choices=BARRIER_MODES, section='barrier', key='mode'),
)

#: name → `LawParameter`
LAW_PARAMETER = {p.name: p for p in LAW_TABLE}
#: name → default
DEFAULTS = {p.name: p.default for p in LAW_TABLE}
