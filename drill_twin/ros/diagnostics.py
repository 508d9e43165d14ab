"""
The twin node's health: what a health period saw, and its report for /diagnostics.

:class:`HealthPeriod` follows the ticks (the engine's health counters, its events, the filter's
analyses, when the twin's clock last moved) and, once a period (the node's wall-clock health
timer), makes the :class:`~drill_twin.twin.health.HealthReport` of the period: the figures
(real-time factor, lag, tick times, command and measurement counts, the log) and the warnings
of a lagging, frozen or missing clock, a missing log, silent sensors and a filter whose
innovations are too large. The events that can come tens of times a second are kept off the
console and counted there once a period.
"""
from __future__ import annotations

import time

from drill_twin import interface as itf
from drill_twin.ros.clock import TwinClock
from drill_twin.ros.commands import CommandIntake
from drill_twin.ros.run_log import RunLog
from drill_twin.twin.health import HealthMonitor, HealthReport

FROZEN_AFTER_S = 1.0
"""Wall time without a step after which health warns that the twin's clock stands still (s)."""
WALL_CONTACT_EVENTS = ('impact', 'contact_end')
"""Events kept off the console (each one still on /diagnostics and in the log's /rosout); the
impacts are counted there once a health period."""
QUIET_EVENTS = WALL_CONTACT_EVENTS + ('measurement_rejected',)
"""Events that can come tens of times a second (contacts, a rig sending bad samples): on
/diagnostics and in the log's /rosout, counted on the console once a health period."""
NIS_WARN_PER_MEASUREMENT = 4.0
"""Mean normalised innovation squared per measured value over a health period above which
health warns (expected 1 when the filter's statistics are right; 4 is far outside the spread
of a period's few analyses)."""
_INTEGER_FIGURES = ('members', 'resets', 'rejected_commands', 'mean_model_resets',
                    'mean_model_failed_steps', 'mean_model_implausible_steps',
                    'ensemble_resets', 'retries', 'ensemble_members_touching_wall',
                    'ensemble_members_lifted_off')
_TICK_TIMES = (('tick_wall_time_s', 'tick_time_ms'), ('tick_wall_time_max_s', 'tick_time_max_ms'),
               ('ensemble_tick_wall_time_s', 'ensemble_tick_time_ms'))


class HealthPeriod:
    """
    The twin's health between two reports (see the module docstring).

    :param engine: the twin's engine.
    :param clock: the node's clock; ``sim_time``: it follows an external /clock.
    :param intake: the node's command intake (dropped and superseded commands).
    :param run_log: the node's log; ``log_enabled``: a log was asked for.
    :param sensor_topics: the rig's measurement topics the node subscribes to.
    """

    def __init__(self, engine, clock: TwinClock, intake: CommandIntake, run_log: RunLog, *,
                 sim_time: bool, sensor_topics: list[str]):
        self.engine, self.clock, self.intake, self.run_log = engine, clock, intake, run_log
        self.sim_time = sim_time
        self.sensor_topics = sensor_topics
        self.monitor = HealthMonitor()
        self.latest: dict = {}
        """The engine's health counters after the latest tick."""
        self._mark = (time.perf_counter(), 0.0)      # (wall, simulated) of the last report
        self._advanced_at = time.monotonic()        # the last tick that took steps
        self._impacts_unreported = 0
        self._refused_unreported = 0
        self._innovations: list[tuple[float, int]] = []  # (NIS, measured values) of the period
        self._measurements_at_report = 0

    # -- following the ticks ---------------------------------------------------------------
    def first_tick(self) -> None:
        """Count the real-time factor from now (the first tick)."""
        self._mark = (time.perf_counter(), self.engine.time_s)

    def stepped(self, snapshot) -> None:
        """Take a tick's snapshot: the engine's counters and events; the clock moved."""
        self._advanced_at = time.monotonic()
        self.latest = snapshot.health
        self.monitor.observe_events(snapshot.events)

    def events(self, snapshot):
        """
        Yield (event, console) for the tick's events to report, and keep its analyses.

        ``console``: whether the event goes to the console too (the quiet ones are counted for
        the next report instead); rejected commands were reported when they came.
        """
        for event in snapshot.events:
            if event.kind in QUIET_EVENTS:
                # A whirling string hits the wall tens of times a second: every event goes to
                # /diagnostics and the log's /rosout, the console gets a count a health period.
                self._impacts_unreported += event.kind == 'impact'
                self._refused_unreported += event.kind == 'measurement_rejected'
                yield event, False
            elif event.kind != 'command_rejected':              # already reported
                yield event, True
        for record in snapshot.analyses:
            self._innovations.append((record.nis, record.measurements))

    # -- reporting ---------------------------------------------------------------------------
    def console_lines(self) -> list[str]:
        """Return the counts of quiet events since the last report, as console warnings."""
        impacts, self._impacts_unreported = self._impacts_unreported, 0
        refused, self._refused_unreported = self._refused_unreported, 0
        lines = []
        if impacts:
            lines.append(f'{impacts} borehole impact{"s" if impacts > 1 else ""} since the '
                         f'last health report (each one on {itf.DIAGNOSTICS} and in the log)')
        if refused:
            lines.append(f'{refused} measurement sample{"s" if refused > 1 else ""} refused '
                         f'since the last health report (each one, with why, on '
                         f'{itf.DIAGNOSTICS} and in the log)')
        return lines

    def report(self, log_enabled: bool) -> HealthReport:
        """Return the report of the period since the last one (and start the next period)."""
        values = self._values(log_enabled)
        counters = dict(self.latest, commands_dropped=self.intake.dropped)
        return self.monitor.report(counters, values)

    def _values(self, log_enabled: bool) -> dict:
        """Return the figures of a health report; note lag and a missing log in the monitor."""
        wall, simulated = time.perf_counter(), self.engine.time_s
        previous_wall, previous_simulated = self._mark
        self._mark = (wall, simulated)
        factor = (simulated - previous_simulated) / max(wall - previous_wall, 1e-9)
        h = self.latest
        lag_s = self.clock.steps_behind() * self.engine.dt
        self._note_clock(factor, lag_s)
        if log_enabled and not self.run_log.taking and self.clock.started:
            self.monitor.note('warn', 'log', 'no log is being written (it could not be opened '
                              'or a write failed; the twin runs on without it)')
        values = {'real_time_factor': f'{factor:.3f}', 'sim_time_s': f'{simulated:.3f}',
                  'behind_wall_clock_ms': f'{1e3 * max(lag_s, 0.0):.0f}',
                  'tick_period_ms': f'{1e3 * self.clock.tick_s:.2f}',
                  'commands_received': self.engine.commands_received,
                  'commands_dropped': self.intake.dropped,
                  'commands_superseded': self.intake.superseded,
                  'log': self.run_log.state()}
        for key, unit in _TICK_TIMES:
            values[unit] = f'{1e3 * h.get(key, 0.0):.2f}'
        for key in ('iterations_per_step', 'ensemble_iterations_per_step'):
            values[key] = f'{h.get(key, 0.0):.2f}'
        for key in _INTEGER_FIGURES:
            values[key] = h.get(key, 0)
        if self.sensor_topics:
            values.update(self._assimilation_values(h))
        return values

    def _assimilation_values(self, h: dict) -> dict:
        """Return the filter's figures of the period; note missing samples, large NIS."""
        innovations, self._innovations = self._innovations, []
        received = self.engine.measurements_received
        new, self._measurements_at_report = (received - self._measurements_at_report,
                                             received)
        values = {'assimilation_analyses': len(innovations),
                  'measurements_received': received,
                  'measurements_used': h.get('measurements_used', 0),
                  'measurements_refused': h.get('measurements_refused', 0)}
        if innovations:
            nis = sum(n for n, _ in innovations) / max(sum(m for _, m in innovations), 1)
            values['nis_per_measurement'] = f'{nis:.3f}'
            if nis > NIS_WARN_PER_MEASUREMENT:
                self.monitor.note('warn', 'innovations', f'the rig\'s measurements disagree '
                                  f'with the ensemble: normalised innovation squared {nis:.3g} '
                                  f'per measured value (expected 1; the noise levels or the '
                                  f'model are off)')
        else:
            values['nis_per_measurement'] = 'none'
        if self.clock.ticks and not new:
            self.monitor.note('warn', 'measurements', 'no measurement sample arrived on '
                              + ', '.join(self.sensor_topics)
                              + ' in the period: the ensemble runs in open loop')
        return values

    def _note_clock(self, factor: float, lag_s: float) -> None:
        """
        Note lag behind the clock the twin follows, and a frozen or missing clock.

        Also a /clock that went back (use_sim_time).
        """
        if self.sim_time and not self.clock.started:
            self.monitor.note('warn', 'clock', 'waiting for the first /clock message '
                              '(use_sim_time)')
        elif self.sim_time and lag_s < 0:
            self.monitor.note('warn', 'clock', f'/clock went back {-lag_s:.3f} s behind the '
                              f'twin; it waits for /clock to reach it again')
        late = lag_s > 0.1 or (factor < 0.95 and not self.sim_time)
        if not self.clock.fast and self.clock.ticks and late:
            what, clock = (('/clock', '/clock') if self.sim_time
                           else ('real time', 'the wall clock'))
            self.monitor.note('warn', 'lag', f'falling behind {what} ({1e3 * lag_s:.0f} ms '
                              f'behind {clock}, real-time factor {factor:.3f})')
        still = time.monotonic() - self._advanced_at
        if self.clock.ticks and still > FROZEN_AFTER_S:
            self.monitor.note('warn', 'frozen', f'the twin\'s clock has not advanced for '
                              f'{still:.1f} s')
