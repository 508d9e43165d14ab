"""
The running twin on a terminal: a status line once a second and a summary at exit.

Pure formatting of :class:`~drill_twin.twin.engine.TwinSnapshot` figures (no ROS, no I/O
except :class:`StatusPrinter`, which writes to the stream it is given)::

    t 125.3 s  RTF 1.00  depth 1601.42 m  bit 48 rpm (surface 50)  ROP 8.1 m/h  SSI 0.84 \
    events 2 impacts, 1 lift-off          (one line on the terminal)

Units: drilling units on screen (rpm, m/h), SI in the snapshot.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
import math
import time
from typing import Callable, Iterable, TextIO

RPM_PER_RAD_PER_S = 60.0 / (2.0 * math.pi)

# How event kinds are named on the console (singular, plural); others use their kind.
_EVENT_WORDS = {
    'impact': ('impact', 'impacts'),
    'contact_end': ('contact end', 'contact ends'),
    'lift_off': ('lift-off', 'lift-offs'),
    'landing': ('landing', 'landings'),
    'diverged': ('reset after divergence', 'resets after divergence'),
    'command_rejected': ('rejected command', 'rejected commands'),
    'ensemble_failed': ('ensemble failure', 'ensemble failures'),
}
_QUIET = {'contact_end', 'landing'}            # the end of something already counted


def _number(value: float, digits: int) -> str:
    return f'{value:.{digits}f}' if math.isfinite(value) else '-'


def describe_events(counts: Counter, *, include_quiet: bool = False) -> str:
    """'2 impacts, 1 lift-off' from counts by event kind ('none' if there are none)."""
    parts = []
    for kind, count in sorted(counts.items(), key=lambda item: (-item[1], item[0])):
        if count <= 0 or (kind in _QUIET and not include_quiet):
            continue
        singular, plural = _EVENT_WORDS.get(kind, (kind.replace('_', ' '),) * 2)
        parts.append(f'{count} {singular if count == 1 else plural}')
    return ', '.join(parts) if parts else 'none'


@dataclass
class RunTally:
    """What the run did so far: first and last time (s) and depth (m), events by kind."""

    start_time_s: float | None = None
    start_depth_m: float | None = None
    time_s: float = 0.0
    depth_m: float = math.nan
    events: Counter = field(default_factory=Counter)

    def add(self, snapshot) -> None:
        """Count a snapshot's events and note where the bit is."""
        if self.start_time_s is None:
            self.start_time_s, self.start_depth_m = snapshot.time_s, snapshot.bit.depth_m
        self.time_s, self.depth_m = snapshot.time_s, snapshot.bit.depth_m
        self.events.update(event.kind for event in snapshot.events)


def status_line(snapshot, real_time_factor: float, events: Counter) -> str:
    """
    One line.

    Twin time, real-time factor, bit depth, bit and surface speed, ROP over the KPI window,
    stick-slip severity, events so far.
    """
    bit = snapshot.bit
    surface = snapshot.observation.top_speed_rad_per_s * RPM_PER_RAD_PER_S
    return (f't {snapshot.time_s:.1f} s  RTF {_number(real_time_factor, 2)}  '
            f'depth {bit.depth_m:.2f} m  '
            f'bit {_number(bit.speed_rad_per_s * RPM_PER_RAD_PER_S, 0)} rpm '
            f'(surface {_number(surface, 0)})  '
            f'ROP {_number(snapshot.rop_m_per_h, 1)} m/h  '
            f'SSI {_number(snapshot.stick_slip_severity, 2)}  '
            f'events {describe_events(events)}')


def exit_summary(tally: RunTally, wall_s: float, *, log_path: str | None = None,
                 reason: str = 'stopped') -> str:
    """
    Lines printed when the twin ends.

    Time, mean real-time factor, drilled depth, events, the log.
    """
    twin_s = tally.time_s - (tally.start_time_s or 0.0)
    factor = twin_s / wall_s if wall_s > 0 else math.nan
    lines = [f'drill_twin {reason} after {tally.time_s:.1f} s of twin time in {wall_s:.1f} s '
             f'(real-time factor {_number(factor, 2)})']
    if tally.start_depth_m is not None:
        drilled = tally.depth_m - tally.start_depth_m
        rop = 3600.0 * drilled / twin_s if twin_s > 0 else math.nan
        lines.append(f'  bit depth {tally.start_depth_m:.2f} -> {tally.depth_m:.2f} m '
                     f'({drilled:.2f} m drilled, mean ROP {_number(rop, 1)} m/h)')
    lines.append(f'  events: {describe_events(tally.events, include_quiet=True)}')
    lines.append(f'  log: {log_path}' if log_path else '  log: none')
    return '\n'.join(lines)


class StatusPrinter:
    """
    Writes :func:`status_line` to ``stream`` at most once per ``interval_s`` of wall time.

    On a terminal it rewrites one line in place, elsewhere it appends lines.

    Call :meth:`update` after every tick and :meth:`finish` at exit (it ends the status
    line and writes :func:`exit_summary`).
    """

    def __init__(self, stream: TextIO, *, interval_s: float = 1.0,
                 clock: Callable[[], float] = time.monotonic):
        self.stream = stream
        self.interval_s = float(interval_s)
        self.clock = clock
        self.tally = RunTally()
        self.terminal = bool(getattr(stream, 'isatty', lambda: False)())
        self._start = clock()
        self._next = self._start + self.interval_s
        self._mark = (self._start, None)          # (wall s, twin s) of the last line
        self._width = 0

    def update(self, snapshot) -> str | None:
        """Count the snapshot; write and return the status line if one is due."""
        self.tally.add(snapshot)
        now = self.clock()
        if self._mark[1] is None:
            self._mark = (now, snapshot.time_s)
        if now < self._next:
            return None
        self._next = now + self.interval_s
        wall, twin = self._mark
        factor = (snapshot.time_s - twin) / (now - wall) if now > wall else math.nan
        self._mark = (now, snapshot.time_s)
        line = status_line(snapshot, factor, self.tally.events)
        if self.terminal:
            self.stream.write('\r' + line.ljust(self._width))
            self._width = len(line)
        else:
            self.stream.write(line + '\n')
        self.stream.flush()
        return line

    def finish(self, *, log_path: str | None = None, reason: str = 'stopped') -> str:
        """End the status line and write the exit summary (returned too)."""
        summary = exit_summary(self.tally, self.clock() - self._start, log_path=log_path,
                               reason=reason)
        if self.terminal and self._width:
            self.stream.write('\n')
        self.stream.write(summary + '\n')
        self.stream.flush()
        return summary


def count_events(snapshots: Iterable) -> Counter:
    """Events by kind over snapshots (for tests and offline runs)."""
    counts: Counter = Counter()
    for snapshot in snapshots:
        counts.update(event.kind for event in snapshot.events)
    return counts
