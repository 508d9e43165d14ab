"""
The data of the twin's rerun views: arrays of SI values in, rerun columns out.

The ``send_*`` functions take arrays of SI values (one row per sample) and are the one place
where units are converted and entities named; the recorded view
(:mod:`~drill_twin.viz.rerun_native`) and the live one (:mod:`~drill_twin.viz.live_view`) both
call them. WOB and TOB are shown positive while drilling (compression, resisting torque); the
ROS topics carry the paper's signs (negative).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun._unions import build_dense_union
from rerun.encodings.tensor_data import TensorDataBatch

from drill_twin.viz.rerun_entities import (
    BAND_LINES, BLUE, ENSEMBLE_QUANTITIES, GERM_ENTRIES, GREEN, GREY, HEALTH_ENTITIES,
    LAW_ENTRIES, RPM_PER_RAD_PER_S, station_entity, StringGeometry, TIMELINE)
from drill_twin.viz.rerun_styles import log_bound_styles


def _time(t_s) -> list:
    return [rr.TimeColumn(TIMELINE, duration=np.asarray(t_s, dtype=float))]


def send_scalars(recording, entity: str, t_s, values) -> None:
    """Send ``values`` at the times ``t_s`` (s): (n,) one series, (n, k) k series."""
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
    send_scalars(recording, 'bit/depth', t_s, depth_m)
    send_scalars(recording, 'bit/rop', t_s, 3600.0 * np.asarray(rop_m_per_s))
    send_scalars(recording, 'bit/speed', t_s, RPM_PER_RAD_PER_S * np.asarray(speed_rad_per_s))
    send_scalars(recording, 'bit/wob', t_s, -1e-3 * np.asarray(weight_on_bit_n))
    send_scalars(recording, 'bit/tob', t_s, -1e-3 * np.asarray(torque_on_bit_nm))


def send_top(recording, t_s, speed_rad_per_s, torque_nm, hook_load_n) -> None:
    """Top drive: speed, torque applied; the hook load (SI)."""
    send_scalars(recording, 'top/speed', t_s, RPM_PER_RAD_PER_S * np.asarray(speed_rad_per_s))
    send_scalars(recording, 'top/torque', t_s, 1e-3 * np.asarray(torque_nm))
    send_scalars(recording, 'top/hook_load', t_s, 1e-3 * np.asarray(hook_load_n))


def send_commands(recording, speed_t_s, speed_rad_per_s, hook_t_s, hook_load_n) -> None:
    """Commands as applied: top-drive speed (rad/s) and hook load (N)."""
    send_scalars(recording, 'cmd/top_drive_speed', speed_t_s,
                 RPM_PER_RAD_PER_S * np.asarray(speed_rad_per_s, dtype=float))
    send_scalars(recording, 'cmd/hook_load', hook_t_s, 1e-3 * np.asarray(hook_load_n, dtype=float))


def send_kpis(recording, t_s, stick_slip_severity, mse_pa, rop_m_per_h) -> None:
    """Send the KPIs over the twin's window: SSI (-), MSE (Pa), ROP (m/h)."""
    send_scalars(recording, 'kpi/ssi', t_s, stick_slip_severity)
    send_scalars(recording, 'kpi/mse', t_s, 1e-6 * np.asarray(mse_pa, dtype=float))
    send_scalars(recording, 'kpi/rop', t_s, rop_m_per_h)


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
        send_scalars(recording, f'ensemble/{key}/mean', t_s, means[key])


def _band(recording, entity: str, t_s, low, high) -> None:
    """Send a band as :data:`BAND_LINES` lines from ``low`` to ``high`` (arrays (n,))."""
    low, high = np.asarray(low)[:, None], np.asarray(high)[:, None]
    send_scalars(recording, entity, t_s,
                 low + np.linspace(0.0, 1.0, BAND_LINES) * (high - low))


def send_estimate(recording, t_s, mean, lower, upper, open_loop=None, truth=None) -> None:
    """
    Send an assimilation's bit speed estimate (EST.mcap of ``drill-twin assimilate``), rad/s.

    Arrays (n,) at ``t_s``: the analysed ensemble's mean and 95 % bounds, drawn as the
    ensemble's mean and band; ``open_loop``: (t_s, mean, lower, upper) of the same ensemble
    without analysis (thin grey lines); ``truth``: (t_s, speed) of the rig log's true bit
    speed (green). Their series styles are logged with them.
    """
    scale = RPM_PER_RAD_PER_S
    _band(recording, 'ensemble/speed/band', t_s, scale * np.asarray(lower),
          scale * np.asarray(upper))
    send_scalars(recording, 'ensemble/speed/mean', t_s, scale * np.asarray(mean))
    if open_loop is not None:
        log_bound_styles(recording, 'ensemble/speed/open_loop', 'open loop', GREY, 1.2, 0.6)
        t_open, *values = open_loop
        for bound, series in zip(('mean', 'lower', 'upper'), values):
            send_scalars(recording, f'ensemble/speed/open_loop/{bound}', t_open,
                         scale * np.asarray(series))
    if truth is not None:
        recording.log('ensemble/speed/truth', rr.SeriesLines(
            names='truth (rig log)', colors=GREEN, widths=1.5), static=True)
        send_scalars(recording, 'ensemble/speed/truth', truth[0], scale * np.asarray(truth[1]))


def send_germ(recording, t_s, mean, lower, upper) -> None:
    """
    Send the estimated bit-rock germ of the analyses (assimilation).

    Arrays (n, 3): G11, G12, G22 of the analysed members' mean, 2.5 % and 97.5 %.
    """
    _send_bounds(recording, 'germ', GERM_ENTRIES, t_s, mean, lower, upper)


def send_law(recording, t_s, mean, lower, upper) -> None:
    """
    Send the estimated factors of the law's a1 ... a5 of the analyses (parameters 'law').

    Arrays (n, 5): the analysed members' mean, 2.5 % and 97.5 % (1: the configured law).
    """
    _send_bounds(recording, 'law', LAW_ENTRIES, t_s, mean, lower, upper)


def send_bias(recording, t_s, channels, mean, lower, upper) -> None:
    """
    Send the estimated sensor biases of the analyses (assimilation, ``bias_prior_std``).

    ``channels``: their names in column order; arrays (n, len(channels)), SI: the analysed
    members' mean, 2.5 % and 97.5 %. Each channel's series styles are logged with them.
    """
    for channel in channels:
        log_bound_styles(recording, f'ensemble/bias/{channel}', f'{channel} bias', BLUE)
    _send_bounds(recording, 'bias', channels, t_s, mean, lower, upper)


def _send_bounds(recording, group: str, keys, t_s, mean, lower, upper) -> None:
    """Send ``ensemble/<group>/<key>/{mean,lower,upper}``: column k of the arrays (n, keys)."""
    for column, key in enumerate(keys):
        for bound, values in (('mean', mean), ('lower', lower), ('upper', upper)):
            send_scalars(recording, f'ensemble/{group}/{key}/{bound}', t_s,
                         np.asarray(values, dtype=float)[:, column])


def send_ensemble_model(recording, t_s, rop_m_per_s, weight_on_bit_n, speed_rad_per_s) -> None:
    """Send the mean model beside the ensemble, for comparison (SI)."""
    send_scalars(recording, 'ensemble/speed/model', t_s,
                 RPM_PER_RAD_PER_S * np.asarray(speed_rad_per_s))
    send_scalars(recording, 'ensemble/rop/model', t_s, 3600.0 * np.asarray(rop_m_per_s))
    send_scalars(recording, 'ensemble/wob/model', t_s, -1e-3 * np.asarray(weight_on_bit_n))


def send_station(recording, geometry: StringGeometry, index: int, t_s, v_m, w_m,
                 previous: tuple[float, float] | None = None) -> None:
    """
    One station's lateral motion: orbit segments, pipe outline, radial deflection.

    ``previous``: the (v, w) before the first sample (m), to join batches of a live view.
    """
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
    send_scalars(recording, f'{entity}/radial', t_s, np.hypot(v_mm, w_mm))
    ends = t_s[[0, -1]]
    send_scalars(recording, f'{entity}/clearance', ends,
                 np.full(2, 1e3 * geometry.station_clearance_m[index]))


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
    send_scalars(recording, 'contact/max_force', t_s, forces.max(axis=1) if forces.size else
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


def send_health(recording, t_s, values: dict[str, Sequence[float]]) -> None:
    """Send health figures: ``values`` holds any of :data:`HEALTH_ENTITIES`' keys."""
    for key, entity in HEALTH_ENTITIES.items():
        if key in values:
            send_scalars(recording, entity, t_s, values[key])


_TEXT_LEVELS = {'info': 'INFO', 'warn': 'WARN', 'error': 'ERROR', 'debug': 'DEBUG'}


def send_text(recording, entity: str, t_s, texts: Sequence[str], levels: Sequence[str]) -> None:
    """Lines of text ('diagnostics/events' or 'rosout') with levels info/warn/error."""
    if not len(texts):
        return
    recording.send_columns(entity, indexes=_time(t_s), columns=rr.TextLog.columns(
        text=list(texts), level=[_TEXT_LEVELS.get(level, 'INFO') for level in levels]))
