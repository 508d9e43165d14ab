"""
Frozen dataclass instances made at the time loop's rate.

A step makes four frozen dataclass instances (its result twice, its force evaluation, its
wall forces). A frozen dataclass's ``__init__`` sets each field through
``object.__setattr__``: 1.1 us for the 11 fields of a StepResult given by position, 1.4 us
by name (measured). :func:`record` makes the same instance by writing the fields, all given by
name, into its ``__dict__``: 0.7 us, checks included. The instance is the class's own, equal
to the one its ``__init__`` makes, and still frozen for everyone who holds it.
"""
from __future__ import annotations

import dataclasses

_FIELDS: dict[type, frozenset] = {}
"""The field names of each class :func:`record` has made."""


def record(cls, /, **fields):
    """
    Return the instance of the frozen dataclass ``cls`` with ``fields`` (every field, by name).

    ``cls`` must have no ``__post_init__`` (it would not run) and no ``__slots__`` (no
    ``__dict__``); a missing or unknown field is a TypeError, as for ``cls(**fields)``.
    """
    names = _FIELDS.get(cls)
    if names is None:
        names = _FIELDS[cls] = _field_names(cls)
    if fields.keys() != names:
        raise TypeError(f'{cls.__name__}: missing {sorted(names - fields.keys())}, '
                        f'unknown {sorted(fields.keys() - names)}')
    made = object.__new__(cls)
    made.__dict__.update(fields)
    return made


def _field_names(cls) -> frozenset:
    if not dataclasses.is_dataclass(cls) or not cls.__dataclass_params__.frozen:
        raise TypeError(f'{cls.__name__} is not a frozen dataclass')
    if hasattr(cls, '__post_init__') or '__slots__' in vars(cls):
        raise TypeError(f'{cls.__name__} has a __post_init__ or __slots__')
    return frozenset(field.name for field in dataclasses.fields(cls))
