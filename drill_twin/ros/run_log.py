"""
The twin node's MCAP log as the node keeps it: opened by policy, written, stopped on failure.

:class:`RunLog` holds the run's :class:`~drill_twin.recording.twin_log.TwinLog` (a rosbag2
bag in ``log_dir``), or none: logging is off, the log could not be opened, or a write failed
(disk full, a file-size limit). ``on_log_error`` says what then: ``continue`` (the twin runs
on without a log) or ``exit`` (:class:`LogDirectoryError` when opening; the node stops with
status 1 after a failed write). Commands taken before an external clock started are kept
and written at the epoch once it starts.
"""
from __future__ import annotations

from drill_twin import interface as itf
from drill_twin.ros import messages
from drill_twin.ros.build import log_metadata, new_log_path, open_log
from drill_twin.ros.clock import TwinClock
from drill_twin.ros.parameters import TwinParameters


class LogDirectoryError(RuntimeError):
    """The log cannot be written and ``on_log_error`` says exit."""


class RunLog:
    """The node's log (see the module docstring); every write is a no-op without one."""

    def __init__(self):
        self.log = None
        """The open :class:`~drill_twin.recording.twin_log.TwinLog`, or None."""
        self.error: str | None = None
        """Why the log stopped or could not be opened (None while it runs, or without one)."""
        self.stopped = False
        """Whether a write failed and the log was given up."""
        self._early: list[tuple[str, object]] = []  # commands before an external clock

    @property
    def taking(self) -> bool:
        """Whether the log takes messages (open, not failed)."""
        return self.log is not None and self.log.open

    def open(self, params: TwinParameters, engine, clock: TwinClock, stations_m, *, tf: bool,
             sensor_topics: tuple[dict, dict]) -> str | None:
        """
        Open the run's log (a new rosbag2 bag in ``log_dir``), stamped with ``clock``'s epoch.

        ``tf``: with /tf and /tf_static; ``sensor_topics``: the rig's JointState and Float64
        topics the twin assimilates ({topic: sensor}, {topic: channel}).
        Return None, or the error line to report if it cannot be created and
        ``on_log_error`` is continue; raise LogDirectoryError if it is exit.
        """
        metadata = log_metadata(params, engine, epoch_ns=clock.epoch_ns,
                                substeps=clock.substeps, fast=clock.fast)
        path = new_log_path(params.log_dir)
        try:
            self.log = open_log(path, params, stations_m, metadata, tf=tf,
                                measurement_topics=sensor_topics[0],
                                scalar_measurement_topics=sensor_topics[1])
        except OSError as error:
            text = f'cannot write the log {path}: {error.strerror or error}'
            if params.on_log_error == 'exit':
                raise LogDirectoryError(text) from None
            self.error = text
            return text + '; running without a log (on_log_error: continue)'
        return None

    def write(self, topic: str, message, time_ns: int) -> None:
        """Log ``message`` on ``topic`` at ``time_ns`` (without a log: nothing)."""
        if self.log:
            self.log.write(topic, message, time_ns)

    def write_serialized(self, topic: str, data: bytes, time_ns: int) -> None:
        """Log a serialised message (the caller checked :attr:`taking`)."""
        self.log.write_serialized(topic, data, time_ns)

    def line(self, level: str, text: str, node_name: str, time_ns: int) -> None:
        """Log one of the twin's own log lines on /rosout."""
        if self.log:
            self.write(itf.ROSOUT, messages.log(level, text, node_name, time_ns), time_ns)

    def command(self, topic: str, message, started: bool, time_ns: int) -> None:
        """
        Log a command taken at twin time ``time_ns`` (it takes effect then).

        Before an external clock has ``started``, keep it for :meth:`clock_started`.
        """
        if not started:
            self._early.append((topic, message))
        else:
            self.write(topic, message, time_ns)

    def clock_started(self, epoch_ns: int) -> None:
        """Log the commands taken before the clock started at ``epoch_ns`` (they act from it)."""
        for topic, message in self._early:
            self.write(topic, message, epoch_ns)
        self._early.clear()

    def failure(self, on_log_error: str) -> str | None:
        """
        Notice a failed write: give the log up; return why, with what the twin does now.

        None while the log works (or there is none). ``on_log_error`` exit: the twin stops.
        """
        if self.log is None or self.log.open:
            return None
        error, self.log = self.log.error, None
        self.stopped = True
        self.error = (error or 'the log was closed') + (
            '; stopping (on_log_error: exit)' if on_log_error == 'exit'
            else '; the twin runs on without a log (on_log_error: continue)')
        return self.error

    def state(self) -> str:
        """Return the log for a health report: its path, 'stopped' or 'none'."""
        return (str(self.log.path) if self.taking else
                'stopped' if self.stopped else 'none')

    def flush(self) -> None:
        """Write what the log holds (a health period's chunk)."""
        if self.log:
            self.log.flush()

    def close(self) -> str | None:
        """Complete the log; return why completing it failed (disk full), or None."""
        if self.log:
            self.log.close()
            return self.log.error
        return None
