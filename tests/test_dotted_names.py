"""Every dotted name of the project's packages in src/ and docs/ (``swarm_core.laws.swarm_control``,
``swarm_tools.run.launch.finish``...) names something that is there (no ROS graph): its module
imports and the rest is an attribute of it, so a module or name that moves cannot leave its old
name behind in a docstring or a doc.  A name with a file's suffix (``swarm.launch.py``) is a file,
and an entry-point group a setup.py declares (``swarm_core.engines``) is no module."""
import ast
import dataclasses
import importlib
import re

from tests.helpers import PACKAGES, ROOT

DOTTED = re.compile(r'(?<![\w./-])((?:%s)(?:\.[A-Za-z_]\w*)+)(?![\w/-])' % '|'.join(PACKAGES))
FILE_SUFFIXES = {'py', 'md', 'yaml', 'yml', 'json', 'jsonl', 'xml', 'cfg', 'toml', 'txt', 'mcap', 'npz', 'png'}


def entry_point_groups() -> set:
    """The entry-point groups (``entry_points={GROUP: [...]}``) of every package's setup.py."""
    groups = set()
    for setup in ROOT.glob('src/*/setup.py'):
        for node in ast.walk(ast.parse(setup.read_text())):
            if isinstance(node, ast.keyword) and node.arg == 'entry_points' and isinstance(node.value, ast.Dict):
                groups.update(k.value for k in node.value.keys if isinstance(k, ast.Constant))
    return groups


def texts():
    files = sorted(p for p in (ROOT / 'src').rglob('*.py') if '__pycache__' not in p.parts)
    return files + sorted((ROOT / 'docs').rglob('*.md'))


def names_in(path):
    """(line, dotted name) of every dotted name of a project package in the file ``path``."""
    for i, line in enumerate(path.read_text().splitlines(), 1):
        for m in DOTTED.finditer(line):
            if m.group(1).rsplit('.', 1)[1] not in FILE_SUFFIXES:
                yield i, m.group(1)


def has(obj, name) -> bool:
    """``obj.name`` is there: an attribute, or a field a class declares without a default."""
    if hasattr(obj, name):
        return True
    fields = getattr(obj, '__dataclass_fields__', None) if dataclasses.is_dataclass(obj) else None
    return bool(fields and name in fields) or name in getattr(obj, 'model_fields', {}) \
        or name in getattr(obj, '__annotations__', {})


def resolves(name: str) -> bool:
    """The longest importable module of ``name``, then every further part an attribute."""
    parts = name.split('.')
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module('.'.join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            if not has(obj, attr):
                return False
            obj = getattr(obj, attr, None)
        return True
    return False


def test_a_moved_name_does_not_resolve():
    assert resolves('swarm_core.scenario.loader.Scenario.content_hash')
    assert resolves('swarm_tools.run.launch.RunPlan.scn')         # a dataclass field, no default
    assert not resolves('swarm_core.comms.belief_controls')         # the module before the re-layout
    assert not resolves('swarm_core.scenario.loader.no_such_name')


def test_every_dotted_project_name_resolves():
    groups = entry_point_groups()
    assert 'swarm_core.engines' in groups
    seen, stale = {}, []
    for path in texts():
        for line, name in names_in(path):
            if name in groups:
                continue
            if name not in seen:
                seen[name] = resolves(name)
            if not seen[name]:
                stale.append(f'{path.relative_to(ROOT)}:{line} {name}')
    assert stale == []
