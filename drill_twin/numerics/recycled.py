"""
Arrays that a time step hands to its caller, reused once nobody holds them any more.

A step returns new arrays (the state, the forces, the flags) that its caller may keep as
long as it likes. Allocating them anew costs the mean model about 9 us a step (19 arrays),
a tenth of its step, and a new chunk of memory each time. :class:`RecycledArrays` keeps the
sets it made and hands out again the one used longest ago when no array of it is
referenced from anywhere but the pool: CPython counts every reference (a variable, a
container, a view, whose base is the array, a buffer export such as a memoryview), so an
array that anything can still reach is never written again. When that set is still held,
a new set is made; the pool grows to what its caller's pattern needs (two or three sets
for a simulator, measured) and past ``kept`` forgets its oldest set (left to whoever holds it).

A set may be a namedtuple of arrays: it is handed out as a namedtuple of the same class (its
arrays in the order it was made), so that its caller reads the arrays by name.

Reference counts mean what this relies on only in CPython; elsewhere every set is new.
"""
from __future__ import annotations

import sys
from collections import deque
from typing import Callable

import numpy as np

_COUNTS_REFERENCES = sys.implementation.name == 'cpython'


class RecycledArrays:
    """
    Sets of arrays from ``make``, each reused only when nothing but this pool holds it.

    :param make: returns a new set, a tuple (or a namedtuple) of arrays that nothing else
        references.
    :param kept: the most sets kept for reuse.
    """

    def __init__(self, make: Callable[[], tuple[np.ndarray, ...]], kept: int = 6):
        if kept < 1:
            raise ValueError(f'kept: at least 1 set, got {kept}')
        self._make = make
        self._kept = kept
        self._sets: deque[list[np.ndarray]] = deque()
        self._free_count: int | None = None
        self._handed = tuple                 # the sets' class: tuple, or a namedtuple's _make
        self.made = 0
        """Sets made so far (a measure of how often none was free)."""

    def take(self) -> tuple[np.ndarray, ...]:
        """Return a set no one else holds: the longest unused one if free, else a new one."""
        sets = self._sets
        if sets and sum(map(sys.getrefcount, sets[0])) == self._free_count:
            arrays = sets.popleft()
            sets.append(arrays)
            return self._handed(arrays)     # a new tuple: holding it holds the arrays
        made = self._make()
        self._handed = made._make if hasattr(made, '_fields') else tuple
        arrays = list(made)
        del made
        self.made += 1
        if not _COUNTS_REFERENCES:
            return self._handed(arrays)
        if self._free_count is None:        # the count of a set held by the pool alone
            self._free_count = sum(map(sys.getrefcount, arrays))
        sets.append(arrays)
        if len(sets) > self._kept:
            sets.popleft()
        return self._handed(arrays)
