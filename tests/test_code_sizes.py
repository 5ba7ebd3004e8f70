"""The size limits of the source (no ROS): no .py file under src/ over `MAX_FILE_LINES` lines,
no function (or method, nested ones included) over `MAX_FUNCTION_LINES`, its decorators counted.
A file or function that grows past them is split by concept, not by line count."""
import ast

from tests.helpers import ROOT

MAX_FILE_LINES = 600
MAX_FUNCTION_LINES = 80


def sources():
    return sorted(p for p in (ROOT / 'src').rglob('*.py') if '__pycache__' not in p.parts)


def function_lengths(path):
    """(lines, 'FILE:LINE name') of every function of ``path``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            first = min([node.lineno] + [d.lineno for d in node.decorator_list])
            yield node.end_lineno - first + 1, f'{path.relative_to(ROOT)}:{node.lineno} {node.name}'


def test_no_source_file_is_over_the_limit():
    assert sources()
    sizes = [(len(p.read_text().splitlines()), str(p.relative_to(ROOT))) for p in sources()]
    assert [s for s in sizes if s[0] > MAX_FILE_LINES] == []


def test_no_function_is_over_the_limit():
    lengths = [f for p in sources() for f in function_lengths(p)]
    assert lengths
    assert sorted(f for f in lengths if f[0] > MAX_FUNCTION_LINES) == []
