"""
The twin's rerun layout.

Entities, units, styles and blueprint, shared by the recorded view
(:mod:`~drill_twin.viz.rerun_native`) and the live one
(:mod:`~drill_twin.viz.live_view`).

Everything is logged natively (not through rerun's MCAP importer) on one duration timeline,
``run time``, in seconds of the run, in the units a drilling engineer reads: rpm, kN, kN·m,
m/h, mm.  WOB and TOB are shown positive while drilling (compression, resisting torque);
the ROS topics carry the paper's signs (negative).  The ``send_*`` functions take arrays
of SI values (one row per sample) and are the one place where units are converted and
entities named; both views call them.

Entities (under ``/``): ``bit/*``, ``top/*``, ``cmd/*``, ``kpi/*``, ``ensemble/germ/<g>/{mean,
lower,upper}`` and ``ensemble/law/<a>/{mean,lower,upper}`` (assimilation), ``ensemble/<q>/{band,
mean,model}``, ``lateral/<station>/*`` (orbit, pipe, wall, radial deflection),
``along/*`` (contact force and deflection along the depth), ``diagnostics/*``, ``rosout``.

The lateral views look down the hole: v to the right, w down the screen (x, the string
axis, points into the screen, so (x, v, w) is right-handed).  rerun is imported only by the
functions that use it.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence
import warnings

import numpy as np

from drill_twin import interface as itf

APPLICATION_ID = 'drill_twin'
TIMELINE = 'run time'
"""The duration timeline of every view: seconds since the start of the run."""

TABS = ('bit', 'driller', 'lateral', 'ensemble', 'diagnostics')
"""Tab names for ``--tab`` (and ``active_tab``), in display order."""
TAB_TITLES = {'bit': 'Bit', 'driller': 'Driller', 'lateral': 'Lateral motion',
              'ensemble': 'Ensemble', 'diagnostics': 'Diagnostics'}

RPM_PER_RAD_PER_S = 60.0 / (2.0 * math.pi)
BAND_LINES = 48
"""Lines filling the 95 % band (rerun has no filled area between two series)."""
BAND_LINE_WIDTH = 6.0
TRAIL_S = 10.0
"""Seconds of orbit drawn behind the cursor."""

# Colours (RGB)
BLUE, ORANGE, GREEN, RED, GREY, DARK = ((40, 110, 230), (245, 140, 40), (60, 170, 90),
                                        (225, 60, 60), (140, 140, 140), (70, 70, 70))
PURPLE = (150, 90, 200)
LIGHT = (225, 225, 225)        # on rerun's dark plot background
BAND = (175, 200, 245)


# -- geometry --------------------------------------------------------------------------------

@dataclass(frozen=True)
class StringGeometry:
    """What the lateral views draw: borehole, node depths and the stations' pipe size (m)."""

    borehole_radius_m: float
    node_x_m: np.ndarray
    stations_m: tuple[float, ...]
    station_outer_radius_m: tuple[float, ...]

    @property
    def station_clearance_m(self) -> tuple[float, ...]:
        """Radial gap between pipe and wall at each station (m): the centre's wall contact."""
        return tuple(self.borehole_radius_m - r for r in self.station_outer_radius_m)

    @classmethod
    def from_config(cls, config, stations_m: Sequence[float] | None = None) -> 'StringGeometry':
        """
        From a :class:`~drill_twin.config.schema.DrillStringConfig`.

        Stations default to ``config.output.stations_m``.
        """
        from drill_twin.fem.mesh import build_mesh

        mesh = build_mesh(config)
        stations = tuple(float(x) for x in (config.output.stations_m if stations_m is None
                                            else stations_m))
        outer = []
        for x_m in stations:
            element, _ = mesh.locate(min(max(x_m, 0.0), mesh.total_length_m))
            outer.append(float(mesh.outer_radius_m[element]))
        return cls(config.borehole.diameter_m / 2.0, np.asarray(mesh.node_x_m, dtype=float),
                   stations, tuple(outer))


def station_entity(x_m: float) -> str:
    """Entity of a station's lateral views, e.g. 'lateral/x700m' (topic-safe name)."""
    return f'lateral/{itf.station_name(x_m)}'


def tab_index(tab: int | str) -> int:
    """Index of a tab given by index or (case-insensitive) name; ValueError if unknown."""
    if isinstance(tab, int):
        if not 0 <= tab < len(TABS):
            raise ValueError(f'tab index {tab} is not in 0..{len(TABS) - 1}')
        return tab
    name = str(tab).strip().lower()
    for i, key in enumerate(TABS):
        if name in (key, TAB_TITLES[key].lower()):
            return i
    raise ValueError(f'unknown tab {tab!r}; one of: {", ".join(TABS)}')


# -- static styles ---------------------------------------------------------------------------

_LINES = {
    # entity: (legend name, colour, width)
    'bit/depth': ('bit depth', BLUE, 2.0),
    'bit/rop': ('ROP (instant)', BLUE, 1.5),
    'kpi/rop': ('ROP (window mean)', LIGHT, 2.5),
    'bit/speed': ('bit', BLUE, 1.5),
    'top/speed': ('surface (top drive)', ORANGE, 2.5),
    'bit/wob': ('WOB', BLUE, 1.5),
    'bit/tob': ('TOB', BLUE, 1.5),
    'top/torque': ('surface torque', ORANGE, 1.5),
    'top/hook_load': ('hook load', ORANGE, 2.0),
    'kpi/ssi': ('SSI', PURPLE, 2.0),
    'kpi/mse': ('MSE', GREEN, 2.0),
    'contact/max_force': ('largest wall force', RED, 1.5),
    'diagnostics/real_time_factor': ('real-time factor', BLUE, 2.0),
    'diagnostics/tick_time': ('tick', BLUE, 1.5),
    'diagnostics/tick_time_max': ('slowest tick (last 100)', RED, 1.5),
    'diagnostics/iterations': ('mean model', BLUE, 1.5),
    'diagnostics/ensemble_iterations': ('ensemble', ORANGE, 1.5),
    'diagnostics/resets': ('member resets', RED, 2.0),
}
_POINTS = {
    'cmd/top_drive_speed': ('command', LIGHT, 5.0),
    'cmd/hook_load': ('command', LIGHT, 5.0),
}
ENSEMBLE_QUANTITIES = {
    # key: (title, unit)
    'speed': ('Bit speed', 'rpm'),
    'rop': ('ROP', 'm/h'),
    'wob': ('WOB', 'kN'),
}
GERM_ENTRIES = {'g11': ('G11', BLUE), 'g12': ('G12', ORANGE), 'g22': ('G22', GREEN)}
"""The estimated bit-rock germ's entries (assimilation), in message order, and their colours."""
LAW_ENTRIES = {'a1': ('a1', BLUE), 'a2': ('a2', ORANGE), 'a3': ('a3', GREEN),
               'a4': ('a4', RED), 'a5': ('a5', PURPLE)}
"""The estimated factors of the law's a1 ... a5 (assimilation, parameters 'law'), in message
order, and their colours."""
CHANNEL_UNITS = {'top_speed': 'rad/s', 'top_torque': 'N m', 'hook_load': 'N',
                 'block_position': 'm', 'bit_speed': 'rad/s', 'torque_on_bit': 'N m',
                 'weight_on_bit': 'N'}
"""The SI unit of each measured channel (assimilation.measurements), for the sensor biases."""


def log_styles(recording, geometry: StringGeometry) -> None:
    """Log the static parts: series names, colours and widths, the borehole drawings."""
    import rerun as rr

    for entity, (name, colour, width) in _LINES.items():
        recording.log(entity, rr.SeriesLines(names=name, colors=colour, widths=width),
                      static=True)
    for entity, (name, colour, size) in _POINTS.items():
        recording.log(entity, rr.SeriesPoints(names=name, colors=colour, marker_sizes=size,
                                              markers='circle'), static=True)
    for key in ENSEMBLE_QUANTITIES:
        recording.log(f'ensemble/{key}/band', rr.SeriesLines(
            names=['95 % band'] * BAND_LINES, colors=[BAND] * BAND_LINES,
            widths=[BAND_LINE_WIDTH] * BAND_LINES), static=True)
        recording.log(f'ensemble/{key}/mean', rr.SeriesLines(
            names='ensemble mean', colors=BLUE, widths=2.5), static=True)
        recording.log(f'ensemble/{key}/model', rr.SeriesLines(
            names='mean model', colors=ORANGE, widths=1.2), static=True)
    for group, entries in (('germ', GERM_ENTRIES), ('law', LAW_ENTRIES)):
        for key, (name, colour) in entries.items():
            recording.log(f'ensemble/{group}/{key}/mean', rr.SeriesLines(
                names=f'{name} (mean)', colors=colour, widths=2.0), static=True)
            for bound in ('lower', 'upper'):
                recording.log(f'ensemble/{group}/{key}/{bound}', rr.SeriesLines(
                    names=f'{name} (95 %)', colors=colour, widths=0.8), static=True)
    for x_m, outer_m, gap_m in zip(geometry.stations_m, geometry.station_outer_radius_m,
                                   geometry.station_clearance_m):
        _log_cross_section(recording, station_entity(x_m), geometry.borehole_radius_m,
                           outer_m, gap_m)
        recording.log(f'{station_entity(x_m)}/radial', rr.SeriesLines(
            names='deflection', colors=BLUE, widths=1.5), static=True)
        recording.log(f'{station_entity(x_m)}/clearance', rr.SeriesLines(
            names='wall contact', colors=RED, widths=2.0), static=True)
    _log_data_styles(recording, geometry)
    recording.log('lateral/help', rr.TextDocument(LATERAL_HELP.format(trail=TRAIL_S),
                                                  media_type='text/plain'), static=True)


def _log_cross_section(recording, entity: str, borehole_m: float, outer_m: float,
                       gap_m: float) -> None:
    """Borehole wall, the circle where the pipe's centre touches it, axes, a scale bar."""
    import rerun as rr

    wall_mm, gap_mm = 1e3 * borehole_m, 1e3 * gap_m
    recording.log(f'{entity}/wall', rr.Ellipses2D(
        centers=[(0.0, 0.0)], half_sizes=[(wall_mm, wall_mm)], colors=DARK, line_radii=1.5,
        draw_order=1.0), static=True)
    recording.log(f'{entity}/contact_circle', rr.Ellipses2D(
        centers=[(0.0, 0.0)], half_sizes=[(gap_mm, gap_mm)], colors=RED, line_radii=0.6,
        draw_order=2.0), static=True)
    tick = _scale_mm(wall_mm)
    top = -wall_mm - 4.0                     # scale bar and axis names in the top corners,
    recording.log(f'{entity}/axes', rr.LineStrips2D(   # outside the wall circle
        [[(-wall_mm, 0.0), (wall_mm, 0.0)], [(0.0, -wall_mm), (0.0, wall_mm)],
         [(-wall_mm - 10.0, top), (-wall_mm - 10.0 + tick, top)]],
        colors=[GREY, GREY, DARK], radii=[0.3, 0.3, 1.2], draw_order=0.5), static=True)
    # (a pointer resting in the middle of a view shows a tooltip: no labels there)
    recording.log(f'{entity}/labels', rr.Points2D(
        [(wall_mm - 10.0, top + 2.0), (-wall_mm - 10.0 + tick / 2, top + 14.0)],
        radii=0.01, colors=DARK, labels=['v →  w ↓', f'{tick:g} mm'], show_labels=True),
        static=True)
    del outer_m                                          # the pipe is drawn with the data


def _scale_mm(length_mm: float) -> float:
    """Return a round scale-bar length about a third of ``length_mm``."""
    for step in (500, 200, 100, 50, 20, 10, 5, 2, 1):
        if step <= length_mm / 2.5:
            return float(step)
    return 1.0


# -- data ------------------------------------------------------------------------------------

def _time(t_s) -> list:
    import rerun as rr

    return [rr.TimeColumn(TIMELINE, duration=np.asarray(t_s, dtype=float))]


def _scalars(recording, entity: str, t_s, values) -> None:
    import rerun as rr

    values = np.asarray(values, dtype=float)
    if values.shape[0] == 0:
        return
    columns = rr.Scalars.columns(scalars=values)
    if values.ndim == 2:
        columns = columns.partition([values.shape[1]] * values.shape[0])
    recording.send_columns(entity, indexes=_time(t_s), columns=columns)


def send_bit(recording, t_s, depth_m, rop_m_per_s, speed_rad_per_s, weight_on_bit_n,
             torque_on_bit_nm) -> None:
    """Send the mean model's bit (SI, the paper's signs), arrays of one value per sample."""
    _scalars(recording, 'bit/depth', t_s, depth_m)
    _scalars(recording, 'bit/rop', t_s, 3600.0 * np.asarray(rop_m_per_s))
    _scalars(recording, 'bit/speed', t_s, RPM_PER_RAD_PER_S * np.asarray(speed_rad_per_s))
    _scalars(recording, 'bit/wob', t_s, -1e-3 * np.asarray(weight_on_bit_n))
    _scalars(recording, 'bit/tob', t_s, -1e-3 * np.asarray(torque_on_bit_nm))


def send_top(recording, t_s, speed_rad_per_s, torque_nm, hook_load_n) -> None:
    """Top drive: speed, torque applied; the hook load (SI)."""
    _scalars(recording, 'top/speed', t_s, RPM_PER_RAD_PER_S * np.asarray(speed_rad_per_s))
    _scalars(recording, 'top/torque', t_s, 1e-3 * np.asarray(torque_nm))
    _scalars(recording, 'top/hook_load', t_s, 1e-3 * np.asarray(hook_load_n))


def send_commands(recording, speed_t_s, speed_rad_per_s, hook_t_s, hook_load_n) -> None:
    """Commands as applied: top-drive speed (rad/s) and hook load (N)."""
    _scalars(recording, 'cmd/top_drive_speed', speed_t_s,
             RPM_PER_RAD_PER_S * np.asarray(speed_rad_per_s, dtype=float))
    _scalars(recording, 'cmd/hook_load', hook_t_s, 1e-3 * np.asarray(hook_load_n, dtype=float))


def send_kpis(recording, t_s, stick_slip_severity, mse_pa, rop_m_per_h) -> None:
    """Send the KPIs over the twin's window: SSI (-), MSE (Pa), ROP (m/h)."""
    _scalars(recording, 'kpi/ssi', t_s, stick_slip_severity)
    _scalars(recording, 'kpi/mse', t_s, 1e-6 * np.asarray(mse_pa, dtype=float))
    _scalars(recording, 'kpi/rop', t_s, rop_m_per_h)


def _ensemble_values(states) -> dict[str, np.ndarray]:
    """Bit states (n, 6) in BitState order -> displayed quantities."""
    states = np.asarray(states, dtype=float).reshape(-1, 6)
    return {'speed': RPM_PER_RAD_PER_S * states[:, 4], 'rop': 3600.0 * states[:, 1],
            'wob': -1e-3 * states[:, 2]}


def send_ensemble(recording, t_s, mean, lower, upper) -> None:
    """
    Send the ensemble mean and 2.5/97.5 % quantiles.

    Arrays (n, 6) in BitState field order (depth, ROP, WOB, angle, speed, TOB; SI). The band
    is :data:`BAND_LINES` lines from the lower to the upper bound.
    """
    means, lows, highs = map(_ensemble_values, (mean, lower, upper))
    for key in ENSEMBLE_QUANTITIES:
        _band(recording, f'ensemble/{key}/band', t_s, lows[key], highs[key])
        _scalars(recording, f'ensemble/{key}/mean', t_s, means[key])


def _band(recording, entity: str, t_s, low, high) -> None:
    """Send a band as :data:`BAND_LINES` lines from ``low`` to ``high`` (arrays (n,))."""
    low, high = np.asarray(low)[:, None], np.asarray(high)[:, None]
    _scalars(recording, entity, t_s,
             low + np.linspace(0.0, 1.0, BAND_LINES) * (high - low))


def send_estimate(recording, t_s, mean, lower, upper, open_loop=None, truth=None) -> None:
    """
    Send an assimilation's bit speed estimate (EST.mcap of ``drill-twin assimilate``), rad/s.

    Arrays (n,) at ``t_s``: the analysed ensemble's mean and 95 % bounds, drawn as the
    ensemble's mean and band; ``open_loop``: (t_s, mean, lower, upper) of the same ensemble
    without analysis (thin grey lines); ``truth``: (t_s, speed) of the rig log's true bit
    speed (green). Their series styles are logged with them.
    """
    import rerun as rr

    scale = RPM_PER_RAD_PER_S
    _band(recording, 'ensemble/speed/band', t_s, scale * np.asarray(lower),
          scale * np.asarray(upper))
    _scalars(recording, 'ensemble/speed/mean', t_s, scale * np.asarray(mean))
    if open_loop is not None:
        recording.log('ensemble/speed/open_loop/mean', rr.SeriesLines(
            names='open loop (mean)', colors=GREY, widths=1.2), static=True)
        for bound in ('lower', 'upper'):
            recording.log(f'ensemble/speed/open_loop/{bound}', rr.SeriesLines(
                names='open loop (95 %)', colors=GREY, widths=0.6), static=True)
        t_open, *values = open_loop
        for bound, series in zip(('mean', 'lower', 'upper'), values):
            _scalars(recording, f'ensemble/speed/open_loop/{bound}', t_open,
                     scale * np.asarray(series))
    if truth is not None:
        recording.log('ensemble/speed/truth', rr.SeriesLines(
            names='truth (rig log)', colors=GREEN, widths=1.5), static=True)
        _scalars(recording, 'ensemble/speed/truth', truth[0], scale * np.asarray(truth[1]))


def send_germ(recording, t_s, mean, lower, upper) -> None:
    """
    Send the estimated bit-rock germ of the analyses (assimilation).

    Arrays (n, 3): G11, G12, G22 of the analysed members' mean, 2.5 % and 97.5 %.
    """
    for column, key in enumerate(GERM_ENTRIES):
        for bound, values in (('mean', mean), ('lower', lower), ('upper', upper)):
            _scalars(recording, f'ensemble/germ/{key}/{bound}', t_s,
                     np.asarray(values, dtype=float)[:, column])


def send_law(recording, t_s, mean, lower, upper) -> None:
    """
    Send the estimated factors of the law's a1 ... a5 of the analyses (parameters 'law').

    Arrays (n, 5): the analysed members' mean, 2.5 % and 97.5 % (1: the configured law).
    """
    for column, key in enumerate(LAW_ENTRIES):
        for bound, values in (('mean', mean), ('lower', lower), ('upper', upper)):
            _scalars(recording, f'ensemble/law/{key}/{bound}', t_s,
                     np.asarray(values, dtype=float)[:, column])


def send_bias(recording, t_s, channels, mean, lower, upper) -> None:
    """
    Send the estimated sensor biases of the analyses (assimilation, ``bias_prior_std``).

    ``channels``: their names in column order; arrays (n, len(channels)), SI: the analysed
    members' mean, 2.5 % and 97.5 %. Each channel's series styles are logged with them.
    """
    import rerun as rr

    for column, channel in enumerate(channels):
        recording.log(f'ensemble/bias/{channel}/mean', rr.SeriesLines(
            names=f'{channel} bias (mean)', colors=BLUE, widths=2.0), static=True)
        for bound in ('lower', 'upper'):
            recording.log(f'ensemble/bias/{channel}/{bound}', rr.SeriesLines(
                names=f'{channel} bias (95 %)', colors=BLUE, widths=0.8), static=True)
        for bound, values in (('mean', mean), ('lower', lower), ('upper', upper)):
            _scalars(recording, f'ensemble/bias/{channel}/{bound}', t_s,
                     np.asarray(values, dtype=float)[:, column])


def send_ensemble_model(recording, t_s, rop_m_per_s, weight_on_bit_n, speed_rad_per_s) -> None:
    """Send the mean model beside the ensemble, for comparison (SI)."""
    _scalars(recording, 'ensemble/speed/model', t_s,
             RPM_PER_RAD_PER_S * np.asarray(speed_rad_per_s))
    _scalars(recording, 'ensemble/rop/model', t_s, 3600.0 * np.asarray(rop_m_per_s))
    _scalars(recording, 'ensemble/wob/model', t_s, -1e-3 * np.asarray(weight_on_bit_n))


def send_station(recording, geometry: StringGeometry, index: int, t_s, v_m, w_m,
                 previous: tuple[float, float] | None = None) -> None:
    """
    One station's lateral motion: orbit segments, pipe outline, radial deflection.

    ``previous``: the (v, w) before the first sample (m), to join batches of a live view.
    """
    import rerun as rr

    t_s = np.asarray(t_s, dtype=float)
    if t_s.size == 0:
        return
    entity = station_entity(geometry.stations_m[index])
    v_mm, w_mm = 1e3 * np.asarray(v_m, dtype=float), 1e3 * np.asarray(w_m, dtype=float)
    points = np.stack([v_mm, w_mm], axis=1)
    start = points[:1] if previous is None else 1e3 * np.asarray([previous], dtype=float)
    before = np.concatenate([start, points[:-1]])
    segments = np.stack([before, points], axis=1)                 # (n, 2, 2)
    recording.send_columns(f'{entity}/orbit', indexes=_time(t_s), columns=rr.LineStrips2D.columns(
        strips=list(segments)).partition([1] * t_s.size))
    outer_mm = 1e3 * geometry.station_outer_radius_m[index]
    recording.send_columns(f'{entity}/pipe', indexes=_time(t_s), columns=rr.Ellipses2D.columns(
        centers=points, half_sizes=np.full((t_s.size, 2), outer_mm)))
    _scalars(recording, f'{entity}/radial', t_s, np.hypot(v_mm, w_mm))
    ends = t_s[[0, -1]]
    _scalars(recording, f'{entity}/clearance', ends,
             np.full(2, 1e3 * geometry.station_clearance_m[index]))


def _log_data_styles(recording, geometry: StringGeometry) -> None:
    """Log the static colours of the orbits, pipes and bar charts."""
    import rerun as rr

    _log_bar_axes(recording, geometry)
    for x_m in geometry.stations_m:
        entity = station_entity(x_m)
        recording.log(f'{entity}/orbit', rr.LineStrips2D.from_fields(
            colors=BLUE, radii=0.8, draw_order=3.0), static=True)
        recording.log(f'{entity}/pipe', rr.Ellipses2D.from_fields(
            colors=ORANGE, line_radii=1.5, draw_order=4.0), static=True)


def send_profiles(recording, geometry: StringGeometry, t_s, contact_force_n,
                  station_radial_m) -> None:
    """
    Along the depth at each sample.

    Wall contact force at every node (N, (n, nodes)) and the stations' radial deflection (m, (n,
    stations)) as a % of their clearance.
    """
    t_s = np.asarray(t_s, dtype=float)
    if t_s.size == 0:
        return
    forces = 1e-3 * np.asarray(contact_force_n, dtype=float)
    _scalars(recording, 'contact/max_force', t_s, forces.max(axis=1) if forces.size else
             np.zeros(t_s.size))
    if forces.shape[1] == geometry.node_x_m.size:
        recording.send_columns('along/contact_force', indexes=_time(t_s),
                               columns=[_bar_values(forces)])
    if geometry.stations_m:
        share = (100.0 * np.asarray(station_radial_m, dtype=float)
                 / np.asarray(geometry.station_clearance_m))
        recording.send_columns('along/deflection', indexes=_time(t_s),
                               columns=[_bar_values(share)])


class _ArrowBatch:
    """A ready-made Arrow array as a component batch (for ``rr.ComponentColumn``)."""

    def __init__(self, array):
        self._array = array

    def as_arrow_array(self):
        return self._array


def _bar_values(values: np.ndarray):
    """
    Make a column of bar-chart value vectors, one per row of ``values`` (n, bars).

    ``rr.BarChart.columns`` stacks equal-length rows into one 2-D tensor, and building one
    ``TensorData`` per row costs milliseconds; the Arrow array is built here directly.
    """
    import pyarrow as pa
    import rerun as rr
    from rerun._unions import build_dense_union
    from rerun.encodings.tensor_data import TensorDataBatch

    values = np.ascontiguousarray(values, dtype=np.float64)
    n, k = values.shape
    data_type = TensorDataBatch._ARROW_DATATYPE
    rows = pa.array(np.arange(n + 1, dtype=np.int32))
    shape = pa.ListArray.from_arrays(rows, pa.array(np.full(n, k, dtype=np.uint64)))
    buffer = build_dense_union(data_type.field('buffer').type, 'F64', pa.ListArray.from_arrays(
        pa.array(np.arange(n + 1, dtype=np.int32) * k), pa.array(values.ravel())))
    array = pa.StructArray.from_arrays(
        [shape.cast(data_type.field('shape').type), pa.nulls(n, data_type.field('names').type),
         buffer], fields=list(data_type))
    return rr.ComponentColumn(rr.BarChart.descriptor_values(), _ArrowBatch(array))


def _log_bar_axes(recording, geometry: StringGeometry) -> None:
    """Log the abscissa (depth, m), bar widths and colours of the along-the-depth charts."""
    import rerun as rr

    nodes = geometry.node_x_m
    width = 0.8 * float(np.min(np.diff(nodes))) if nodes.size > 1 else 1.0
    charts = [('along/contact_force', nodes, width, RED)]
    if geometry.stations_m:
        charts.append(('along/deflection', np.asarray(geometry.stations_m), 40.0, BLUE))
    for entity, abscissa, bar_width, colour in charts:
        with warnings.catch_warnings():       # from_fields warns about the absent values
            warnings.simplefilter('ignore')
            chart = rr.BarChart.from_fields(
                abscissa=abscissa, widths=np.full(abscissa.size, bar_width, dtype=np.float32),
                color=colour)
        recording.log(entity, chart, static=True)


def send_health(recording, t_s, values: dict[str, Sequence[float]]) -> None:
    """
    Health figures.

    'real_time_factor', 'tick_time_ms', 'tick_time_max_ms', 'iterations_per_step',
    'ensemble_iterations_per_step', 'resets' (any subset).
    """
    for key, entity in (('real_time_factor', 'diagnostics/real_time_factor'),
                        ('tick_time_ms', 'diagnostics/tick_time'),
                        ('tick_time_max_ms', 'diagnostics/tick_time_max'),
                        ('iterations_per_step', 'diagnostics/iterations'),
                        ('ensemble_iterations_per_step', 'diagnostics/ensemble_iterations'),
                        ('resets', 'diagnostics/resets')):
        if key in values:
            _scalars(recording, entity, t_s, values[key])


_TEXT_LEVELS = {'info': 'INFO', 'warn': 'WARN', 'error': 'ERROR', 'debug': 'DEBUG'}


def send_text(recording, entity: str, t_s, texts: Sequence[str], levels: Sequence[str]) -> None:
    """Lines of text ('diagnostics/events' or 'rosout') with levels info/warn/error."""
    import rerun as rr

    if not len(texts):
        return
    recording.send_columns(entity, indexes=_time(t_s), columns=rr.TextLog.columns(
        text=list(texts), level=[_TEXT_LEVELS.get(level, 'INFO') for level in levels]))


# -- blueprint -------------------------------------------------------------------------------

def _legend(visible: bool = True):
    import rerun.blueprint as rrb

    return rrb.PlotLegend(corner='LeftTop', visible=visible)


def _series(name: str, contents: Sequence[str], *, legend: bool = False, **kwargs):
    import rerun.blueprint as rrb

    return rrb.TimeSeriesView(name=name, origin='/', contents=list(contents),
                              plot_legend=_legend(legend), **kwargs)


def _bit_tab():
    import rerun.blueprint as rrb

    return rrb.Grid(
        _series('Bit depth (m)', ['bit/depth']),
        _series('ROP (m/h): instant (blue), window mean (white)', ['bit/rop', 'kpi/rop']),
        _series('Speed (rpm): bit (blue), surface (orange)', ['bit/speed', 'top/speed']),
        _series('Weight on bit (kN)', ['bit/wob']),
        _series('Torque on bit (kN·m)', ['bit/tob']),
        _series('Stick-slip severity SSI (-)', ['kpi/ssi']),
        grid_columns=2, name=TAB_TITLES['bit'])


def _driller_tab():
    import rerun.blueprint as rrb

    return rrb.Grid(
        _series('Surface speed (rpm), commands as dots', ['top/speed', 'cmd/top_drive_speed']),
        _series('Surface torque (kN·m)', ['top/torque']),
        _series('Hook load (kN), commands as dots', ['top/hook_load', 'cmd/hook_load']),
        _series('Weight on bit (kN)', ['bit/wob']),
        _series('ROP (m/h): instant (blue), window mean (white)', ['bit/rop', 'kpi/rop']),
        _series('Stick-slip severity SSI (-)', ['kpi/ssi']),
        grid_columns=2, name=TAB_TITLES['driller'])


def _orbit_view(geometry: StringGeometry, index: int):
    import rerun.blueprint as rrb

    x_m = geometry.stations_m[index]
    entity = station_entity(x_m)
    reach = 1e3 * geometry.borehole_radius_m * 1.1
    trail = rrb.VisibleTimeRanges(timeline=TIMELINE,
                                  start=rrb.TimeRangeBoundary.cursor_relative(seconds=-TRAIL_S),
                                  end=rrb.TimeRangeBoundary.cursor_relative())
    return rrb.Spatial2DView(
        name=f'Orbit at {itf.station_label(x_m)}',
        origin=entity, contents=[f'{entity}/{part}' for part in (
            'wall', 'contact_circle', 'axes', 'labels', 'orbit', 'pipe')],
        visual_bounds=rrb.VisualBounds2D(x_range=[-reach, reach],
                                         y_range=[-reach - 10.0, reach]),
        background=rrb.Background(color=(255, 255, 255)),
        overrides={f'{entity}/orbit': [trail]})


LATERAL_HELP = (
    'Orbits look down the hole at the cursor time: black the borehole wall, orange the pipe '
    '(or collar), blue the path of its centre over the last {trail:g} s, red where the '
    'centre is when the pipe touches the wall. Bar charts: along the string, at the cursor.')


def _lateral_tab(geometry: StringGeometry):
    import rerun.blueprint as rrb

    views = []
    for index in range(len(geometry.stations_m)):
        views.append(_orbit_view(geometry, index))
    views.append(rrb.BarChartView(name='Wall contact force (kN) vs depth (m)',
                                  origin='along/contact_force', plot_legend=_legend(False)))
    for x_m in geometry.stations_m:
        entity = station_entity(x_m)
        views.append(_series(f'Radial deflection at {itf.station_label(x_m)} (mm)',
                             [f'{entity}/radial', f'{entity}/clearance']))
    views.append(rrb.BarChartView(name='Deflection, % of clearance, vs depth (m)',
                                  origin='along/deflection', plot_legend=_legend(False)))
    if not geometry.stations_m:
        views.append(rrb.TextDocumentView(name='No measurement stations in this log',
                                          origin='lateral'))
    grid = rrb.Grid(*views, grid_columns=len(geometry.stations_m) + 1,
                    row_shares=[3, 2] if geometry.stations_m else None)
    return rrb.Vertical(
        grid, rrb.Horizontal(
            _series('Largest wall contact force along the string (kN)', ['contact/max_force']),
            rrb.TextDocumentView(name='How to read', origin='lateral/help'),
            column_shares=[1, 1]),
        row_shares=[3, 1], name=TAB_TITLES['lateral'])


def _ensemble_tab(assimilation: bool = False, law: bool = False, bias_channels=(),
                  estimate: bool = False):
    import rerun.blueprint as rrb

    views = []
    if estimate:                    # an offline estimate: its bit speed, the truth, open loop
        views.append(_series(
            'Bit speed (rpm): estimate (blue), its 95 % band (shaded), truth (green), '
            'open loop (grey: mean, 95 %)',
            ['ensemble/speed/band', 'ensemble/speed/open_loop/lower',
             'ensemble/speed/open_loop/upper', 'ensemble/speed/open_loop/mean',
             'ensemble/speed/truth', 'ensemble/speed/mean']))
    for key, (title, unit) in ({} if estimate else ENSEMBLE_QUANTITIES).items():
        views.append(_series(
            f'{title} ({unit}): ensemble mean (blue), 95 % band (shaded), mean model (orange)',
            [f'ensemble/{key}/band', f'ensemble/{key}/model', f'ensemble/{key}/mean']))
    if assimilation:
        views.append(_series(
            'Estimated bit-rock germ: G11 (blue), G12 (orange), G22 (green); mean, 95 % (thin)',
            [f'ensemble/germ/{key}/{b}' for key in GERM_ENTRIES
             for b in ('lower', 'upper', 'mean')]))
    if assimilation and law:
        views.append(_series(
            'Law factors a1..a5 (blue, orange, green, red, purple; 1 = configured), '
            'mean, 95 % (thin)',
            [f'ensemble/law/{key}/{b}' for key in LAW_ENTRIES
             for b in ('lower', 'upper', 'mean')]))
    for channel in bias_channels if assimilation else ():
        views.append(_series(
            f'Estimated {channel} sensor bias ({CHANNEL_UNITS.get(channel, "SI")}): mean, '
            '95 % (thin)', [f'ensemble/bias/{channel}/{b}' for b in ('lower', 'upper', 'mean')]))
    return rrb.Vertical(*views, name=TAB_TITLES['ensemble'])


def _diagnostics_tab():
    import rerun.blueprint as rrb

    return rrb.Horizontal(
        rrb.Vertical(
            _series('Real-time factor (twin s per wall s)', ['diagnostics/real_time_factor']),
            _series('Tick wall time (ms): last (blue), slowest (red)',
                    ['diagnostics/tick_time', 'diagnostics/tick_time_max']),
            _series('Newton iterations per step: mean model (blue), ensemble (orange)',
                    ['diagnostics/iterations', 'diagnostics/ensemble_iterations']),
            _series('Member resets so far', ['diagnostics/resets'])),
        rrb.Vertical(
            rrb.TextLogView(name='Events (impacts, lift-offs, resets, rejected commands)',
                            origin='diagnostics/events'),
            rrb.TextLogView(name='/rosout', origin='rosout')),
        name=TAB_TITLES['diagnostics'])


def twin_blueprint(geometry: StringGeometry, *, active_tab: int | str = 0,
                   follow: bool = True, assimilation: bool = False, law: bool = False,
                   bias_channels=(), estimate: bool = False):
    """
    Build the rerun blueprint of the twin's views (tabs :data:`TABS`).

    :param active_tab: the tab shown first (index or name).
    :param follow: start with the time cursor following the newest data (at the end of a
        recorded run, moving with a live one).
    :param assimilation: the ensemble tab shows the estimated germ too.
    :param law: and the estimated factors of the law's coefficients (parameters 'law').
    :param bias_channels: and the estimated biases of these channels' sensors.
    :param estimate: the log is an offline estimate (EST.mcap): the ensemble tab shows its bit
        speed with the truth and the open loop instead of the twin's ensemble.
    """
    import rerun.blueprint as rrb

    tabs = rrb.Tabs(_bit_tab(), _driller_tab(), _lateral_tab(geometry),
                    _ensemble_tab(assimilation, law, tuple(bias_channels), estimate),
                    _diagnostics_tab(), active_tab=tab_index(active_tab))
    return rrb.Blueprint(tabs,
                         rrb.TimePanel(timeline=TIMELINE, state='collapsed',
                                       play_state='following' if follow else 'paused'),
                         rrb.BlueprintPanel(state='collapsed'),
                         rrb.SelectionPanel(state='collapsed'), auto_views=False)
