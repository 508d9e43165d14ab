"""The twin's console: status line, event words, the printer's pace and the exit summary."""
from collections import Counter
import io

from drill_twin.viz.console import (describe_events, exit_summary, RunTally, status_line,
                                    StatusPrinter)
from drill_twin.integrator.stepping import TwinEvent
from snapshots import impact, snapshot


def test_status_line_in_drilling_units():
    s = snapshot(0.0)        # bit 5 rad/s = 47.7 rpm, surface 5 rad/s, depth 1600 m
    line = status_line(s, 0.987, Counter({'impact': 2, 'lift_off': 1, 'contact_end': 2}))
    assert line == ('t 0.0 s  RTF 0.99  depth 1600.00 m  bit 48 rpm (surface 48)  '
                    'ROP 7.2 m/h  SSI 0.80  events 2 impacts, 1 lift-off')
    assert '\n' not in line
    assert 'RTF -' in status_line(s, float('nan'), Counter())
    assert status_line(s, 1.0, Counter()).endswith('events none')


def test_describe_events():
    assert describe_events(Counter()) == 'none'
    assert describe_events(Counter({'impact': 1})) == '1 impact'
    assert describe_events(Counter({'diverged': 2, 'command_rejected': 1, 'landing': 4})) == (
        '2 resets after divergence, 1 rejected command')
    assert describe_events(Counter({'landing': 4}), include_quiet=True) == '4 landings'
    assert describe_events(Counter({'something_new': 3})) == '3 something new'


def test_printer_once_per_interval_and_summary():
    class Clock:
        now = 100.0

        def __call__(self):
            return self.now

    clock, stream = Clock(), io.StringIO()
    printer = StatusPrinter(stream, interval_s=1.0, clock=clock)
    lines = []
    for i in range(1, 501):                     # 5 s of twin time at 2 x real time
        clock.now += 0.005
        line = printer.update(snapshot(i * 0.01, events=[impact(i * 0.01)] if i in (50, 300)
                                       else []))
        if line:
            lines.append(line)
    assert len(lines) == 2                      # at 1.0 and 2.0 s of wall time (2.5 s ran)
    assert 'RTF 2.00' in lines[0] and 'events 1 impact' in lines[0]
    assert 'events 2 impacts' in lines[1]
    assert stream.getvalue().splitlines()[:2] == lines       # not a terminal: one per line
    summary = printer.finish(log_path='runs/x.mcap')
    assert summary.splitlines() == [
        'drill_twin stopped after 5.0 s of twin time in 2.5 s (real-time factor 2.00)',
        '  bit depth 1600.00 -> 1600.01 m (0.01 m drilled, mean ROP 7.2 m/h)',
        '  events: 2 impacts',
        '  log: runs/x.mcap']
    assert stream.getvalue().endswith(summary + '\n')


def test_printer_rewrites_one_line_on_a_terminal():
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    class Clock:
        now = 0.0

        def __call__(self):
            return self.now

    clock, stream = Clock(), Terminal()
    printer = StatusPrinter(stream, clock=clock)
    for i in range(1, 301):
        clock.now += 0.01
        printer.update(snapshot(i * 0.01))
    printer.finish(reason='interrupted')
    text = stream.getvalue()
    assert text.startswith('\rt ') and text.count('\r') == 2
    assert '\ndrill_twin interrupted after 3.0 s' in text


def test_tally_counts_every_event():
    tally = RunTally()
    for t in (0.5, 1.0):
        tally.add(snapshot(t, events=[TwinEvent('lift_off', 'warn', t, 'lifted')]))
    assert tally.events == Counter({'lift_off': 2})
    assert tally.start_time_s == 0.5 and tally.time_s == 1.0
    assert 'log: none' in exit_summary(tally, 0.0)
