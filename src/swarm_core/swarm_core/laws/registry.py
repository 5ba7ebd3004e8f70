"""Laws by name (no ROS), shaped like the engines' registry (`engine.registry`): the built-in
laws, those that installed packages register, and a user's law from a file
(``path/to/alignment.py:Alignment``, relative to the scenario file) or a module
(``package.module:Class``); a law from a scenario's mapping (`make_law`) and from flat
parameters, which is how agent nodes get it.

A package adds a law under the entry-point group ``swarm_core.laws`` (``my_law =
my_package.laws:MyLaw``), as pytest plugins add themselves, and a scenario names it
``law: {kind: my_law}``.  A name that two sources claim is refused, naming both.

A law file is code the run executes, as a pytest conftest is: it runs in every process that
uses the law (the engines, every agent node).
"""
from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import sys
from importlib.metadata import entry_points
from pathlib import Path

from swarm_core.laws.base import Law, LawError

GROUP = 'swarm_core.laws'
#: the laws of swarm_core itself: kind -> 'module:Class'
BUILT_IN = {
    'global': 'swarm_core.laws.paper.laws:Global',
    'local': 'swarm_core.laws.paper.laws:Local',
    'leader_following': 'swarm_core.laws.paper.laws:LeaderFollowing',
    'homotopy': 'swarm_core.laws.paper.laws:Homotopy',
    'target': 'swarm_core.laws.paper.laws:Target',
    'spl_parallel': 'swarm_core.laws.spl:ParallelFormation',
    'spl_circular': 'swarm_core.laws.spl:CircularFormation',
    'blend': 'swarm_core.laws.blend:Blend',
}


def _registered() -> dict:
    """kind -> [source, ...] of every registered law: 'built-in module:Class' or 'entry point
    module:Class (distribution)'; more than one source is a clash.  Read once per sys.path (a
    scan of the installed packages costs milliseconds; a scenario load asks every time)."""
    return _registered_on(tuple(sys.path))


@functools.lru_cache(maxsize=4)
def _registered_on(path: tuple) -> dict:
    out = {kind: [f'built-in {where}'] for kind, where in BUILT_IN.items()}
    for ep in entry_points(group=GROUP):
        dist = getattr(ep.dist, 'name', None)
        out.setdefault(ep.name, []).append(f'entry point {ep.value}' + (f' ({dist})' if dist else ''))
    return out


def names() -> list[str]:
    """Every registered law's kind: the built-in ones, then the registered ones."""
    return [*BUILT_IN, *sorted(k for k in _registered() if k not in BUILT_IN)]


def _by_name(kind: str, field: str):
    """The class registered as ``kind``, or None; LawError if two sources claim it."""
    sources = _registered().get(kind)
    if sources is None:
        return None
    if len(sources) > 1:
        raise LawError(f'{field}.kind {kind!r}: claimed by two sources: {" and ".join(sources)}')
    if kind in BUILT_IN:
        module, name = BUILT_IN[kind].split(':')
        return getattr(importlib.import_module(module), name)
    ep = next(iter(entry_points(group=GROUP, name=kind)))
    try:
        cls = ep.load()
    except Exception as err:   # a registered law that does not import: named in one line
        raise LawError(f'{field}.kind {kind!r}: entry point {ep.value} does not import: '
                       f'{type(err).__name__}: {err}') from None
    _check_class(cls, kind, ep.value.rpartition(':')[2], field)
    if cls.kind != kind:
        cls.kind = kind
    return cls


def _check_class(cls, kind, name, field):
    if not (isinstance(cls, type) and issubclass(cls, Law)) or cls is Law:
        raise LawError(f'{field}.kind {kind!r}: {name} is not a law (a subclass of swarm_core.laws.Law)')


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
    except (Exception, SystemExit) as err:   # a law file that does not import (or exits): one line
        sys.modules.pop(mod_name, None)
        raise LawError(f'law.kind {kind!r}: {path.name} does not import: {type(err).__name__}: {err}') from None
    _FILES[path] = (stamp, module)
    return module


def law_class(kind: str, base_dir=None, field: str = 'law') -> type[Law]:
    """The `Law` subclass a kind names: a registered one, ``FILE.py:Class`` (relative to
    ``base_dir``) or ``module:Class``.  LawError names the kind and the problem."""
    cls = _by_name(kind, field)
    if cls is not None:
        return cls
    if '\0' in kind:
        raise LawError(f'{field}.kind {kind!r}: a NUL byte is in no file\'s or module\'s name')
    source, sep, name = kind.rpartition(':')
    if not sep or not source or not name.isidentifier():
        raise LawError(f'{field}.kind {kind!r}: not a law kind ({", ".join(names())}) '
                       'nor FILE.py:Class nor module:Class')
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
        except (Exception, SystemExit) as err:   # a module that does not import (or exits): one line
            raise LawError(f'{field}.kind {kind!r}: module {source} does not import: '
                           f'{type(err).__name__}: {err}') from None
        kind_name = kind
    cls = getattr(module, name, None)
    if cls is None:
        raise LawError(f'{field}.kind {kind!r}: {source} has no {name}')
    _check_class(cls, kind, name, field)
    if cls.parts:
        raise LawError(f'{field}.kind {kind!r}: a law made of laws is named by its kind, as kind: blend is')
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
        for part in ('from', 'to'):         # a law made of laws (a blend): its parts' files
            walk(m.get(part))
        if isinstance(kind, str) and ':' in kind:
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


def make_law(mapping, base_dir=None, where: str = 'law') -> Law:
    """The law of a scenario's ``law:`` mapping (a registered kind, ``blend`` of two, or a
    user's file or module), its values checked.  LawError names the problem."""
    if not isinstance(mapping, dict) or 'kind' not in mapping:
        raise LawError(f'{where}: a law is a mapping with a kind ({", ".join(names())} or FILE.py:Class)')
    kind, rest = mapping['kind'], {k: v for k, v in mapping.items() if k != 'kind'}
    if not isinstance(kind, str):
        raise LawError(f'{where}.kind: a string, got {kind!r}')
    cls = law_class(kind, base_dir, where)
    if cls.parts:                   # a law made of laws (a blend): each part a law of any kind
        extra = sorted(set(rest) - set(cls.parts))
        if extra or any(part not in rest for part in cls.parts):
            raise LawError(f'{where}: a {kind} has exactly {" and ".join(f"{p}: <law>" for p in cls.parts)}'
                           + (f' (unknown key {extra[0]!r})' if extra else ''))
        return cls(*(make_law(rest[part], base_dir, f'{where}.{part}') for part in cls.parts))
    return cls.from_mapping(rest, base_dir, where)


def law_mapping(law) -> dict:
    """A law as a scenario's ``law:`` section: ``{kind, parameter: value...}`` (blend:
    ``{kind: blend, from: {...}, to: {...}}``), as metrics.json records it."""
    return law.mapping()


def flat_parameters(law, prefix: str = '') -> dict:
    """The law as flat parameters ``{law: kind, name: value...}`` (blend: ``from.law``,
    ``from.NAME``, ``to.law``...): an agent node's ROS parameters."""
    return law.flat(prefix)


def from_flat_parameters(flat: dict, prefix: str = ''):
    """The inverse of `flat_parameters`."""
    cls = law_class(flat[prefix + 'law'])
    if cls.parts:
        return cls(*(from_flat_parameters(flat, f'{prefix}{part}.') for part in cls.parts))
    return cls(**{k: flat[prefix + k] for k in cls.param_specs()})


def default_law(kinds: dict, prefix: str = ''):
    """The law named by the kinds of flat parameters (``law``, and a blend's ``from.law``,
    ``to.law``) with every other parameter at its default: what a node declares from."""
    cls = law_class(kinds[prefix + 'law'])
    if cls.parts:
        return cls(*(default_law(kinds, f'{prefix}{part}.') for part in cls.parts))
    return cls()


def parameter_specs(law, prefix: str = '') -> dict:
    """name → (default, description, range or choices or None) of every flat parameter of a law,
    for an agent node to declare."""
    return law.flat_specs(prefix)


def _value(v) -> str:
    return repr(v) if isinstance(v, str) else f'{v:g}' if isinstance(v, float) else str(v)


def describe(cls: type[Law]) -> list[str]:
    """Lines that say what a law class is: its kind, the dimensions it supports, its one-line
    doc, then each parameter with its default, range or choices and description."""
    dims = ', '.join(f'{d}D' for d in cls.dims)
    lines = [f'{cls.kind}  [{dims}]  {cls.summary()}']
    for part in cls.parts:
        lines.append(f'    {part:<18} a law of any other kind')
    for name, spec in cls.param_specs().items():
        limits = spec.limits
        text = ('yes/no' if limits is None else ' | '.join(limits) if isinstance(spec.default, str)
                else f'[{_value(limits[0])}, {_value(limits[1])}]' + (' integer' if spec.integer else ''))
        lines.append(f'    {name:<18} {_value(spec.default):<9} {text:<20} {spec.doc}')
    return lines


def catalogue() -> tuple[list[str], list[str]]:
    """(lines describing every registered law, one error line per law that cannot be used:
    a kind two sources claim, an entry point that does not import)."""
    lines, errors = [], []
    for kind in names():
        try:
            lines += describe(law_class(kind, field='swarm laws'))
        except LawError as err:
            errors.append(str(err))
    return lines, errors
