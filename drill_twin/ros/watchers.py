"""
Who watches a running twin besides ROS: a rerun live view and a console status line.

Both optional (``drill-twin twin --view`` and a terminal); :class:`Watchers` hands each tick's
snapshot, the twin's log lines and the commands to those there are, and finishes them at the
end. The live view's module is imported only when one is asked for: rerun takes about a
second to import.
"""
from __future__ import annotations

import sys

from drill_twin import interface as itf
from drill_twin.viz.console import StatusPrinter

LIVE_VIEW_KEYS = {itf.CMD_TOP_DRIVE_SPEED: 'top_drive_speed_rad_per_s',
                  itf.CMD_HOOK_LOAD: 'hook_load_n'}
"""Command topic -> the LiveView.command keyword that shows it."""


class Watchers:
    """
    The live view and the console status of a run, each one or None.

    :param live_view: a :class:`~drill_twin.viz.live_view.LiveView` streaming to rerun.
    :param status: a :class:`~drill_twin.viz.console.StatusPrinter` for a terminal.
    """

    def __init__(self, live_view=None, status=None):
        self.live_view = live_view
        self.status = status

    def update(self, snapshot) -> None:
        """Show a tick's snapshot."""
        if self.live_view:
            self.live_view.update(snapshot)
        if self.status:
            self.status.update(snapshot)

    def line(self, time_s: float, text: str, level: str) -> None:
        """Show one of the twin's log lines (twin time ``time_s``)."""
        if self.live_view:
            self.live_view.log_line(time_s, text, level)

    def command(self, time_s: float, topic: str, value) -> None:
        """Show a command taken at twin time ``time_s`` (the speed and hook load)."""
        if self.live_view and topic in LIVE_VIEW_KEYS:
            self.live_view.command(time_s, **{LIVE_VIEW_KEYS[topic]: value})

    def finish(self, log_path: str | None, interrupted: bool) -> None:
        """Stop streaming (the viewer keeps running for the user); print the exit summary."""
        if self.live_view:
            self.live_view.close()
        if self.status:
            self.status.finish(log_path=log_path,
                               reason='interrupted' if interrupted else 'stopped')


def live_view(engine, stations_m, web: bool):
    """Return a LiveView of ``engine``'s twin streaming to a rerun viewer it spawns."""
    from drill_twin.viz.live_view import LiveView       # rerun: only for a live view

    settings = engine.ensemble.assimilation
    view = LiveView(stations_m, engine.config, assimilation=engine.assimilating,
                    law=settings is not None and settings.filter.parameters == 'law',
                    bias_channels=() if settings is None
                    else settings.estimated_bias_channels())
    view.spawn_viewer(web=web)
    return view


def console_status():
    """Return a StatusPrinter on stderr."""
    return StatusPrinter(sys.stderr)
