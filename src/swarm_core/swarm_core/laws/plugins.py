"""Laws by name (no ROS): the paper's kinds, the shipped laws, ``blend``, and a user's law from a
file (``path/to/alignment.py:Alignment``, relative to the scenario file) or a module
(``package.module:Class``); and a law as flat parameters, which is how agent nodes get it.

A law file is code the run executes, as a pytest conftest is: it runs in every process that
uses the law (the engines, every agent node).
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
from pathlib import Path

from swarm_core.laws.base import Law, LawError
from swarm_core.laws.blend import Blend
from swarm_core.laws.config import LAW_PARAMETERS, LawConfig
from swarm_core.laws.parameters import LAW_KINDS, LAW_PARAMETER, LAW_TABLE
from swarm_core.laws.spl import CircularFormation, ParallelFormation

#: the shipped laws of the `Law` interface, by kind
SHIPPED = {cls.kind: cls for cls in (ParallelFormation, CircularFormation)}
#: every kind a scenario may name besides a user's ``file.py:Class`` or ``module:Class``
KINDS = (*LAW_KINDS, *SHIPPED, Blend.kind)
#: the paper's law parameters a ``law:`` section sets (the others are the target/barrier sections')
PAPER_KEYS = tuple(p.scenario_key for p in LAW_TABLE if p.section == 'law')


#: the law files imported in this process: resolved path → ((mtime, size), module)
_FILES = {}


def _law_file(kind: str, path: Path):
    """The module of law file ``path``, imported once while the file is unchanged (so that a law
    named twice is one class: laws compare equal by class and parameters), again if it changed."""
    stat = path.stat()
    stamp = (stat.st_mtime_ns, stat.st_size)
    known = _FILES.get(path)
    if known is not None and known[0] == stamp:
        return known[1]
    mod_name = f'swarm_user_law_{hashlib.sha256(str(path).encode()).hexdigest()[:16]}'
    try:
        spec = importlib.util.spec_from_file_location(mod_name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[mod_name] = module
        spec.loader.exec_module(module)
    except Exception as err:   # a law file that does not import: named in one line
        sys.modules.pop(mod_name, None)
        raise LawError(f'law.kind {kind!r}: {path.name} does not import: {type(err).__name__}: {err}') from None
    _FILES[path] = (stamp, module)
    return module


def law_class(kind: str, base_dir=None, field: str = 'law') -> type[Law]:
    """The `Law` subclass a kind names: a shipped one, ``FILE.py:Class`` (relative to
    ``base_dir``) or ``module:Class``.  LawError names the kind and the problem."""
    if kind in SHIPPED:
        return SHIPPED[kind]
    source, sep, name = kind.rpartition(':')
    if not sep or not source or not name.isidentifier():
        raise LawError(f'{field}.kind {kind!r}: not a law kind ({", ".join(KINDS)}) nor FILE.py:Class nor module:Class')
    if source.endswith('.py'):
        path = Path(source)
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
        path = path.resolve()
        if not path.is_file():
            raise LawError(f'{field}.kind {kind!r}: no file {path}')
        module = _law_file(kind, path)
        kind_name = f'{path}:{name}'
    else:
        try:
            module = importlib.import_module(source)
        except Exception as err:   # a module that does not import: named in one line
            raise LawError(f'{field}.kind {kind!r}: module {source} does not import: '
                           f'{type(err).__name__}: {err}') from None
        kind_name = kind
    cls = getattr(module, name, None)
    if cls is None:
        raise LawError(f'{field}.kind {kind!r}: {source} has no {name}')
    if not (isinstance(cls, type) and issubclass(cls, Law)) or cls is Law:
        raise LawError(f'{field}.kind {kind!r}: {name} is not a law (a subclass of swarm_core.laws.Law)')
    if issubclass(cls, Blend):
        raise LawError(f'{field}.kind {kind!r}: a blend is named as kind: blend')
    cls.kind = kind_name
    return cls


def law_code_hash(mapping, base_dir=None) -> str:
    """A hash of the source files of the users' laws a ``law:`` mapping names (a blend's too),
    '' for shipped laws: a study's cache keys carry it, so that an edited law file reruns."""
    files = []

    def walk(m):
        if not isinstance(m, dict):
            return
        kind = m.get('kind')
        if kind == Blend.kind:
            walk(m.get('from'))
            walk(m.get('to'))
        elif isinstance(kind, str) and kind not in KINDS and ':' in kind:
            where = kind.rpartition(':')[0]
            if where.endswith('.py'):
                path = Path(where)
                files.append(path if path.is_absolute() or base_dir is None else Path(base_dir) / path)
            else:
                spec = importlib.util.find_spec(where.split('.')[0]) and importlib.util.find_spec(where)
                if spec is not None and spec.origin:
                    files.append(Path(spec.origin))
    walk(mapping)
    if not files:
        return ''
    h = hashlib.sha256()
    for f in files:
        try:
            h.update(f.resolve().read_bytes())
        except OSError:
            h.update(str(f).encode())
    return h.hexdigest()[:16]


def paper_law(mapping: dict, where: str = 'law') -> LawConfig:
    """The paper's law of a ``law:`` mapping ({kind, alpha, ...}), each value checked against
    `LAW_TABLE` (the target and barrier terms are their sections' and stay off here)."""
    values = {p.name: p.default for p in LAW_TABLE}
    for key, v in mapping.items():
        name = 'law' if key == 'kind' else key
        p = LAW_PARAMETER.get(name)
        if p is None or p.section != 'law':
            raise LawError(f'{where}: unknown parameter {key!r} of the paper\'s law (known: {", ".join(PAPER_KEYS)})')
        if p.choices:
            if v not in p.choices:
                raise LawError(f'{where}: {key} must be one of {", ".join(p.choices)}, got {v!r}')
        elif p.bound is not None:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not p.bound.ok(float(v)):
                raise LawError(f'{where}: {key} = {v!r} is outside [{p.bound.lo:g}, {p.bound.hi:g}]')
            v = float(v)
        values[name] = v
    return LawConfig.from_parameters(values)


def make_law(mapping, base_dir=None, where: str = 'law'):
    """The law of a scenario's ``law:`` mapping: a `LawConfig` for the paper's kinds, else a
    `Law` (shipped, ``blend`` of two, or a user's).  LawError names the problem."""
    if not isinstance(mapping, dict) or 'kind' not in mapping:
        raise LawError(f'{where}: a law is a mapping with a kind ({", ".join(KINDS)} or FILE.py:Class)')
    kind, rest = mapping['kind'], {k: v for k, v in mapping.items() if k != 'kind'}
    if not isinstance(kind, str):
        raise LawError(f'{where}.kind: a string, got {kind!r}')
    if kind in LAW_KINDS:
        return paper_law(mapping, where)
    if kind == Blend.kind:
        extra = sorted(set(rest) - {'from', 'to'})
        if extra or 'from' not in rest or 'to' not in rest:
            raise LawError(f'{where}: a blend has exactly from: <law> and to: <law>'
                           + (f' (unknown key {extra[0]!r})' if extra else ''))
        return Blend(make_law(rest['from'], base_dir, f'{where}.from'), make_law(rest['to'], base_dir, f'{where}.to'))
    cls = law_class(kind, base_dir, where)
    try:
        return cls(**rest)
    except LawError:
        raise
    except Exception as err:   # a user's __init__
        raise LawError(f'law {cls.kind}: {type(err).__name__}: {err}') from None


def law_kind(law) -> str:
    """The kind of any law (a `LawConfig`'s or a `Law`'s)."""
    return law.kind


def law_mapping(law) -> dict:
    """A law as a scenario's ``law:`` section: ``{kind, parameter: value...}`` (blend:
    ``{kind: blend, from: {...}, to: {...}}``), as metrics.json records it."""
    if isinstance(law, LawConfig):
        return {'kind' if k == 'law' else k: v for k, v in law.parameters().items()
                if LAW_PARAMETER[k].section == 'law'}
    if isinstance(law, Blend):
        return {'kind': Blend.kind, 'from': law_mapping(law.from_law), 'to': law_mapping(law.to_law)}
    return {'kind': law.kind, **law.parameters()}


def flat_parameters(law, prefix: str = '') -> dict:
    """The law as flat parameters ``{law: kind, name: value...}`` (blend: ``from.law``,
    ``from.NAME``, ``to.law``...): an agent node's ROS parameters."""
    if isinstance(law, LawConfig):
        return {prefix + k: v for k, v in law.parameters().items()}
    if isinstance(law, Blend):
        return {prefix + 'law': Blend.kind, **flat_parameters(law.from_law, prefix + 'from.'),
                **flat_parameters(law.to_law, prefix + 'to.')}
    return {prefix + 'law': law.kind, **{prefix + k: v for k, v in law.parameters().items()}}


def from_flat_parameters(flat: dict, prefix: str = ''):
    """The inverse of `flat_parameters`."""
    kind = flat[prefix + 'law']
    if kind in LAW_KINDS:
        return LawConfig.from_parameters({p.name: flat[prefix + p.name] for p in LAW_TABLE})
    if kind == Blend.kind:
        return Blend(from_flat_parameters(flat, prefix + 'from.'), from_flat_parameters(flat, prefix + 'to.'))
    cls = law_class(kind)
    return cls(**{k: flat[prefix + k] for k in cls.param_specs()})


def default_law(kinds: dict, prefix: str = ''):
    """The law named by the kinds of flat parameters (``law``, and a blend's ``from.law``,
    ``to.law``) with every other parameter at its default: what a node declares from."""
    kind = kinds[prefix + 'law']
    if kind in LAW_KINDS:
        return LawConfig(kind=kind)
    if kind == Blend.kind:
        return Blend(default_law(kinds, prefix + 'from.'), default_law(kinds, prefix + 'to.'))
    return law_class(kind)()


def parameter_specs(law, prefix: str = '') -> dict:
    """name → (default, description, range or choices or None) of every flat parameter of a law,
    for an agent node to declare (the paper's: `LAW_PARAMETERS`)."""
    if isinstance(law, LawConfig):
        defaults = LawConfig().parameters()
        return {prefix + k: (defaults[k], *LAW_PARAMETERS[k]) for k in defaults}
    if isinstance(law, Blend):
        return {prefix + 'law': (Blend.kind, 'control law: blend of from and to, u = (1 − λ) u_from + λ u_to', None),
                **parameter_specs(law.from_law, prefix + 'from.'), **parameter_specs(law.to_law, prefix + 'to.')}
    out = {prefix + 'law': (law.kind, f'control law: {law.kind}', None)}
    for name, spec in type(law).param_specs().items():
        out[prefix + name] = (spec.default if not spec.integer else int(spec.default), spec.doc, (spec.lo, spec.hi))
    return out
