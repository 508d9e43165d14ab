"""
How many model steps a tick of the twin takes: the pace of its clock (ROS-free).

Three paces:

- ``fast``: a tick's steps every tick, as fast as the machine goes (the node publishes /clock);
- ``wall``: the steps whose time the wall clock (the ROS clock) has reached since the first
  tick, at most as many again as a tick's while catching up after a stall, so the twin's
  clock never runs ahead of the wall clock;
- ``external``: the steps whose time an external /clock (``use_sim_time``: a simulator or a bag
  player) has reached since its first message, at most :data:`EXTERNAL_CATCH_UP_TICKS` ticks'
  worth per tick; the twin's clock starts at that first message and never passes the last.

Times are integer nanoseconds; ``step_index`` is the number of model steps taken so far.
"""
from __future__ import annotations

from dataclasses import dataclass

PACES = ('fast', 'wall', 'external')
EXTERNAL_CATCH_UP_TICKS = 10
"""Ticks' worth of steps a tick takes at most behind an external clock (an external clock
that jumps is followed within a few ticks, the executor staying responsive)."""


@dataclass(slots=True)
class Pacer:
    """
    Steps per tick for one pace (see the module docstring).

    :param pace: 'fast', 'wall' or 'external'.
    :param dt_ns: model time step (ns).
    :param substeps: model steps of one tick.
    :param epoch_ns: the twin's clock at step 0 (ns): the wall clock at start, 0 when fast,
        the first external clock message (None until it arrives).
    """

    pace: str
    dt_ns: int
    substeps: int
    epoch_ns: int | None
    origin_ns: int | None = None
    """Clock time of step 0 as the pace counts it (set on the first tick)."""

    def __post_init__(self) -> None:
        if self.pace not in PACES:
            raise ValueError(f'pace must be one of {", ".join(PACES)}, got {self.pace!r}')
        if self.dt_ns <= 0 or self.substeps < 1:
            raise ValueError('dt_ns and substeps must be positive')

    @property
    def started(self) -> bool:
        """False while an external clock has not sent its first message."""
        return self.epoch_ns is not None

    def start(self, epoch_ns: int) -> None:
        """Begin the twin's clock at the first external clock message."""
        if self.epoch_ns is None:
            self.epoch_ns = int(epoch_ns)

    def steps(self, now_ns: int | None, step_index: int) -> int:
        """
        Model steps this tick takes.

        ``now_ns`` is the wall or external clock (unused when fast).
        """
        if self.pace == 'fast':
            return self.substeps
        if self.epoch_ns is None or now_ns is None:
            return 0
        if self.origin_ns is None:
            # Wall: the start-up before the first tick does not count (never before the epoch).
            self.origin_ns = (self.epoch_ns if self.pace == 'external'
                              else max(self.epoch_ns, now_ns - self.substeps * self.dt_ns))
        limit = self.substeps * (EXTERNAL_CATCH_UP_TICKS if self.pace == 'external' else 2)
        return int(min(max(self.behind(now_ns, step_index), 0), limit))

    def behind(self, now_ns: int | None, step_index: int) -> int:
        """
        Return the whole model steps the twin is behind the clock it follows.

        0 when fast or before the first tick; negative if that clock went back.
        """
        if self.pace == 'fast' or self.origin_ns is None or now_ns is None:
            return 0
        return (now_ns - self.origin_ns) // self.dt_ns - step_index
