"""
The twin streamed to a rerun viewer while it runs, with the layout of the recorded view.

:class:`LiveView` takes the engine's :class:`~drill_twin.twin.engine.TwinSnapshot` after
each tick, keeps samples at most ``sample_rate_hz`` per second of twin time (contact-force
profiles at most ``profile_rate_hz``; events all), and sends what it holds at most
``send_rate_hz`` times per second of wall time in column batches, through the same
:mod:`~drill_twin.viz.rerun_series` functions as ``drill-twin view``.  The viewer it
spawns listens on 127.0.0.1 only.
"""
from __future__ import annotations

import subprocess
import time
from typing import Callable, Sequence

import numpy as np
import rerun as rr

from drill_twin.config import load_config
from drill_twin.viz import rerun_series as series
from drill_twin.viz.rerun_blueprint import twin_blueprint
from drill_twin.viz.rerun_entities import APPLICATION_ID, HEALTH_ENTITIES, StringGeometry
from drill_twin.viz.rerun_styles import log_styles
from drill_twin.viz.rerun_view import viewer_command

_BIT_FIELDS = ('depth_m', 'rop_m_per_s', 'weight_on_bit_n', 'angle_rad', 'speed_rad_per_s',
               'torque_on_bit_nm')


def _bit_row(state) -> tuple[float, ...]:
    return tuple(float(getattr(state, name)) for name in _BIT_FIELDS)


def _bounds(rows: list, width: int) -> tuple:
    """Split rows (t, mean, lower, upper; ``width`` values each) into (t, mean, lower, upper)."""
    a = np.asarray(rows, dtype=float)
    return (a[:, 0], a[:, 1:1 + width], a[:, 1 + width:1 + 2 * width],
            a[:, 1 + 2 * width:1 + 3 * width])


class LiveView:
    """
    Stream twin snapshots to rerun (see the module docstring).

    :param stations_m: depths (m) of the measurement stations, in the snapshot's order.
    :param config: the model configuration (borehole and pipe sizes); default: the built-in
        one.
    :param recording: a rerun ``RecordingStream`` to log to (default: a new one; connect it
        with :meth:`spawn_viewer` or :meth:`connect`, or give one that saves to a file).
    :param active_tab: the tab shown first (index or name, see ``rerun_entities.TABS``).
    :param clock: wall clock (s) for the send rate (tests pass a fake one).
    :param assimilation: the twin assimilates: the ensemble tab shows the estimated germ.
    :param law: its filter estimates the law's coefficients too: the ensemble tab shows them.
    :param bias_channels: the channels whose sensor bias its filter estimates (shown likewise).
    """

    def __init__(self, stations_m: Sequence[float], config=None, *, recording=None,
                 sample_rate_hz: float = 50.0, profile_rate_hz: float = 10.0,
                 send_rate_hz: float = 4.0, active_tab: int | str = 0,
                 clock: Callable[[], float] = time.monotonic, assimilation: bool = False,
                 law: bool = False, bias_channels=()):
        if config is None:
            config = load_config(None)
        self.geometry = StringGeometry.from_config(config, stations_m)
        self.blueprint = twin_blueprint(self.geometry, active_tab=active_tab, follow=True,
                                        assimilation=assimilation, law=law,
                                        bias_channels=bias_channels)
        self._bias_channels = tuple(bias_channels)
        self.recording = recording if recording is not None else rr.RecordingStream(
            APPLICATION_ID)
        self.sample_period_s = 1.0 / sample_rate_hz
        self.profile_period_s = 1.0 / profile_rate_hz
        self.send_period_s = 1.0 / send_rate_hz
        self._clock = clock
        self._next_sample = -np.inf
        self._next_profile = -np.inf
        self._last_send = None
        self._last_ensemble_time = None
        self._previous_orbit: list[tuple[float, float] | None] = [None] * len(
            self.geometry.stations_m)
        self._rate_mark = None                   # (wall s, twin s) of the last health row
        self.viewer: subprocess.Popen | None = None
        self._styled = False
        self._clear()

    # -- viewer ------------------------------------------------------------------------------
    def spawn_viewer(self, *, web: bool = False, port: int = 9876,
                     web_port: int = 9090) -> subprocess.Popen:
        """
        Start a rerun viewer (native, or the web viewer) bound to 127.0.0.1 and stream to it.

        Returns the viewer process (left running when the twin stops).
        """
        self.viewer = subprocess.Popen(viewer_command(None, web=web, port=port,
                                                      web_port=web_port))
        self.connect(f'rerun+http://127.0.0.1:{port}/proxy')
        return self.viewer

    def connect(self, url: str) -> None:
        """Stream to a running viewer or proxy at ``url`` (rerun+http://HOST:PORT/proxy)."""
        self.recording.connect_grpc(url, default_blueprint=self.blueprint)
        self._style()

    def _style(self) -> None:
        """
        Log the static styles and drawings once the recording has its sink.

        Static data logged before ``save``/``connect`` did not all reach the viewer in
        rerun 0.41.
        """
        log_styles(self.recording, self.geometry)
        self._styled = True

    # -- data --------------------------------------------------------------------------------
    def _clear(self) -> None:
        self._rows: dict[str, list] = {'bit': [], 'top': [], 'kpi': [], 'ensemble': [],
                                       'germ': [], 'law': [], 'bias': [], 'station': [],
                                       'profile': [], 'health': []}
        self._events: list[tuple[float, str, str]] = []
        self._commands: dict[str, list] = {'speed': [], 'hook': []}

    def update(self, snapshot, time_s: float | None = None) -> None:
        """
        Take the snapshot of a tick at twin time ``time_s``.

        ``time_s``: s since the start, default ``snapshot.time_s``. Buffered samples are sent
        when a send is due.
        """
        t = float(snapshot.time_s if time_s is None else time_s)
        for event in snapshot.events:
            self._events.append((float(event.time_s), f'{event.kind.replace("_", " ")}: '
                                 f'{event.message}', event.level))
        for record in snapshot.analyses:            # every analysis (a few per second)
            self._rows['germ'].append((record.time_s, *record.germ_mean, *record.germ_lower,
                                       *record.germ_upper))
            if all(np.isfinite(record.law_mean)):
                self._rows['law'].append((record.time_s, *record.law_mean, *record.law_lower,
                                          *record.law_upper))
            if record.bias_channels:          # the same channels in every analysis of a run
                self._bias_channels = record.bias_channels
                self._rows['bias'].append((record.time_s, *record.bias_mean,
                                           *record.bias_lower, *record.bias_upper))
        if t >= self._next_sample:
            self._next_sample = t + self.sample_period_s - 1e-9
            self._sample(snapshot, t)
        now = self._clock()
        if self._last_send is None:
            self._last_send = now
        elif now - self._last_send >= self.send_period_s:
            self._health(snapshot, t, now)
            self.flush()
            self._last_send = now

    def command(self, time_s: float, *, top_drive_speed_rad_per_s: float | None = None,
                hook_load_n: float | None = None) -> None:
        """Draw a command as applied at twin time ``time_s`` (a dot)."""
        if top_drive_speed_rad_per_s is not None:
            self._commands['speed'].append((float(time_s), float(top_drive_speed_rad_per_s)))
        if hook_load_n is not None:
            self._commands['hook'].append((float(time_s), float(hook_load_n)))

    def _sample(self, snapshot, t: float) -> None:
        o = snapshot.observation
        self._rows['bit'].append((t, *_bit_row(snapshot.bit)))
        self._rows['top'].append((t, float(o.top_speed_rad_per_s), float(o.top_torque_nm[0]),
                                  float(o.hook_load_n)))
        self._rows['kpi'].append((t, snapshot.stick_slip_severity, snapshot.mse_pa,
                                  snapshot.rop_m_per_h))
        ensemble_t = snapshot.ensemble_time_s
        if snapshot.ensemble_mean is not None and ensemble_t != self._last_ensemble_time:
            self._last_ensemble_time = ensemble_t
            self._rows['ensemble'].append((float(ensemble_t), *_bit_row(snapshot.ensemble_mean),
                                           *_bit_row(snapshot.ensemble_lower),
                                           *_bit_row(snapshot.ensemble_upper)))
        stations = len(self.geometry.stations_m)
        if stations:
            lateral = np.asarray(o.station_displacement_m[0, :stations, 1:3], dtype=float)
            self._rows['station'].append((t, *lateral.ravel()))
        if t >= self._next_profile:
            self._next_profile = t + self.profile_period_s - 1e-9
            self._rows['profile'].append((t, np.asarray(o.contact_force_n[0], dtype=float)))

    def _health(self, snapshot, t: float, now: float) -> None:
        h = snapshot.health
        factor = np.nan
        if self._rate_mark is not None and now > self._rate_mark[0]:
            factor = (t - self._rate_mark[1]) / (now - self._rate_mark[0])
        self._rate_mark = (now, t)
        self._rows['health'].append((t, factor, 1e3 * h.get('tick_wall_time_s', np.nan),
                                     1e3 * h.get('tick_wall_time_max_s', np.nan),
                                     h.get('iterations_per_step', np.nan),
                                     h.get('ensemble_iterations_per_step', np.nan),
                                     h.get('resets', np.nan)))

    def flush(self) -> None:
        """Send everything buffered now."""
        if not self._styled:
            self._style()
        rec, geometry, rows = self.recording, self.geometry, self._rows
        if rows['bit']:
            bit = np.asarray(rows['bit'])
            series.send_bit(rec, bit[:, 0], bit[:, 1], bit[:, 2], bit[:, 5], bit[:, 3],
                            bit[:, 6])
            series.send_ensemble_model(rec, bit[:, 0], bit[:, 2], bit[:, 3], bit[:, 5])
        if rows['top']:
            top = np.asarray(rows['top'])
            series.send_top(rec, top[:, 0], top[:, 1], top[:, 2], top[:, 3])
        if rows['kpi']:
            kpi = np.asarray(rows['kpi'], dtype=float)
            series.send_kpis(rec, kpi[:, 0], kpi[:, 1], kpi[:, 2], kpi[:, 3])
        if rows['ensemble']:
            series.send_ensemble(rec, *_bounds(rows['ensemble'], len(_BIT_FIELDS)))
        if rows['germ']:
            series.send_germ(rec, *_bounds(rows['germ'], 3))
        if rows['law']:
            series.send_law(rec, *_bounds(rows['law'], 5))
        if rows['bias']:
            t, mean, lower, upper = _bounds(rows['bias'], len(self._bias_channels))
            series.send_bias(rec, t, self._bias_channels, mean, lower, upper)
        if rows['station']:
            station = np.asarray(rows['station'])
            for k in range(len(geometry.stations_m)):
                v, w = station[:, 1 + 2 * k], station[:, 2 + 2 * k]
                series.send_station(rec, geometry, k, station[:, 0], v, w,
                                    previous=self._previous_orbit[k])
                self._previous_orbit[k] = (float(v[-1]), float(w[-1]))
        if rows['profile']:
            t = np.array([row[0] for row in rows['profile']])
            forces = np.stack([row[1] for row in rows['profile']])
            radial = np.zeros((t.size, len(geometry.stations_m)))
            if rows['station']:
                station = np.asarray(rows['station'])
                for k in range(radial.shape[1]):
                    radial[:, k] = np.interp(t, station[:, 0], np.hypot(
                        station[:, 1 + 2 * k], station[:, 2 + 2 * k]))
            series.send_profiles(rec, geometry, t, forces, radial)
        if rows['health']:
            health = np.asarray(rows['health'], dtype=float)
            values = {key: health[:, 1 + i] for i, key in enumerate(HEALTH_ENTITIES)
                      if np.isfinite(health[:, 1 + i]).any()}
            series.send_health(rec, health[:, 0], values)
        if self._events:
            series.send_text(rec, 'diagnostics/events', [e[0] for e in self._events],
                             [e[1] for e in self._events], [e[2] for e in self._events])
        speed, hook = self._commands['speed'], self._commands['hook']
        if speed or hook:
            series.send_commands(rec, [c[0] for c in speed], [c[1] for c in speed],
                                 [c[0] for c in hook], [c[1] for c in hook])
        self._clear()

    def log_line(self, time_s: float, text: str, level: str = 'info') -> None:
        """Show a line of the twin's own log (what goes to /rosout)."""
        series.send_text(self.recording, 'rosout', [float(time_s)], [text], [level])

    def close(self) -> None:
        """Send what is left and flush the recording (the viewer keeps running)."""
        self.flush()
        self.recording.flush()
