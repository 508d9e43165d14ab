"""YAML reading with YAML 1.2 numbers (PyYAML alone reads ``1e8`` as a string)."""
from __future__ import annotations

import re

import yaml


class SafeLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that also resolves ``1e8``, ``2.5E-3`` and ``.5`` as floats."""


_FLOAT_1_2 = re.compile(r'''^(?:[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?(?:[eE][-+]?[0-9]+)?
    |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$''', re.X)

SafeLoader.add_implicit_resolver('tag:yaml.org,2002:float', _FLOAT_1_2,
                                 list('-+0123456789.'))
# Integers must stay integers: put the int resolver in front of the wider float pattern.
for _first, _resolvers in list(SafeLoader.yaml_implicit_resolvers.items()):
    _int = [r for r in _resolvers if r[0] == 'tag:yaml.org,2002:int']
    _rest = [r for r in _resolvers if r[0] != 'tag:yaml.org,2002:int']
    SafeLoader.yaml_implicit_resolvers[_first] = _int + _rest


def safe_load(text: str):
    """Parse YAML text with :class:`SafeLoader`."""
    return yaml.load(text, Loader=SafeLoader)  # noqa: S506 - a SafeLoader subclass
