"""
The checks of the configuration's dataclasses and the error they raise.

Each dataclass checks its own values in ``__post_init__`` with these helpers; an error names
the field relative to the object that raised it, and the loader (``loader.py``) prefixes the
key path of that object. The error survives pickling (a map point's check fails in a worker
process and is reported by the parent).
"""
from __future__ import annotations

import math


class ConfigValueError(ValueError):
    """
    A value that cannot describe a real drill string.

    ``key`` is the dotted path relative to the object that raised it; the loader
    prefixes the path of that object.
    """

    def __init__(self, key: str, message: str):
        super().__init__(f'{key}: {message}')
        self.key = key
        self.message = message

    def __reduce__(self):
        return type(self), (self.key, self.message)


def positive(obj, *names: str) -> None:
    """Refuse any of the attributes ``names`` of ``obj`` that is not finite and > 0."""
    for name in names:
        value = getattr(obj, name)
        if not (math.isfinite(value) and value > 0.0):
            raise ConfigValueError(name, f'must be a finite positive number, got {value!r}')


def non_negative(obj, *names: str) -> None:
    """Refuse any of the attributes ``names`` of ``obj`` that is not finite and >= 0."""
    for name in names:
        value = getattr(obj, name)
        if not (math.isfinite(value) and value >= 0.0):
            raise ConfigValueError(name, f'must be a finite number >= 0, got {value!r}')


def at_most(obj, name: str, high: float, reason: str) -> None:
    """Refuse |value| above the plausible ``high`` (``reason`` says why it is implausible)."""
    value = getattr(obj, name)
    if abs(value) > high:
        bound = f'at most {high:g}' if value > 0 else f'at least {-high:g}'
        raise ConfigValueError(name, f'must be {bound} ({reason}), got {value:g}')


def at_least(obj, name: str, low: float, reason: str) -> None:
    """Refuse a value below the plausible ``low`` (``reason`` says why it is implausible)."""
    value = getattr(obj, name)
    if value < low:
        raise ConfigValueError(name, f'must be at least {low:g} ({reason}), got {value:g}')
