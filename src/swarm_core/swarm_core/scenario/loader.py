"""Scenario files (YAML): everything a run needs, validated before anything runs (no ROS).

A bad file raises `ScenarioError` with one line naming the field, e.g.
``scenario.yaml: law.alpha: Input should be greater than or equal to 0 (got -1)``.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal, Optional, get_args

import numpy as np
import yaml
from pydantic import ConfigDict, Field, ValidationError, create_model, field_validator, model_validator

from swarm_core.analysis.outcomes import TRAJECTORY_CHECKS
from swarm_core.checks import InputError, check_run_size
from swarm_core.command.plan import CommandPlan
from swarm_core.command.spec import (
    ConstantLambdaSpec,
    LambdaSpec,
    LeadersSpec,
    LeadersSpec3,
    ProgramSpec,
    build_program,
    build_schedule,
)
from swarm_core.faults.agents import Fault, FaultTimeline, Rendezvous
from swarm_core.files import read_regular
from swarm_core.laws import Law, LawError, law_class, make_law, natural_control, swarm_control
from swarm_core.laws.paper.parameters import LAW_KINDS, LAW_TABLE
from swarm_core.laws.registry import law_code_hash
from swarm_core.model.integrate import noise_rng
from swarm_core.model.natural import initial_frames
from swarm_core.radio import CommModel
from swarm_core.reserved import check_law_names
from swarm_core.robot_spec import RobotsSpec
from swarm_core.scenario.placement import AgentsSpec, AgentsSpec3, initial_conditions, initial_conditions_3d
from swarm_core.scenario.sections import (
    BarrierSpec,
    BarrierSpec3,
    CommsSpec,
    ExpectSpec,
    FailoverSpec,
    FaultSpec,
    NoiseSpec,
    ReunionSpec,
    ReunionSpec3,
    TargetSpec,
    TargetSpec3,
)
from swarm_core.schema import RunSeconds, StepSeconds, Strict, bounded

#: largest scenario file read (bytes), checked before parsing
MAX_FILE_BYTES = 2 * 1024 * 1024


class ScenarioError(ValueError):
    """A scenario that cannot run; the message names the file and the field."""


# ------------------------------------------------------------------ law

def _law_field(p):
    """(type, default) of a law parameter in the schema (`paper.parameters.LAW_TABLE`)."""
    if p.choices:
        return Literal[p.choices], p.default
    return (bounded(p.bound) if p.bound else type(p.default)), p.default


LawSpec = create_model('LawSpec', __base__=Strict, __module__=__name__,
                       __doc__='The ``law:`` section: fields, defaults, bounds of `paper.parameters.LAW_TABLE`.',
                       **{p.scenario_key: _law_field(p) for p in LAW_TABLE if p.section == 'law'})


# ------------------------------------------------------------------ the whole file

class ScenarioSpec(Strict):
    name: str
    description: str = ''
    seed: Annotated[int, Field(ge=0)] = 0
    dt: StepSeconds = 0.05
    duration: RunSeconds = 1000.0
    integrator: Literal['zoh', 'rk4'] = 'zoh'
    agents: AgentsSpec
    law: LawSpec = Field(default_factory=LawSpec)
    lambda_: LambdaSpec = Field(default_factory=lambda: ConstantLambdaSpec(kind='constant'), alias='lambda')
    leaders: LeadersSpec = Field(default_factory=LeadersSpec)
    target: Optional[TargetSpec] = None
    barrier: Optional[BarrierSpec] = None
    noise: NoiseSpec = Field(default_factory=NoiseSpec)
    faults: list[FaultSpec] = Field(default_factory=list)
    failover: Optional[FailoverSpec] = None
    reunion: list[ReunionSpec] = Field(default_factory=list)
    comms: Optional[CommsSpec] = None
    robots: Optional[RobotsSpec] = None          # the scale to robots (swarm_core.robot_spec)
    expect: dict = Field(default_factory=dict)   # what `swarm sweep` checks (see outcomes.py)
    model_config = ConfigDict(extra='forbid', populate_by_name=True)

    @field_validator('name')
    @classmethod
    def _name(cls, v):
        if not v.strip():
            raise ValueError('must not be empty')
        if len(v) > 200:
            raise ValueError('longer than 200 characters')
        return v

    @field_validator('expect', mode='before')
    @classmethod
    def _expect(cls, v):
        """Checked against `ExpectSpec`, kept as the plain mapping outcomes.py reads."""
        if v is None:
            return {}
        if not isinstance(v, dict):
            raise ValueError('expect is a mapping of checks (see outcomes.py)')
        spec = ExpectSpec.model_validate(v)
        return {k: (list(x) if isinstance(x, tuple) else x)
                for k, x in spec.model_dump(by_alias=True, exclude_unset=True).items()}

    @model_validator(mode='after')
    def _steps(self):
        steps = round(self.duration / self.dt)
        if steps < 1:
            raise ValueError(f'duration {self.duration:g} is shorter than one step (dt {self.dt:g}): '
                             'nothing would run')
        check_run_size(steps, self.agents.count or 0)
        return self

    @model_validator(mode='after')
    def _reunion_vs_target(self):
        if self.reunion and self.target is not None:
            raise ValueError('reunion: a scenario with a target cannot also have a rendezvous '
                             '(both use the target term of eq. 15)')
        return self


#: the sections a 3D scenario cannot have yet
NOT_YET_3D = ('robots',)


class ScenarioSpec3(ScenarioSpec):
    """A scenario in three dimensions (``dim: 3``): 3D agents, leader programs (s_u, s_v),
    target, barrier (with a ground) and rendezvous point; the paper's law lifted to 3D
    (docs/model.md).  Faults, failover, the radio and noise are the planar sections."""
    dim: Literal[3]
    agents: AgentsSpec3
    leaders: LeadersSpec3 = Field(default_factory=LeadersSpec3)
    target: Optional[TargetSpec3] = None
    barrier: Optional[BarrierSpec3] = None
    reunion: list[ReunionSpec3] = Field(default_factory=list)



# ------------------------------------------------------------------ runtime scenario

@dataclass
class Scenario:
    """A validated scenario with its initial conditions drawn for one seed."""

    spec: ScenarioSpec
    names: list
    pos0: np.ndarray
    theta0: np.ndarray
    law: Law
    source: str = ''
    #: a hash of the user's law file(s) as loaded ('' for a shipped law, `law_code_hash`):
    #: metrics.json and events.jsonl record it, ``--replay`` compares it with the file now
    law_hash: str = ''
    #: a 3D scenario's initial frames (x, y, z), (N, 3) each (its theta0 is None)
    frames0: tuple | None = None

    @property
    def dim(self) -> int:
        """2 (planar) or 3."""
        return getattr(self.spec, 'dim', 2)

    @property
    def ground(self):
        """The floor's height of a 3D barrier, or None."""
        return getattr(self.spec.barrier, 'ground', None)

    # -- convenience views of the spec
    @property
    def name(self):
        return self.spec.name

    @property
    def label(self) -> str:
        """The name made safe as one file-name component (`safe_label`)."""
        return safe_label(self.spec.name)

    @property
    def seed(self):
        return self.spec.seed

    @property
    def dt(self):
        return self.spec.dt

    @property
    def content_hash(self) -> str:
        """A hash of the validated scenario (with its overrides: seed, dt, duration): two
        processes that loaded the same run have the same one (``swarm join`` checks it)."""
        text = json.dumps(self.spec.model_dump(mode='json', by_alias=True), sort_keys=True, separators=(',', ':'))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @property
    def duration(self):
        return self.spec.duration

    @property
    def steps(self) -> int:
        return int(round(self.spec.duration / self.spec.dt))

    @property
    def target(self):
        return None if self.spec.target is None else np.array(self.spec.target.position, float)

    @property
    def barrier(self):
        if self.spec.barrier is None or not self.spec.barrier.points:
            return None
        return np.array(self.spec.barrier.points, float)

    def command_plan(self) -> CommandPlan:
        """A fresh commander plan (λ schedule and leaders) for this scenario."""
        return CommandPlan(schedule=build_schedule(self.spec.lambda_),
                           fixed_leaders={self.names.index(n): build_program(p)
                                          for n, p in self.spec.leaders.fixed.items()},
                           rule=self.spec.leaders.rule, choose_at=self.spec.leaders.at,
                           rule_programs=[build_program(p) for p in self.spec.leaders.programs],
                           failover_timeout=self.spec.failover.timeout if self.spec.failover else None,
                           rendezvous=[Rendezvous(r.at, r.for_, None if r.point == 'centroid' else
                                                  r.point if r.point == 'none' else tuple(r.point),
                                                  r.gain, r.normalised, r.track, r.coupling)
                                       for r in self.spec.reunion],
                           steering_shape=() if self.dim == 2 else (2,))

    def fault_timeline(self) -> FaultTimeline:
        """A fresh timeline of the scenario's faults (faults.py)."""
        return FaultTimeline([Fault(f.at, f.kind, f.agent, f.for_ or 0.0) for f in self.spec.faults],
                             self.names, self.spec.dt)

    def comms_config(self) -> dict | None:
        """The ``comms`` section as a plain mapping (what `swarm_core.radio.CommModel.from_config` and
        the agents' ``comms`` parameter take), None without one."""
        return None if self.spec.comms is None else self.spec.comms.model_dump(mode='json')

    def comm_model(self):
        """A fresh `swarm_core.radio.CommModel` of this scenario, or None if its radio is perfect."""
        m = CommModel.from_config(self.comms_config(), self.names, self.dt, self.seed)
        return None if m.perfect else m

    def noise_rng(self, index: int) -> np.random.Generator:
        """Agent ``index``'s own noise stream (the same in the batch engine and its node)."""
        return noise_rng(self.spec.seed, index)


def _kinds(union) -> str:
    """'a, b, c': the ``kind`` tags of a discriminated union such as `LambdaSpec`."""
    return ', '.join(get_args(m.model_fields['kind'].annotation)[0] for m in get_args(get_args(union)[0]))


#: top-level field → the discriminated union found under it (for "no kind given" errors)
_UNION_OF = {'lambda': LambdaSpec, 'leaders': ProgramSpec}


def _format_error(err: ValidationError) -> str:
    e = err.errors()[0]
    loc = '.'.join(str(p) for p in e['loc'] if not str(p).startswith('function-')) or '(top level)'
    if e['type'] == 'union_tag_not_found' and e['loc']:
        union = _UNION_OF.get(str(e['loc'][0]))
        kinds = f' (one of: {_kinds(union)})' if union is not None else ''
        return f'{loc}: needs a `kind:` field{kinds}'
    # discriminated unions put the tag in the path: keep it readable
    more = len(err.errors()) - 1
    tail = f' [+{more} more problem{"s" if more > 1 else ""}]' if more else ''
    if isinstance(e.get('ctx', {}).get('error'), InputError):    # a `Bound`'s one text, as it is
        return f'{loc}: {e["ctx"]["error"]}{tail}'
    got = e.get('input')
    got_s = '' if isinstance(got, (dict, list)) or got is None else f' (got {got!r})'
    return f'{loc}: {e["msg"]}{got_s}{tail}'


def safe_label(name: str) -> str:
    """``name`` as one file-name component: anything but letters, digits, ``-``, ``_`` and
    single dots becomes ``_``; leading and trailing dots and underscores go.  So ``../x`` or
    ``/etc/x`` stays inside the output directory (the name itself is only a label)."""
    out = re.sub(r'[^A-Za-z0-9_.-]+', '_', name)
    out = re.sub(r'_+', '_', re.sub(r'\.{2,}', '_', out)).strip('._')
    return out[:100] or 'scenario'


SCENARIO_DIR = 'scenarios'


def shipped_scenarios() -> list[str]:
    """Names of the scenarios shipped with swarm_core."""
    root = resources.files('swarm_core') / SCENARIO_DIR
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith('.yaml'))


def read_text(path, what: str = 'file', hint: str = '') -> str:
    """The text of the input file ``path`` (a scenario, a study, a robot description) with the
    limits of every YAML input: a regular file (a FIFO, a device or a directory is refused,
    never read or waited on; `files.read_regular`) of at most `MAX_FILE_BYTES`, UTF-8.
    ScenarioError naming ``path`` (``what`` it is; ``hint``: how to stay within the size)."""
    if '\0' in str(path):
        raise ScenarioError(f'{str(path)!r}: a path with a NUL byte names no {what}')
    try:
        raw = read_regular(path, MAX_FILE_BYTES)
    except FileNotFoundError:
        raise ScenarioError(f'{path}: no such {what}') from None
    except OSError as err:
        raise ScenarioError(f'{path}: cannot read: {err.strerror or err}') from None
    except ValueError as err:
        raise ScenarioError(f'{path}: {err}; a {what} is at most {MAX_FILE_BYTES} bytes{hint}') from None
    try:
        return raw.decode('utf-8')
    except UnicodeDecodeError as err:
        raise ScenarioError(f'{path}: not UTF-8 text ({err.reason} at byte {err.start})') from None


def resolve(name_or_path: str) -> tuple[str, str]:
    """(text, source) of a shipped scenario name or a YAML file path."""
    if '\0' in str(name_or_path):
        raise ScenarioError(f'{str(name_or_path)!r}: a path with a NUL byte names no scenario file')
    p = Path(name_or_path)
    if p.suffix in ('.yaml', '.yml') or p.exists() or p.is_symlink():
        return read_text(p, 'scenario file', ' (give large swarms a placement rule)'), str(p)
    res = resources.files('swarm_core') / SCENARIO_DIR / f'{name_or_path}.yaml'
    if not res.is_file():
        raise ScenarioError(f'{name_or_path}: not a shipped scenario ({", ".join(shipped_scenarios())}) '
                            'nor a .yaml file')
    return res.read_text(), f'{name_or_path} (shipped)'


def _section_values(spec: ScenarioSpec, sections) -> dict:
    """The paper's law parameters that ``sections`` set, by name: each from its section of a
    validated spec (`paper.parameters.LAW_TABLE`), its default where the scenario has no such
    section (no target, no barrier: their terms are off)."""
    def value(p):
        section = getattr(spec, p.section)
        return p.default if section is None else getattr(section, p.scenario_key)
    return {p.name: value(p) for p in LAW_TABLE if p.section in sections and p.name != 'law'}


def law_config(spec: ScenarioSpec) -> Law:
    """The paper's law of a validated spec (its ``law:``, ``target:`` and ``barrier:`` sections)."""
    return law_class(spec.law.kind)(**_section_values(spec, ('law', 'target', 'barrier')))


def _law_of_another_kind(data: dict, source: str):
    """The `Law` of a ``law:`` section whose kind is not one of the paper's (a shipped law,
    a blend, a user's file or module), checked; None for the paper's law, whose section the
    schema checks.  The section is then left to the schema at its defaults."""
    section = data.get('law')
    if not isinstance(section, dict) or section.get('kind', LAW_KINDS[0]) in LAW_KINDS:
        return None
    path = Path(source)
    try:
        law = make_law(section, base_dir=path.parent if path.is_file() else None)
        check_law_names(law)        # no parameter an agent node or Law already has (every engine alike)
    except LawError as err:
        raise ScenarioError(f'{source}: {err}') from None
    data['law'] = {}
    return law


def _try_law(scn, source):
    """Evaluate a law other than the paper's once on the initial state (t = 0, λ of t = 0, no
    leaders yet), so that a law that raises, returns the wrong shape or a non-finite u there
    is refused with the scenario, before anything runs: ScenarioError naming the law."""
    th = scn.theta0
    try:
        lam = float(scn.command_plan().schedule.value(0.0))
        if scn.dim == 3:
            natural_control(scn.pos0, scn.frames0, np.arange(len(scn.pos0)), scn.law, lambda_=lam,
                            target=scn.target, barrier=scn.barrier, ground=scn.ground, t=0.0)
        else:
            swarm_control(scn.pos0, np.cos(th), np.sin(th), np.arange(len(th)), scn.law, lambda_=lam,
                          target=scn.target, barrier=scn.barrier, t=0.0)
    except LawError as err:
        raise ScenarioError(f'{source}: {err} (at t = 0, on the initial state)') from None


def _spec_model(data: dict, source: str):
    """`ScenarioSpec` (``dim`` 2 or left out: taken out of ``data``, so a planar scenario is what
    it was) or `ScenarioSpec3` (``dim: 3``); ScenarioError for any other ``dim``."""
    dim = data.get('dim', 2)
    if isinstance(dim, bool) or dim not in (2, 3):
        raise ScenarioError(f'{source}: dim: must be 2 or 3 (got {dim!r})')
    if dim == 2:
        data.pop('dim', None)
        return ScenarioSpec
    for key in NOT_YET_3D:
        if data.get(key):
            raise ScenarioError(f'{source}: {key}: not in 3D scenarios yet (dim: 3)')
    for key in data.get('expect') or ():
        if key in TRAJECTORY_CHECKS:
            raise ScenarioError(f'{source}: expect.{key}: a planar check, not in 3D scenarios (dim: 3)')
    return ScenarioSpec3


def parse(data: dict, source: str = '<dict>', **overrides) -> Scenario:
    """Validate a scenario mapping; ``overrides`` (seed, duration, dt) replace its fields."""
    if not isinstance(data, dict):
        raise ScenarioError(f'{source}: a scenario is a YAML mapping, got {type(data).__name__}')
    data = dict(data)
    for key, val in overrides.items():
        if val is not None:
            data[key] = val
    model = _spec_model(data, source)
    plugin = _law_of_another_kind(data, source)
    try:
        spec = model.model_validate(data)
    except ValidationError as err:
        raise ScenarioError(f'{source}: {_format_error(err)}') from None
    # the target and barrier terms reach each paper's law a law holds (a blend's from or to)
    try:
        law = law_config(spec) if plugin is None else plugin.with_world(_section_values(spec, ('target', 'barrier')))
    except LawError as err:
        raise ScenarioError(f'{source}: {err}') from None
    if model is ScenarioSpec3 and 3 not in law.dims:
        raise ScenarioError(f'{source}: law {law.kind} is planar only (its dims: {law.dims}): a 3D scenario '
                            '(dim: 3) needs a law with 3 in its dims')
    if spec.reunion and not {'target_gain', 'target_normalised', 'q0'} <= set(law.param_specs()):
        raise ScenarioError(f'{source}: reunion: the rendezvous changes the paper\'s law, not law {law.kind}')
    names = list(spec.agents.names) if spec.agents.names else None
    for who in spec.leaders.fixed:
        known = names or [f'agent_{i}' for i in range(spec.agents.count)]
        if who not in known:
            raise ScenarioError(f'{source}: leaders.fixed.{who}: unknown agent (agents are {", ".join(known[:8])}'
                                f'{", ..." if len(known) > 8 else ""})')
    known = names or [f'agent_{i}' for i in range(spec.agents.count)]
    for i, f in enumerate(spec.faults):
        if not f.agent.startswith('leader:') and f.agent not in known:
            raise ScenarioError(f'{source}: faults.{i}.{f.kind}: unknown agent {f.agent!r} (agents are '
                                f'{", ".join(known[:8])}{", ..." if len(known) > 8 else ""})')
    frames0 = None
    if model is ScenarioSpec3:
        names, pos0, headings = initial_conditions_3d(spec)
        theta0, frames0 = None, initial_frames(headings)
    else:
        names, pos0, theta0 = initial_conditions(spec)
    if spec.comms is not None:
        try:
            CommModel.from_config(spec.comms.model_dump(mode='json'), names, spec.dt, spec.seed)
        except ValueError as err:
            raise ScenarioError(f'{source}: {err}') from None
        if spec.integrator != 'zoh' and spec.comms.model_dump() != CommsSpec().model_dump():
            raise ScenarioError(f'{source}: comms: a communication model needs integrator zoh')
    try:
        read_description(spec.robots, Path(source).parent if Path(source).is_file() else None)
    except ScenarioError as err:
        raise ScenarioError(f'{source}: {err}') from None
    scn = Scenario(spec=spec, names=names, pos0=pos0, theta0=theta0, law=law, source=source, frames0=frames0)
    if plugin is not None:
        scn.law_hash = law_code_hash(law.mapping())         # the file as this process imported it
        _try_law(scn, source)
    return scn


_Loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)     # libyaml when there (4x faster)


#: deepest nesting of a scenario or study file (the schema nests about 6 levels)
MAX_YAML_DEPTH = 32


def safe_yaml(text: str):
    """Parse YAML text with the safe loader, refusing anchors and aliases (``&a`` / ``*a``)
    and nesting deeper than `MAX_YAML_DEPTH`: an alias bomb (a few lines that expand to
    billions of values) is refused before anything is built from it.  The node graph is
    composed, checked (an alias is a node met twice), then constructed."""
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        seen, stack = set(), [(node, 1)]
        while stack:
            nd, depth = stack.pop()
            if id(nd) in seen:
                mark = nd.start_mark
                raise yaml.composer.ComposerError(None, None, 'YAML aliases (*name) are not allowed',
                                                  mark)
            if depth > MAX_YAML_DEPTH:
                raise yaml.composer.ComposerError(None, None, f'nested deeper than {MAX_YAML_DEPTH} levels',
                                                  nd.start_mark)
            seen.add(id(nd))
            if isinstance(nd, yaml.SequenceNode):
                stack.extend((v, depth + 1) for v in nd.value)
            elif isinstance(nd, yaml.MappingNode):
                stack.extend((x, depth + 1) for kv in nd.value for x in kv)
        return loader.construct_document(node)
    finally:
        loader.dispose()


def _yaml_of(text: str, source: str):
    try:
        return safe_yaml(text)
    except yaml.YAMLError as err:
        msg = ' '.join(str(err).split())
        raise ScenarioError(f'{source}: not valid YAML: {msg[:300]}') from None


def read_yaml(name_or_path: str):
    """(data, source) of a shipped scenario or a YAML file (a scenario or a study) with the
    limits of every YAML input: `MAX_FILE_BYTES`, no aliases, `MAX_YAML_DEPTH`."""
    text, source = resolve(name_or_path)
    if len(text) > MAX_FILE_BYTES:
        raise ScenarioError(f'{source}: more than {MAX_FILE_BYTES} bytes')
    return _yaml_of(text, source), source


def read_yaml_file(path, what: str = 'file'):
    """The data of the YAML file ``path`` (``what`` it is: a robot description) with the
    limits of every YAML input (`read_text`, `safe_yaml`); ScenarioError naming ``path``."""
    return _yaml_of(read_text(path, what), str(path))


def description_path(name: str, base_dir=None) -> Path:
    """The file a ``robots: description:`` names: an absolute path as it is, a relative one
    relative to ``base_dir``, the directory of the scenario that names it (None: a scenario
    that is no file; the working directory)."""
    p = Path(name)
    return Path(os.path.abspath(p if p.is_absolute() or base_dir is None else Path(base_dir) / p))


def read_description(robots: RobotsSpec, base_dir=None) -> None:
    """Read and check the robot description the ``robots:`` section ``robots`` names (if any;
    `description_path`) with the limits of every YAML input, and keep its values in the section
    (`RobotsSpec.take_description`).  ScenarioError ``robots.description: FILE: ...`` naming
    what is wrong (the file, or a field of it)."""
    if robots is None or not robots.description:
        return
    path = description_path(robots.description, base_dir)
    try:
        robots.take_description(read_yaml_file(path, 'robot description'), str(path))
    except (ScenarioError, InputError) as err:
        raise ScenarioError(f'robots.description: {err}') from None


def load(name_or_path: str, **overrides) -> Scenario:
    """Load a shipped scenario by name, or a YAML file, with optional overrides."""
    data, source = read_yaml(name_or_path)
    return parse(data, source, **overrides)
