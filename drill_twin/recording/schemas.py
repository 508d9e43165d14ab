r"""
MCAP schemas of ROS 2 messages, written exactly as rosbag2_storage_mcap writes them.

rosbag2 (``rosbag2_cpp::LocalMessageDefinitionSource``, Jazzy) stores for a topic type a schema
named 'pkg/msg/Type' with encoding 'ros2msg' whose text is:

- the root ``.msg`` file verbatim;
- then, depth first, each dependency once: '\n', a line of 80 '=', a line 'MSG: pkg/Type'
  (the name as written in the referring ``.msg``; a bare 'Type' becomes 'pkg/Type' of the
  referring package) and that ``.msg`` verbatim.

The dependencies of one ``.msg`` are visited in sorted order (rosbag2 keeps them in a
``std::set``).  Field types are found with rosbag2's own regular expression, so comments,
constants, arrays and bounded types are treated as rosbag2 treats them.

Definitions are searched in ``<prefix>/share/<pkg>/msg/`` for each prefix of
AMENT_PREFIX_PATH, then ``sys.prefix`` (the PyPI ROS wheels install there and do not set
AMENT_PREFIX_PATH).
"""
from __future__ import annotations

import functools
import json
import os
from pathlib import Path
import re
import sys

from drill_twin.recording.message_types import canonical_type_name, split_type_name

SCHEMA_ENCODING = 'ros2msg'
MESSAGE_ENCODING = 'cdr'
DELIMITER = '=' * 80 + '\n'
MAX_RECURSION_DEPTH = 50
"""rosbag2's ROSBAG2_CPP_LOCAL_MESSAGE_DEFINITION_SOURCE_MAX_RECURSION_DEPTH."""

# rosbag2_cpp local_message_definition_source.cpp, MSG_FIELD_TYPE_REGEX
_MSG_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+', re.ASCII)
PRIMITIVE_TYPES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string'))


class DefinitionNotFoundError(LookupError):
    """No ``.msg`` (or ``.json``) file for a message type under any searched prefix."""


def search_prefixes() -> list[Path]:
    """Install prefixes searched for ``share/<pkg>``: AMENT_PREFIX_PATH entries, sys.prefix."""
    entries = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes = [Path(p) for p in entries] + [Path(sys.prefix)]
    unique: list[Path] = []
    for prefix in prefixes:
        if prefix not in unique:
            unique.append(prefix)
    return unique


def interface_file(type_name: str, suffix: str) -> Path:
    """
    Find ``share/<pkg>/msg/<Type><suffix>`` ('.msg' or '.json') in the search prefixes.

    The first prefix of :func:`search_prefixes` that has the file wins.
    """
    package, name = split_type_name(type_name)
    for prefix in search_prefixes():
        candidate = prefix / 'share' / package / 'msg' / (name + suffix)
        if candidate.is_file():
            return candidate
    raise DefinitionNotFoundError(
        f'no {name}{suffix} for {type_name} under share/{package}/msg/ of '
        + ', '.join(str(p) for p in search_prefixes()))


def msg_dependencies(text: str, package: str) -> list[str]:
    """
    Non-primitive field types of a ``.msg`` text, sorted, as rosbag2 finds them.

    A bare 'Type' is a type of the same package and becomes 'package/Type'.
    """
    dependencies = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in PRIMITIVE_TYPES:
            continue
        dependencies.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(dependencies)


@functools.lru_cache(maxsize=None)
def _msg_text(type_name: str) -> str:
    return interface_file(type_name, '.msg').read_bytes().decode('utf-8')


@functools.lru_cache(maxsize=None)
def ros2msg_schema(type_name: str) -> str:
    """Full 'ros2msg' schema text of a message type ('pkg/msg/Type'), as rosbag2 writes it."""
    seen: set[str] = set()

    def append_recursive(name: str, depth: int) -> str:
        if depth <= 0:
            raise RecursionError(f'reached max recursion depth resolving {type_name}')
        text = _msg_text(name)
        package, _ = split_type_name(name)
        result = text
        for dependency in msg_dependencies(text, package):
            if dependency not in seen:
                seen.add(dependency)
                result += '\n' + DELIMITER + f'MSG: {dependency}\n'
                result += append_recursive(dependency, depth - 1)
        return result

    return append_recursive(type_name, MAX_RECURSION_DEPTH)


@functools.lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """Return the type hash 'RIHS01_<64 hex>' of a message type, from its ``.json``."""
    canonical = canonical_type_name(type_name)
    path = interface_file(type_name, '.json')
    description = json.loads(path.read_text(encoding='utf-8'))
    for entry in description.get('type_hashes', []):
        if entry.get('type_name') == canonical:
            return entry['hash_string']
    raise DefinitionNotFoundError(f'{path} has no type hash for {canonical}')
