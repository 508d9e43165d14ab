"""
Load a drill-string configuration: YAML -> merged mapping -> frozen dataclasses.

The built-in defaults are ``config/ritto2009.yaml``. A user file overrides any subset of
its keys (mappings merge key by key; lists such as ``sections`` are replaced whole), and
``--set path=value`` overrides single values, where a list item can be addressed by its
``name`` or its index (``sections.drill_pipe.elements=40``, ``output.stations_m.0=650``).

Every problem raises :class:`ConfigError`, whose message is one line naming the file,
the key and what is wrong.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import types
import typing
from pathlib import Path
from typing import Any, Iterable, Literal, get_args, get_origin

import yaml

from drill_twin.config import yaml_io

from drill_twin.config.paths import default_config_path
from drill_twin.config.schema import ConfigValueError, DrillStringConfig


class ConfigError(Exception):
    """
    A configuration that cannot be used; ``str()`` is a one-line message.

    It survives pickling (raised in a worker process, reported by the parent).
    """

    def __init__(self, source: str, key: str, message: str):
        where = f'{source}: {key}' if key else source
        super().__init__(f'{where}: {message}')
        self.source = source
        self.key = key
        self.message = message

    def __reduce__(self):
        return type(self), (self.source, self.key, self.message)


def load_config(path: str | Path | None = None,
                overrides: Iterable[str] = ()) -> DrillStringConfig:
    """Build the configuration from the defaults, an optional file and ``key=value`` items."""
    defaults_path = default_config_path()
    raw = _read_yaml(defaults_path)
    source = str(defaults_path)
    if path is not None:
        source = str(path)
        user = _read_yaml(Path(path))
        raw = merge(raw, user)
    overrides = list(overrides)
    for item in overrides:
        raw = apply_override(raw, item)
    try:
        return build_config(raw, source=source)
    except ConfigError as error:
        if _set_by_override(error.key, error.message, raw, overrides):
            raise ConfigError('--set', error.key, error.message) from None
        raise


def source_of(key: str, config: DrillStringConfig, overrides: Iterable[str] = ()) -> str:
    """
    Whom a problem with ``key`` of ``config`` is blamed on.

    ``--set`` when one of the ``overrides`` set that key, a key inside it or one containing it,
    else the file the configuration came from (``config.source``).
    """
    if _set_by_override(key, '', config_to_dict(config), overrides):
        return '--set'
    return config.source


def _set_by_override(key: str, message: str, raw: dict, overrides: Iterable[str]) -> bool:
    for item in overrides:
        path = labelled_path(raw, item.split('=', 1)[0].strip())
        if (_same_or_inside(key, path) or _same_or_inside(path, key)
                or (message and path in message)):
            return True
    return False


def _same_or_inside(key: str, prefix: str) -> bool:
    return bool(key) and (key == prefix or key.startswith(prefix + '.'))


def labelled_path(raw: dict, path: str) -> str:
    """
    Return a dotted path as errors name it.

    List items by their ``name`` (else their index), so that ``sections.1.length_m`` reads
    ``sections.drill_collar.length_m``.
    """
    node: Any = raw
    labels = []
    for key in path.split('.'):
        if isinstance(node, list):
            index = _list_index(node, key)
            if index is None:
                labels.append(key)
                node = None
                continue
            labels.append(_item_label(node[index], index))
            node = node[index]
        else:
            labels.append(key)
            node = node.get(key) if isinstance(node, dict) else None
    return '.'.join(labels)


def build_config(raw: dict, source: str = '<mapping>') -> DrillStringConfig:
    """Turn a complete mapping into a validated :class:`DrillStringConfig`."""
    try:
        return _build(DrillStringConfig, raw, '', extra={'source': source})
    except _BuildError as error:
        raise ConfigError(source, error.key, error.message) from None


def config_to_dict(config: DrillStringConfig) -> dict:
    """Return the plain mapping of a configuration (for log metadata and round trips)."""
    result = dataclasses.asdict(config)
    result.pop('source', None)
    return _plain(result)


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


MAX_CONFIG_BYTES = 1 << 20
"""A configuration file is read only up to 1 MiB: the shipped one, every key of the schema
with comments, is 6 kB; anything larger (a device, a log named by mistake) is not one."""


def _read_yaml(path: Path) -> dict:
    try:
        with open(path, 'rb') as handle:
            content = handle.read(MAX_CONFIG_BYTES + 1)
    except OSError as error:
        raise ConfigError(str(path), '', f'cannot read: {error.strerror or error}') from None
    if len(content) > MAX_CONFIG_BYTES:
        raise ConfigError(str(path), '', f'larger than {MAX_CONFIG_BYTES // 1024} KiB: not a '
                          'configuration file')
    try:
        text = content.decode('utf-8')
    except UnicodeDecodeError as error:
        byte = content[error.start]
        raise ConfigError(str(path), '', f'not a UTF-8 text file (byte 0x{byte:02x} at offset '
                          f'{error.start})') from None
    try:
        data = yaml_io.safe_load(text)
    except yaml.YAMLError as error:
        mark = getattr(error, 'problem_mark', None)
        where = f'line {mark.line + 1}' if mark is not None else ''
        problem = (getattr(error, 'problem', None) or getattr(error, 'reason', None)
                   or str(error).splitlines()[0])
        raise ConfigError(str(path), where, f'YAML syntax error: {problem}') from None
    except RecursionError:
        raise ConfigError(str(path), '', 'YAML nested too deeply') from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(str(path), '', 'the file must hold a mapping of keys')
    return data


def merge(base: dict, update: dict) -> dict:
    """Merge ``update`` into a copy of ``base``: mappings key by key, anything else replaced."""
    result = copy.deepcopy(base)
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(result.get(key), dict):
            result[key] = merge(result[key], value)
        else:
            result[key] = copy.deepcopy(value)
    return result


def apply_override(raw: dict, item: str) -> dict:
    """Apply one ``dotted.path=value`` override (value parsed as YAML)."""
    if '=' not in item:
        raise ConfigError('--set', item, 'expected key=value')
    path, text = item.split('=', 1)
    path = path.strip()
    try:
        value = yaml_io.safe_load(text) if text.strip() else None
    except yaml.YAMLError:
        raise ConfigError('--set', path, f'cannot parse value {text!r}') from None
    keys = path.split('.')
    result = copy.deepcopy(raw)
    node: Any = result
    for depth, key in enumerate(keys):
        last = depth == len(keys) - 1
        where = '.'.join(keys[:depth + 1])
        if isinstance(node, dict):
            if key not in node:
                raise ConfigError('--set', where, 'unknown key')
            if last:
                node[key] = value
            else:
                node = node[key]
        elif isinstance(node, list):
            index = _list_index(node, key)
            if index is None:
                raise ConfigError('--set', where, 'no list item with that name or index')
            if last:
                node[index] = value
            else:
                node = node[index]
        else:
            raise ConfigError('--set', where, 'is a value, not a mapping')
    return result


def _list_index(items: list, key: str) -> int | None:
    if key.isdigit():
        index = int(key)
        return index if index < len(items) else None
    for index, item in enumerate(items):
        if isinstance(item, dict) and item.get('name') == key:
            return index
    return None


class _BuildError(Exception):
    def __init__(self, key: str, message: str):
        super().__init__(f'{key}: {message}')
        self.key = key
        self.message = message


def _join(prefix: str, key: str) -> str:
    return f'{prefix}.{key}' if prefix else key


def _build(cls, raw: Any, prefix: str, extra: dict | None = None):
    if not isinstance(raw, dict):
        raise _BuildError(prefix, f'expected a mapping, got {_describe(raw)}')
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    extra = extra or {}
    for key in raw:
        if key not in fields or key in extra:
            raise _BuildError(_join(prefix, str(key)), 'unknown key')
    values = dict(extra)
    for name, spec in fields.items():
        if name in extra:
            continue
        key = _join(prefix, name)
        if name not in raw:
            has_default = (spec.default is not dataclasses.MISSING
                           or spec.default_factory is not dataclasses.MISSING)
            if has_default:
                continue
            raise _BuildError(key, 'missing key')
        values[name] = _convert(hints[name], raw[name], key)
    try:
        return cls(**values)
    except ConfigValueError as error:
        raise _BuildError(_join(prefix, error.key), error.message) from None


def _convert(hint, value, key: str):
    origin = get_origin(hint)
    if dataclasses.is_dataclass(hint):
        return _build(hint, value, key)
    if origin in (typing.Union, types.UnionType):
        options = get_args(hint)
        if value is None and type(None) in options:
            return None
        inner = [o for o in options if o is not type(None)]
        return _convert(inner[0], value, key)
    if origin is Literal:
        allowed = get_args(hint)
        if value not in allowed:
            names = ', '.join(str(a) for a in allowed)
            raise _BuildError(key, f'must be one of {names}; got {value!r}')
        return value
    if origin is tuple:
        item_type = get_args(hint)[0]
        if not isinstance(value, list):
            raise _BuildError(key, f'expected a list, got {_describe(value)}')
        return tuple(_convert(item_type, item, f'{key}.{_item_label(item, index)}')
                     for index, item in enumerate(value))
    if hint is bool:
        if not isinstance(value, bool):
            raise _BuildError(key, f'expected true or false, got {_describe(value)}')
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise _BuildError(key, f'expected an integer, got {_describe(value)}')
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _BuildError(key, f'expected a number, got {_describe(value)}')
        if not math.isfinite(value):
            raise _BuildError(key, f'must be finite, got {value}')
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise _BuildError(key, f'expected a string, got {_describe(value)}')
        return value
    raise TypeError(f'unsupported configuration type {hint!r} at {key}')


def _item_label(item, index: int) -> str:
    """Name a list item by its ``name`` when it has one, else by its index."""
    if isinstance(item, dict) and isinstance(item.get('name'), str) and item['name']:
        return item['name']
    return str(index)


def _describe(value) -> str:
    if value is None:
        return 'nothing (null)'
    if isinstance(value, dict):
        return 'a mapping'
    if isinstance(value, list):
        return 'a list'
    return f'{value!r}'
