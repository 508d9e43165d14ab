"""
SIGINT and SIGTERM honoured from the first instant of ``drill-twin twin``.

A job started in the background by a non-interactive shell starts with SIGINT ignored, and
Python then installs no KeyboardInterrupt handler; until ``rclpy.init`` installs its own, half
a second later, a SIGINT was lost. :func:`install` (called by ``drill_twin.cli.main`` before
its heavy imports) catches SIGINT and SIGTERM at once. A signal that arrives before
:func:`arm` is remembered and raised as KeyboardInterrupt by ``arm``, in the subcommand,
where it is handled (the twin stops with status 0); after ``arm`` a signal raises
KeyboardInterrupt at once, as Python's own SIGINT handler does, and rclpy's handlers (which
shut the ROS context down) call this one too.
"""
from __future__ import annotations

import os
import signal

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)

_state = {'installed': False, 'armed': False, 'pending': None}


def wanted(argv: list[str]) -> bool:
    """
    Whether this process runs the twin.

    ``drill-twin twin ...``, ``python -m drill_twin.cli.main twin ...`` or the
    ``lib/drill_twin/twin`` launcher.
    """
    return (len(argv) > 1 and argv[1] == 'twin') or (
        bool(argv) and os.path.basename(argv[0]) == 'twin')


def install() -> None:
    """Catch SIGINT and SIGTERM from now on (whatever their disposition was)."""
    for number in STOP_SIGNALS:
        signal.signal(number, _on_signal)
    _state['installed'] = True


def arm() -> None:
    """From now on a stop signal raises KeyboardInterrupt; one that came before raises now."""
    if not _state['installed']:
        install()
    _state['armed'] = True
    if _state['pending'] is not None:
        raise KeyboardInterrupt


def _on_signal(number, frame) -> None:
    _state['pending'] = number
    if _state['armed']:
        raise KeyboardInterrupt
