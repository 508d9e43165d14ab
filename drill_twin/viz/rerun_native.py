"""
A twin log as native rerun data: read the MCAP file(s), write one ``.rrd`` with the layout.

rerun's own MCAP importer shows raw ROS fields on wall-clock time; it cannot convert units,
shade a band or draw an orbit.  Here the log is read with the project's reader
(:func:`~drill_twin.recording.reader.iter_raw`, which also reads a file cut short), the
numbers are decoded straight from the CDR bytes (:mod:`~drill_twin.recording.cdr`), and the
columns go to rerun through :mod:`~drill_twin.viz.rerun_layout`, the same functions the
live view uses, on the ``run time`` timeline (seconds since the twin's clock epoch).

A log is a ``.mcap`` file, a rosbag2 bag directory (its ``metadata.yaml`` lists the split
files in order; without one, every ``*.mcap`` in it by name) or a list of these.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
import os
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from drill_twin import interface as itf
from drill_twin.recording import cdr
from drill_twin.viz import rerun_layout as layout

PROFILE_RATE_HZ = 10.0
"""Samples per second of run time for the along-the-depth bar charts."""
GERM_TOPICS = (itf.ASSIMILATION_GERM_MEAN, itf.ASSIMILATION_GERM_LOWER,
               itf.ASSIMILATION_GERM_UPPER)
"""The estimated germ (assimilation): mean, 2.5 % and 97.5 % of [G11, G12, G22]."""
LAW_TOPICS = (itf.ASSIMILATION_LAW_MEAN, itf.ASSIMILATION_LAW_LOWER, itf.ASSIMILATION_LAW_UPPER)
"""The estimated factors of the law's a1 ... a5 (parameters 'law'): mean, 2.5 %, 97.5 %."""
ESTIMATE_TOPICS = {f'{prefix}/{bound}': f'{kind}/{bound}'
                   for prefix, kind in ((itf.ASSIMILATION_BIT_STATE, 'estimate'),
                                        (itf.ASSIMILATION_OPEN_LOOP_BIT_STATE, 'open_loop'))
                   for bound in ('mean', 'lower', 'upper')}
"""An offline estimate's bit speed (EST.mcap): topic -> series ('estimate/mean', ...)."""
BIAS_TOPICS = (itf.ASSIMILATION_BIAS_MEAN, itf.ASSIMILATION_BIAS_LOWER,
               itf.ASSIMILATION_BIAS_UPPER)
"""The estimated sensor biases (labelled by channel): mean, 2.5 %, 97.5 %."""
HEALTH_NAME = 'drill_twin: twin health'


class LogNotFound(FileNotFoundError):
    """No MCAP file at the given place."""


def log_files(source) -> list[Path]:
    """
    List the MCAP files of a log, in order.

    A file, a bag directory, or a list of these (:func:`drill_twin.recording.reader.log_files`
    for each); LogNotFound (one line) if an item is not a log.
    """
    from drill_twin.recording import reader

    if isinstance(source, (str, os.PathLike)):
        source = [source]
    files: list[Path] = []
    for item in source:
        try:
            files.extend(reader.log_files(item))
        except (OSError, ValueError) as error:
            raise LogNotFound(str(error)) from None
    if not files:
        raise LogNotFound('no log given')
    return files


def stations_from_topics(topic_names: Iterable[str]) -> list[float]:
    """
    Return the station depths (m) named by the displacement topics, sorted.

    The inverse of :func:`drill_twin.interface.station_name`.
    """
    stations = (itf.station_from_topic(topic) for topic in topic_names)
    return sorted(x_m for x_m in stations if x_m is not None)


@dataclass
class RunColumns:
    """The numbers of a log, per series: lists of (time s, values...) rows."""

    metadata: dict[str, str] = field(default_factory=dict)
    topics: set[str] = field(default_factory=set)
    rows: dict[str, list] = field(default_factory=lambda: defaultdict(list))
    texts: dict[str, list] = field(default_factory=lambda: defaultdict(list))
    bias_channels: tuple[str, ...] = ()
    """The channels of the estimated sensor biases (the bias topics' label)."""

    def array(self, key: str, width: int) -> np.ndarray:
        """Return the rows of series ``key`` as numbers, shape (n, width); (0, width) if none."""
        rows = self.rows.get(key)
        return np.asarray(rows, dtype=float) if rows else np.zeros((0, width))


def _epoch_ns(metadata: dict[str, str]) -> int | None:
    try:
        return int(metadata['clock_epoch_ns'])
    except (KeyError, ValueError):
        return None


def read_run(files: Sequence[Path], stations_m: Sequence[float] | None = None) -> RunColumns:
    """Read the numbers the views plot from the log files (in order)."""
    from drill_twin.recording.reader import iter_raw, read_metadata

    run = RunColumns()
    metadata = read_metadata(files[0])             # a twin log's, or an estimate's (EST.mcap)
    run.metadata = dict(metadata.get('drill_twin') or metadata.get(itf.ESTIMATE_METADATA, {}))
    epoch = _epoch_ns(run.metadata)
    stations = {}
    next_profile = -np.inf
    latest_forces = None
    for path in files:
        for schema, channel, record in iter_raw(path):
            topic = channel.topic
            run.topics.add(topic)
            if epoch is None:
                epoch = record.log_time
            log_s = (record.log_time - epoch) * 1e-9
            data = record.data
            if topic == itf.BIT_STATE:
                stamp, position, velocity, effort = cdr.joint_state(data)
                run.rows['bit'].append(((stamp - epoch) * 1e-9, position[0], velocity[0],
                                        velocity[1], effort[0], effort[1]))
            elif topic == itf.TOP_STATE:
                stamp, position, velocity, effort = cdr.joint_state(data)
                run.rows['top'].append(((stamp - epoch) * 1e-9, velocity[0], effort[0],
                                        effort[1]))
            elif topic in GERM_TOPICS or topic in LAW_TOPICS:
                run.rows[topic].append((log_s, *cdr.float64_multi_array(data)))
            elif topic in ESTIMATE_TOPICS:
                stamp, _, velocity, _ = cdr.joint_state(data)
                run.rows[ESTIMATE_TOPICS[topic]].append(((stamp - epoch) * 1e-9, velocity[0]))
            elif topic == itf.RIG_TRUTH_BIT_STATE:      # joints bit_axial, bit_rotation
                stamp, _, velocity, _ = cdr.joint_state(data)
                run.rows['truth'].append(((stamp - epoch) * 1e-9, velocity[1]))
            elif topic in BIAS_TOPICS:
                if not run.bias_channels:      # the same channels in every message of a run
                    labels = cdr.float64_multi_array_labels(data)
                    run.bias_channels = tuple(labels[0].split(',')) if labels else ()
                run.rows[topic].append((log_s, *cdr.float64_multi_array(data)))
            elif topic in (itf.ENSEMBLE_MEAN, itf.ENSEMBLE_LOWER, itf.ENSEMBLE_UPPER):
                stamp, position, velocity, effort = cdr.joint_state(data)
                run.rows[topic].append(((stamp - epoch) * 1e-9, position[0], velocity[0],
                                        effort[0], position[1], velocity[1], effort[1]))
            elif topic.endswith('/displacement') and topic.startswith('/drill_twin/vibration/'):
                stamp, vector = cdr.vector3_stamped(data)
                stations.setdefault(topic, len(stations))
                run.rows[topic].append(((stamp - epoch) * 1e-9, vector[1], vector[2]))
            elif topic == itf.CONTACT_FORCES:
                latest_forces = cdr.float64_multi_array(data)
                if log_s >= next_profile:
                    next_profile = log_s + 1.0 / PROFILE_RATE_HZ - 1e-9
                    run.rows['contact'].append((log_s, *latest_forces))
            elif topic in (itf.KPI_STICK_SLIP, itf.KPI_MSE, itf.KPI_ROP, itf.CMD_TOP_DRIVE_SPEED,
                           itf.CMD_HOOK_LOAD):
                run.rows[topic].append((log_s, cdr.float64(data)))
            elif topic == itf.DIAGNOSTICS:
                _diagnostics(run, schema.name, data, log_s)
            elif topic == itf.ROSOUT:
                _rosout(run, schema.name, data, log_s)
    return run


def _deserialize(type_name: str, data: bytes):
    from rclpy.serialization import deserialize_message

    from drill_twin.recording.message_types import import_message_class

    return deserialize_message(data, import_message_class(type_name))


_LEVELS = {0: 'info', 1: 'warn', 2: 'error', 3: 'warn'}


def _diagnostics(run: RunColumns, type_name: str, data: bytes, t_s: float) -> None:
    """Health figures to series, every other status (an event) to a line of text."""
    for status in _deserialize(type_name, data).status:
        values = {item.key: item.value for item in status.values}
        if status.name == HEALTH_NAME:
            row = [t_s]
            for key in ('real_time_factor', 'tick_time_ms', 'tick_time_max_ms',
                        'iterations_per_step', 'ensemble_iterations_per_step', 'resets'):
                try:
                    row.append(float(values[key]))
                except (KeyError, ValueError):
                    row.append(np.nan)
            run.rows['health'].append(tuple(row))
            continue
        level = _LEVELS.get(int.from_bytes(status.level, 'little')
                            if isinstance(status.level, bytes) else int(status.level), 'info')
        name = status.name.removeprefix('drill_twin: ')
        event_t = values.get('sim_time_s')
        text = f'{name}: {status.message}' if status.message else name
        run.texts['diagnostics/events'].append(
            (float(event_t) if event_t else t_s, text, level))


_LOG_LEVELS = {10: 'debug', 20: 'info', 30: 'warn', 40: 'error', 50: 'error'}


def _rosout(run: RunColumns, type_name: str, data: bytes, t_s: float) -> None:
    message = _deserialize(type_name, data)
    level = _LOG_LEVELS.get(int.from_bytes(message.level, 'little')
                            if isinstance(message.level, bytes) else int(message.level), 'info')
    run.texts['rosout'].append((t_s, message.msg, level))


def geometry_of(run: RunColumns, stations_m: Sequence[float] | None = None
                ) -> layout.StringGeometry:
    """
    Return the string's geometry from the log's configuration and its stations.

    The built-in configuration if the log has none or an unreadable one; the stations given,
    else those with a displacement topic in the log.
    """
    import yaml

    from drill_twin.config import build_config, ConfigError, load_config

    config = None
    text = run.metadata.get('config')
    if text:
        try:
            config = build_config(yaml.safe_load(text), source='log')
        except (ConfigError, yaml.YAMLError, TypeError, ValueError):
            config = None                      # not a twin configuration: sizes as built in
    if config is None:
        config = load_config(None)
    if stations_m is None:
        stations_m = stations_from_topics(run.topics)
    return layout.StringGeometry.from_config(config, stations_m)


def send_run(recording, run: RunColumns, geometry: layout.StringGeometry) -> None:
    """Log every series of a run to a rerun recording."""
    layout.log_styles(recording, geometry)
    bit = run.array('bit', 6)
    if bit.size:
        t = bit[:, 0]
        layout.send_bit(recording, t, bit[:, 1], bit[:, 2], bit[:, 3], bit[:, 4], bit[:, 5])
        layout.send_ensemble_model(recording, t, bit[:, 2], bit[:, 4], bit[:, 3])
    top = run.array('top', 4)
    if top.size:
        layout.send_top(recording, top[:, 0], top[:, 1], top[:, 2], top[:, 3])
    speed, hook = run.array(itf.CMD_TOP_DRIVE_SPEED, 2), run.array(itf.CMD_HOOK_LOAD, 2)
    layout.send_commands(recording, speed[:, 0], speed[:, 1], hook[:, 0], hook[:, 1])
    for topic, entity, scale in ((itf.KPI_STICK_SLIP, 'kpi/ssi', 1.0),
                                 (itf.KPI_MSE, 'kpi/mse', 1e-6),
                                 (itf.KPI_ROP, 'kpi/rop', 1.0)):
        values = run.array(topic, 2)
        layout._scalars(recording, entity, values[:, 0], scale * values[:, 1])
    _send_ensemble(recording, run)
    _send_estimate(recording, run)
    _send_germ(recording, run)
    radial = []
    profile_t = run.array('contact', 1)[:, 0] if run.rows.get('contact') else np.zeros(0)
    for index, x_m in enumerate(geometry.stations_m):
        rows = run.array(itf.vibration_displacement_topic(x_m), 3)
        layout.send_station(recording, geometry, index, rows[:, 0], rows[:, 1], rows[:, 2])
        radial.append(np.interp(profile_t, rows[:, 0], np.hypot(rows[:, 1], rows[:, 2]))
                      if rows.shape[0] else np.zeros(profile_t.size))
    if profile_t.size:
        contact = run.array('contact', 1 + geometry.node_x_m.size)
        layout.send_profiles(recording, geometry, profile_t, contact[:, 1:],
                             np.stack(radial, axis=1) if radial
                             else np.zeros((profile_t.size, 0)))
    health = run.array('health', 7)
    if health.size:
        keys = ('real_time_factor', 'tick_time_ms', 'tick_time_max_ms', 'iterations_per_step',
                'ensemble_iterations_per_step', 'resets')
        layout.send_health(recording, health[:, 0],
                           {key: health[:, 1 + i] for i, key in enumerate(keys)})
    for entity, lines in run.texts.items():
        lines = sorted(lines, key=lambda line: line[0])
        layout.send_text(recording, entity, [line[0] for line in lines],
                         [line[1] for line in lines], [line[2] for line in lines])


def _send_ensemble(recording, run: RunColumns) -> None:
    mean, lower, upper = (run.array(topic, 7) for topic in (
        itf.ENSEMBLE_MEAN, itf.ENSEMBLE_LOWER, itf.ENSEMBLE_UPPER))
    n = min(mean.shape[0], lower.shape[0], upper.shape[0])
    if n == 0:
        return
    layout.send_ensemble(recording, mean[:n, 0], mean[:n, 1:], lower[:n, 1:], upper[:n, 1:])


def _send_estimate(recording, run: RunColumns) -> None:
    """Send an offline estimate's bit speed with its truth and open loop (EST.mcap), if any."""
    series = {key: run.array(key, 2) for key in (*ESTIMATE_TOPICS.values(), 'truth')}
    n = min(len(series[f'estimate/{b}']) for b in ('mean', 'lower', 'upper'))
    if n == 0:
        return
    m = min(len(series[f'open_loop/{b}']) for b in ('mean', 'lower', 'upper'))
    open_loop = ((series['open_loop/mean'][:m, 0],
                  *(series[f'open_loop/{b}'][:m, 1] for b in ('mean', 'lower', 'upper')))
                 if m else None)
    truth = series['truth']
    layout.send_estimate(recording, series['estimate/mean'][:n, 0],
                         *(series[f'estimate/{b}'][:n, 1] for b in ('mean', 'lower', 'upper')),
                         open_loop=open_loop,
                         truth=(truth[:, 0], truth[:, 1]) if len(truth) else None)


def is_estimate(run: RunColumns) -> bool:
    """Tell whether the run is an offline estimate (EST.mcap of ``drill-twin assimilate``)."""
    return bool(run.rows.get('estimate/mean'))


def _send_germ(recording, run: RunColumns) -> None:
    mean, lower, upper = (run.array(topic, 4) for topic in GERM_TOPICS)
    n = min(mean.shape[0], lower.shape[0], upper.shape[0])
    if n:
        layout.send_germ(recording, mean[:n, 0], mean[:n, 1:], lower[:n, 1:], upper[:n, 1:])
    mean, lower, upper = (run.array(topic, 6) for topic in LAW_TOPICS)
    n = min(mean.shape[0], lower.shape[0], upper.shape[0])
    if n:
        layout.send_law(recording, mean[:n, 0], mean[:n, 1:], lower[:n, 1:], upper[:n, 1:])
    b = len(run.bias_channels)
    mean, lower, upper = (run.array(topic, 1 + b) for topic in BIAS_TOPICS)
    n = min(mean.shape[0], lower.shape[0], upper.shape[0])
    if n and b:
        layout.send_bias(recording, mean[:n, 0], run.bias_channels, mean[:n, 1:],
                         lower[:n, 1:], upper[:n, 1:])


def write_rrd(source, rrd_path: str | os.PathLike, stations_m: Sequence[float] | None = None,
              *, active_tab: int | str | None = None,
              application_id: str = layout.APPLICATION_ID) -> Path:
    """
    Convert a twin log into one self-contained ``.rrd`` (data and blueprint).

    :param source: a ``.mcap`` file, a bag directory, or a list of these (split files).
    :param stations_m: station depths (m); default: those of the log's topics.
    :param active_tab: the tab shown first (index or name, see :data:`rerun_layout.TABS`;
        None: the bit's, or the ensemble's for an offline estimate).
    :returns: the ``.rrd`` path.
    """
    import rerun as rr

    files = log_files(source)
    run = read_run(files)
    geometry = geometry_of(run, stations_m)
    estimate = is_estimate(run)
    if active_tab is None:
        active_tab = 'ensemble' if estimate else 0
    blueprint = layout.twin_blueprint(geometry, active_tab=active_tab, estimate=estimate,
                                      assimilation=bool(run.rows.get(itf.ASSIMILATION_GERM_MEAN)),
                                      law=bool(run.rows.get(itf.ASSIMILATION_LAW_MEAN)),
                                      bias_channels=run.bias_channels)
    rrd_path = Path(rrd_path)
    recording = rr.RecordingStream(application_id, recording_id=files[0].stem)
    try:
        recording.save(rrd_path, default_blueprint=blueprint)
        send_run(recording, run, geometry)
        recording.flush()
    finally:
        recording.disconnect()
    return rrd_path
