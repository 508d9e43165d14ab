"""
Frozen records made at the time loop's rate.

A step makes four frozen dataclasses (its result twice, its force evaluation, its wall forces).
A frozen dataclass's ``__init__`` sets each field through ``object.__setattr__`` (1.4 us for
the 9 fields of a StepResult, measured); :func:`maker` returns a constructor that writes the
same fields into the instance's ``__dict__`` (0.5 us): the same object, equal to the one the
class makes, still frozen for everyone who holds it.
"""
from __future__ import annotations

import dataclasses


def maker(cls):
    """
    Return ``make(field_1, ..., field_n)``: an instance of the frozen dataclass ``cls``.

    Every field is given, in the order of ``dataclasses.fields(cls)`` (positionally or by
    name); ``cls`` must have no ``__post_init__`` and no ``__slots__``.
    """
    if not dataclasses.is_dataclass(cls) or not cls.__dataclass_params__.frozen:
        raise TypeError(f'{cls.__name__} is not a frozen dataclass')
    if hasattr(cls, '__post_init__') or '__slots__' in vars(cls):
        raise TypeError(f'{cls.__name__} has a __post_init__ or __slots__')
    names = [field.name for field in dataclasses.fields(cls)]
    # As dataclasses makes __init__: code generated from the field names.
    source = (f"def make({', '.join(names)}):\n    record = new(cls)\n"
              f"    fields = record.__dict__\n"
              + ''.join(f'    fields[{name!r}] = {name}\n' for name in names)
              + '    return record\n')
    scope = {'new': object.__new__, 'cls': cls}
    exec(source, scope)                                    # noqa: S102 (names of a dataclass)
    make = scope['make']
    make.__qualname__ = make.__name__ = f'make_{cls.__name__}'
    make.__doc__ = f'Return a {cls.__name__} of its fields ({", ".join(names)}).'
    return make
