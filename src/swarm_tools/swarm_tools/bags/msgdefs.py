"""ROS 2 message definitions as rosbag2 puts them in an MCAP schema (no rclpy import here):
a type's ``.msg`` text, then each dependency (sorted, depth first, each once) after a line of
80 ``=`` and ``MSG: pkg/Type`` (`message_definition`), found in the installed share
directories; and whether a type starts with a ``std_msgs/Header`` stamp (the live view reads it)."""
from __future__ import annotations

import os
import re
import struct
import sys
from pathlib import Path

from swarm_ros.protocol import cdr_byte_order

SEPARATOR = '=' * 80

PRIMITIVES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
              'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'}
# as rosbag2_storage_mcap's MSG_FIELD_TYPE_REGEX: a field type at the start of a line
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_TYPE_NAME = re.compile(r'^([a-zA-Z][a-zA-Z0-9_]*)/((?:msg|srv)/)?([a-zA-Z][a-zA-Z0-9_]*)$')


class DefinitionNotFound(LookupError):
    pass


# --------------------------------------------------------------------------- definitions
def share_dirs() -> list[Path]:
    """Install prefixes' ``share`` directories: $AMENT_PREFIX_PATH, then this interpreter's
    prefix (the venv, where the ROS wheels put their ``share/<pkg>/msg``)."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes += [sys.prefix, str(Path(sys.executable).resolve().parent.parent)]
    out = []
    for p in prefixes:
        d = Path(p) / 'share'
        if d.is_dir() and d not in out:
            out.append(d)
    return out


def _msg_file(type_name: str) -> tuple[str, Path]:
    m = _TYPE_NAME.match(type_name)
    if not m:
        raise DefinitionNotFound(f'{type_name}: not a pkg/Type or pkg/msg/Type name')
    pkg, ns, name = m.group(1), (m.group(2) or 'msg/').rstrip('/'), m.group(3)
    for share in share_dirs():
        f = share / pkg / ns / f'{name}.msg'
        if f.is_file():
            return pkg, f
    raise DefinitionNotFound(f'{type_name}: no {pkg}/{ns}/{name}.msg under {", ".join(map(str, share_dirs()))}')


def msg_dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types of a .msg text, as rosbag2 finds them (sorted, unique)."""
    deps = set()
    for m in _FIELD_TYPE.finditer(text):
        t = m.group(1)
        if t in PRIMITIVES:
            continue
        deps.add(t if '/' in t else f'{package}/{t}')
    return sorted(deps)


def message_definition(type_name: str) -> str:
    """The full ``ros2msg`` definition of ``type_name`` as rosbag2_storage_mcap builds it."""
    seen: set[str] = set()

    def text_of(name: str, depth: int) -> str:
        if depth <= 0:
            raise DefinitionNotFound(f'{type_name}: definition nests too deep')
        pkg, path = _msg_file(name)
        text = path.read_text()
        out = text
        for dep in msg_dependencies(text, pkg):
            if dep not in seen:
                seen.add(dep)
                out += f'\n{SEPARATOR}\nMSG: {dep}\n' + text_of(dep, depth - 1)
        return out

    return text_of(type_name, 50)


def split_definition(full: str) -> dict[str, str]:
    """Inverse of `message_definition`: {'' (the top type) or 'pkg/Type': text}."""
    parts = full.split(f'\n{SEPARATOR}\n')
    out = {'': parts[0]}
    for p in parts[1:]:
        head, _, body = p.partition('\n')
        out[head.removeprefix('MSG: ').strip()] = body
    return out


def _first_field_type(text: str, package: str) -> str | None:
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        ftype, _, rest = line.partition(' ')
        if '=' in rest:          # a constant, not a field
            continue
        if ftype in PRIMITIVES or ftype.startswith('string<'):
            return ftype
        base = ftype.split('[', 1)[0]
        if base == 'Header':
            return 'std_msgs/Header'
        return base if '/' in base else f'{package}/{base}'
    return None


def has_leading_stamp(full_definition: str, type_name: str) -> bool:
    """True if the message opens with a time stamp: a ``std_msgs/Header`` or a
    ``builtin_interfaces/Time`` first field (then the CDR bytes 4..12 are sec, nanosec)."""
    m = _TYPE_NAME.match(type_name)
    if not m:
        return False
    top = split_definition(full_definition)['']
    first = _first_field_type(top, m.group(1))
    return first in ('std_msgs/Header', 'std_msgs/msg/Header', 'builtin_interfaces/Time',
                     'builtin_interfaces/msg/Time')


def leading_stamp_ns(data: bytes) -> int | None:
    """sec·1e9 + nanosec of the stamp that opens a CDR message (see `has_leading_stamp`)."""
    if len(data) < 12:
        return None
    sec, nsec = struct.unpack_from(cdr_byte_order(data) + 'iI', data, 4)
    return sec * 1_000_000_000 + nsec
