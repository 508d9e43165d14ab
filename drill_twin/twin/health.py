"""
The twin's health: what went wrong since the last report, ROS-free.

:class:`HealthMonitor` collects what the twin's parts report between two health reports
(failed and implausible mean-model steps, member resets, sub-step retries, rejected, dropped
and superseded commands, a lost ensemble, a log that stopped, lag) and turns them into a
:class:`HealthReport`:

- ERROR: the mean model failed a step, broke a physical bound (the state guard), or was
  restarted; the ensemble was lost;
- WARN: an ensemble member was restarted, a step needed sub-step retries, commands were
  rejected or dropped, measurement samples were refused (assimilation), the log stopped or
  could not be written, the twin lags the wall clock;
- OK ("running") only when nothing went wrong since the last report.

A problem is reported in the period it happened and held (at its level, marked "in the
previous period") in the next report too, so that a listener sampling any one report after
it hears of it. Counters are cumulative since start; the report compares them with the
previous report's. The node converts a report to a ``diagnostic_msgs/DiagnosticStatus``
(:func:`drill_twin.ros.messages.health_report`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

LEVEL_ORDER = ('ok', 'warn', 'error')

COUNTERS = {
    'mean_model_failed_steps': ('error', 'the mean model failed {n} step(s) (skipped after a '
                                         'retry from a safe state)'),
    'mean_model_implausible_steps': ('error', 'the mean model broke a physical bound in {n} '
                                              'step(s){detail}'),
    'mean_model_diverged': ('error', 'the mean model diverged {n} time(s) and was restarted '
                                     'from a safe state'),
    'ensemble_resets': ('warn', '{n} ensemble member reset(s)'),
    'retries': ('warn', '{n} sub-step retry(ies)'),
    'rejected_commands': ('warn', '{n} command(s) rejected{detail}'),
    'commands_dropped': ('warn', '{n} command(s) dropped before they reached the twin '
                                 '(the subscription\'s queue overflowed)'),
    'measurements_refused': ('warn', '{n} measurement sample(s) refused, the ensemble filter '
                                     'went on without them{detail}'),
}
"""Cumulative counters that make a report WARN or ERROR when they grow, and what it says."""


@dataclass(frozen=True)
class HealthReport:
    """
    One health report.

    level: 'ok', 'warn' or 'error'; message: 'running' or every reason, '; '-separated;
    reasons: the reasons one by one; values: figures for the DiagnosticStatus key-values
    (strings).
    """

    level: str
    message: str
    reasons: tuple[str, ...]
    values: dict = field(default_factory=dict)


class HealthMonitor:
    """Collects problems between health reports (see the module docstring)."""

    def __init__(self):
        self._notes: dict[str, tuple[str, str]] = {}
        self._held: dict[str, tuple[str, str]] = {}
        self._reported: dict[str, int] = {}
        self._details: dict[str, str] = {}

    def note(self, level: str, key: str, text: str) -> None:
        """
        Return a problem of this period.

        Per key, the worst level with its text (the latest text among notes of that level).
        """
        previous = self._notes.get(key)
        if previous is not None and _rank(previous[0]) > _rank(level):
            return
        self._notes[key] = (level, text)

    def detail(self, counter: str, text: str) -> None:
        """Return the latest detail of a counter's problem (e.g. which bound was broken)."""
        self._details[counter] = text

    def observe_events(self, events) -> None:
        """
        Twin events of a tick.

        A lost ensemble is a problem of its own; the last reason of an implausible mean-model
        step or a rejected command becomes a detail.
        """
        for event in events:
            if event.kind == 'ensemble_failed':
                self.note(event.level, 'ensemble_failed', event.message)
            elif event.kind == 'implausible' and event.level == 'error':
                self.detail('mean_model_implausible_steps', event.values.get('reason', ''))
            elif event.kind == 'command_rejected':
                self.detail('rejected_commands', event.message)
            elif event.kind == 'measurement_rejected':
                self.detail('measurements_refused', event.values.get('reason', event.message))

    def report(self, counters: dict, values: dict) -> HealthReport:
        """
        Return the report of this period.

        ``counters`` are the cumulative counts (COUNTERS' keys; missing ones count 0),
        ``values`` the figures to show.
        """
        for name, (level, template) in COUNTERS.items():
            count = int(counters.get(name, 0))
            new = count - self._reported.get(name, 0)
            self._reported[name] = count
            if new > 0:
                detail = self._details.pop(name, '')
                self.note(level, name, template.format(
                    n=new, detail=f' (last: {detail})' if detail else ''))
        current, self._notes = self._notes, {}
        held = {key: (level, f'{text} (in the previous period)')
                for key, (level, text) in self._held.items() if key not in current}
        self._held = current
        issues = list(current.values()) + list(held.values())
        level = max((lvl for lvl, _ in issues), key=_rank, default='ok')
        reasons = tuple(text for _, text in issues)
        return HealthReport(level=level, message='; '.join(reasons) if reasons else 'running',
                            reasons=reasons, values=dict(values))


def _rank(level: str) -> int:
    return LEVEL_ORDER.index(level)
