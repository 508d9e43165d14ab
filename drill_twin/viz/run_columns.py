"""
A twin log read into columns of numbers: what the rerun views plot.

The log is read with the project's reader (:func:`~drill_twin.recording.reader.iter_raw`, which
also reads a file cut short) and the numbers are decoded straight from the CDR bytes
(:mod:`~drill_twin.recording.cdr`); only the diagnostics and ``/rosout`` messages are
deserialised by rclpy, imported when the first of them is read (rclpy comes with ROS, which
reading a log without them does not need). Nothing here imports rerun.

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
from drill_twin.recording import cdr, reader
from drill_twin.recording.message_types import import_message_class
from drill_twin.recording.reader import iter_raw, read_metadata
from drill_twin.viz.rerun_entities import HEALTH_ENTITIES

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
    from rclpy.serialization import deserialize_message       # rclpy: see the module docstring

    return deserialize_message(data, import_message_class(type_name))


_LEVELS = {0: 'info', 1: 'warn', 2: 'error', 3: 'warn'}


def _diagnostics(run: RunColumns, type_name: str, data: bytes, t_s: float) -> None:
    """Health figures to series, every other status (an event) to a line of text."""
    for status in _deserialize(type_name, data).status:
        values = {item.key: item.value for item in status.values}
        if status.name == HEALTH_NAME:
            row = [t_s]
            for key in HEALTH_ENTITIES:
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


def is_estimate(run: RunColumns) -> bool:
    """Tell whether the run is an offline estimate (EST.mcap of ``drill-twin assimilate``)."""
    return bool(run.rows.get('estimate/mean'))
