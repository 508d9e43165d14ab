"""
A twin log as native rerun data: one ``.rrd`` with the layout.

rerun's own MCAP importer shows raw ROS fields on wall-clock time; it cannot convert units,
shade a band or draw an orbit.  Here the log is read into columns
(:mod:`~drill_twin.viz.run_columns`) and the columns go to rerun through
:mod:`~drill_twin.viz.rerun_series`, the same functions the live view uses, on the ``run time``
timeline (seconds since the twin's clock epoch).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np
import rerun as rr
import yaml

from drill_twin import interface as itf
from drill_twin.config import build_config, ConfigError, load_config
from drill_twin.viz import rerun_series as series
from drill_twin.viz.rerun_blueprint import twin_blueprint
from drill_twin.viz.rerun_entities import APPLICATION_ID, HEALTH_ENTITIES, StringGeometry
from drill_twin.viz.rerun_styles import log_styles
from drill_twin.viz.run_columns import (
    BIAS_TOPICS, ESTIMATE_TOPICS, GERM_TOPICS, is_estimate, LAW_TOPICS, log_files, read_run,
    RunColumns, stations_from_topics)


def geometry_of(run: RunColumns, stations_m: Sequence[float] | None = None
                ) -> StringGeometry:
    """
    Return the string's geometry from the log's configuration and its stations.

    The built-in configuration if the log has none or an unreadable one; the stations given,
    else those with a displacement topic in the log.
    """
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
    return StringGeometry.from_config(config, stations_m)


def send_run(recording, run: RunColumns, geometry: StringGeometry) -> None:
    """Log every series of a run to a rerun recording."""
    log_styles(recording, geometry)
    bit = run.array('bit', 6)
    if bit.size:
        t = bit[:, 0]
        series.send_bit(recording, t, bit[:, 1], bit[:, 2], bit[:, 3], bit[:, 4], bit[:, 5])
        series.send_ensemble_model(recording, t, bit[:, 2], bit[:, 4], bit[:, 3])
    top = run.array('top', 4)
    if top.size:
        series.send_top(recording, top[:, 0], top[:, 1], top[:, 2], top[:, 3])
    speed, hook = run.array(itf.CMD_TOP_DRIVE_SPEED, 2), run.array(itf.CMD_HOOK_LOAD, 2)
    series.send_commands(recording, speed[:, 0], speed[:, 1], hook[:, 0], hook[:, 1])
    for topic, entity, scale in ((itf.KPI_STICK_SLIP, 'kpi/ssi', 1.0),
                                 (itf.KPI_MSE, 'kpi/mse', 1e-6),
                                 (itf.KPI_ROP, 'kpi/rop', 1.0)):
        values = run.array(topic, 2)
        series.send_scalars(recording, entity, values[:, 0], scale * values[:, 1])
    _send_ensemble(recording, run)
    _send_estimate(recording, run)
    _send_germ(recording, run)
    radial = []
    profile_t = run.array('contact', 1)[:, 0] if run.rows.get('contact') else np.zeros(0)
    for index, x_m in enumerate(geometry.stations_m):
        rows = run.array(itf.vibration_displacement_topic(x_m), 3)
        series.send_station(recording, geometry, index, rows[:, 0], rows[:, 1], rows[:, 2])
        radial.append(np.interp(profile_t, rows[:, 0], np.hypot(rows[:, 1], rows[:, 2]))
                      if rows.shape[0] else np.zeros(profile_t.size))
    if profile_t.size:
        contact = run.array('contact', 1 + geometry.node_x_m.size)
        series.send_profiles(recording, geometry, profile_t, contact[:, 1:],
                             np.stack(radial, axis=1) if radial
                             else np.zeros((profile_t.size, 0)))
    health = run.array('health', 1 + len(HEALTH_ENTITIES))
    if health.size:
        series.send_health(recording, health[:, 0],
                           {key: health[:, 1 + i] for i, key in enumerate(HEALTH_ENTITIES)})
    for entity, lines in run.texts.items():
        lines = sorted(lines, key=lambda line: line[0])
        series.send_text(recording, entity, [line[0] for line in lines],
                         [line[1] for line in lines], [line[2] for line in lines])


def _send_ensemble(recording, run: RunColumns) -> None:
    ensemble = _bounds(run, (itf.ENSEMBLE_MEAN, itf.ENSEMBLE_LOWER, itf.ENSEMBLE_UPPER), 6)
    if ensemble is not None:
        series.send_ensemble(recording, *ensemble)


def _send_estimate(recording, run: RunColumns) -> None:
    """Send an offline estimate's bit speed with its truth and open loop (EST.mcap), if any."""
    rows = {key: run.array(key, 2) for key in (*ESTIMATE_TOPICS.values(), 'truth')}
    n = min(len(rows[f'estimate/{b}']) for b in ('mean', 'lower', 'upper'))
    if n == 0:
        return
    m = min(len(rows[f'open_loop/{b}']) for b in ('mean', 'lower', 'upper'))
    open_loop = ((rows['open_loop/mean'][:m, 0],
                  *(rows[f'open_loop/{b}'][:m, 1] for b in ('mean', 'lower', 'upper')))
                 if m else None)
    truth = rows['truth']
    series.send_estimate(recording, rows['estimate/mean'][:n, 0],
                         *(rows[f'estimate/{b}'][:n, 1] for b in ('mean', 'lower', 'upper')),
                         open_loop=open_loop,
                         truth=(truth[:, 0], truth[:, 1]) if len(truth) else None)


def _send_germ(recording, run: RunColumns) -> None:
    """Send the estimated germ, law and sensor biases of a run's analyses, if any."""
    germ = _bounds(run, GERM_TOPICS, 3)
    if germ is not None:
        series.send_germ(recording, *germ)
    law = _bounds(run, LAW_TOPICS, 5)
    if law is not None:
        series.send_law(recording, *law)
    bias = _bounds(run, BIAS_TOPICS, len(run.bias_channels))
    if bias is not None and run.bias_channels:
        t, mean, lower, upper = bias
        series.send_bias(recording, t, run.bias_channels, mean, lower, upper)


def _bounds(run: RunColumns, topics, width: int):
    """
    Return (t, mean, lower, upper) of a mean and its bounds, ``width`` values each.

    The three series cut to their common length; None if it is 0.
    """
    mean, lower, upper = (run.array(topic, 1 + width) for topic in topics)
    n = min(mean.shape[0], lower.shape[0], upper.shape[0])
    return (mean[:n, 0], mean[:n, 1:], lower[:n, 1:], upper[:n, 1:]) if n else None


def write_rrd(source, rrd_path: str | os.PathLike, stations_m: Sequence[float] | None = None,
              *, active_tab: int | str | None = None,
              application_id: str = APPLICATION_ID) -> Path:
    """
    Convert a twin log into one self-contained ``.rrd`` (data and blueprint).

    :param source: a ``.mcap`` file, a bag directory, or a list of these (split files).
    :param stations_m: station depths (m); default: those of the log's topics.
    :param active_tab: the tab shown first (index or name, see
        :data:`~drill_twin.viz.rerun_entities.TABS`; None: the bit's, or the ensemble's for an
        offline estimate).
    :returns: the ``.rrd`` path.
    """
    files = log_files(source)
    run = read_run(files)
    geometry = geometry_of(run, stations_m)
    estimate = is_estimate(run)
    if active_tab is None:
        active_tab = 'ensemble' if estimate else 0
    blueprint = twin_blueprint(geometry, active_tab=active_tab, estimate=estimate,
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
