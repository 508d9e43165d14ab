"""
What the twin node runs on, built outside it (no rclpy): the engine, its limits, the log.

The node (:mod:`drill_twin.ros.twin_node`) is handed a built
:class:`~drill_twin.twin.engine.TwinEngine` and its
:class:`~drill_twin.ros.parameters.TwinParameters`; these functions make them.
"""
from __future__ import annotations

import datetime
from pathlib import Path

import yaml

from drill_twin import __version__
from drill_twin.config import ConfigError, load_config
from drill_twin.config.loader import config_to_dict
from drill_twin.recording.log_metadata import TwinLogMetadata
from drill_twin.recording.twin_log import TwinLog
from drill_twin.ros.parameters import model_overrides, TwinParameters
from drill_twin.twin.engine import CommandLimits, EnsembleSettings, TwinEngine


def command_limits(params: TwinParameters) -> CommandLimits:
    """Return the commands the twin accepts (top-drive speed rad/s, hook load N, torque N m)."""
    return CommandLimits(top_drive_speed_max_rad_per_s=params.top_drive_speed_max_rad_per_s,
                         hook_load_min_n=params.hook_load_min_n,
                         hook_load_max_n=params.hook_load_max_n,
                         top_drive_torque_limit_max_nm=params.top_drive_torque_limit_max_nm)


def build_engine(params: TwinParameters) -> TwinEngine:
    """
    Load the model configuration the parameters name and build the twin's engine.

    The ensemble's worker process starts here. Raises ConfigError on a bad configuration.
    """
    config = load_config(params.model_config or None, model_overrides(params))
    assimilation = assimilation_settings(params)
    # An ensemble filter's members draw their germs from the filter's prior.
    dispersion = (params.ensemble_dispersion if assimilation is None
                  else assimilation.filter.prior_dispersion)
    return TwinEngine(config,
                      EnsembleSettings(members=params.ensemble_members, dispersion=dispersion,
                                       seed=params.seed,
                                       separate_process=params.ensemble_process,
                                       assimilation=assimilation),
                      command_limits(params), kpi_window_s=params.kpi_window_s)


def assimilation_settings(params: TwinParameters):
    """
    Return the ensemble filter's settings the parameters ask for, or None (assimilation off).

    Raises ConfigError naming the file, key or parameter at fault.
    """
    if not params.assimilation_enabled:
        return None
    from drill_twin.assimilation.settings import load_assimilation

    if params.ensemble_members < 2:
        raise ConfigError('parameters', 'ensemble_members', f'assimilation needs at least 2 '
                          f'ensemble members, got {params.ensemble_members}')
    for item in params.assimilation_overrides:
        if not item.startswith('assimilation.'):
            raise ConfigError('assimilation_overrides', item, 'expected assimilation.KEY=VALUE')
    return load_assimilation(params.assimilation_config or None,
                             list(params.assimilation_overrides))


def log_metadata(params: TwinParameters, engine: TwinEngine, *, epoch_ns: int, substeps: int,
                 fast: bool) -> TwinLogMetadata:
    """Describe the run as its log carries it (what ``replay --resimulate`` needs)."""
    return TwinLogMetadata(
        config_yaml=yaml.safe_dump(config_to_dict(engine.config), sort_keys=False),
        seed=params.seed, clock_epoch_ns=epoch_ns, time_step_s=engine.dt,
        ensemble_members=params.ensemble_members,
        ensemble_dispersion=engine.ensemble.dispersion,
        ensemble_process=bool(params.ensemble_process), rate_hz=params.rate_hz,
        substeps=substeps, fast=fast, kpi_window_s=params.kpi_window_s, version=__version__,
        assimilation=engine.assimilating)


def new_log_path(log_dir: str | Path) -> Path:
    """Return a bag directory not yet used: ``log_dir/drill_twin_<UTC time>[_k]``."""
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime('%Y%m%dT%H%M%SZ')
    path = Path(log_dir) / f'drill_twin_{stamp}'
    counter = 1
    while path.exists():
        path = Path(log_dir) / f'drill_twin_{stamp}_{counter}'
        counter += 1
    return path


def open_log(path: Path, params: TwinParameters, stations_m, metadata: TwinLogMetadata, *,
             tf: bool = False, measurement_topics=(),
             scalar_measurement_topics=()) -> TwinLog:
    """
    Open the run's log, the rosbag2 bag ``path``.

    With /tf and /tf_static if ``tf``, and the rig's sensor topics the twin assimilates
    (JointState; its channels on topics of their own: Float64).
    Raises OSError.
    """
    return TwinLog(path, stations_m, metadata, split_duration_s=params.log_split_s, tf=tf,
                   measurement_topics=measurement_topics,
                   scalar_measurement_topics=scalar_measurement_topics)


def contact_node_depths_m(config) -> list[float]:
    """
    Return the depths x of the nodes (m, down from the top).

    In the order of the contact-force array on /drill_twin/contact/forces (top to bottom).
    """
    from drill_twin.fem.mesh import build_mesh

    return [float(x) for x in build_mesh(config).node_x_m]


def contact_nodes_markdown(config) -> str:
    """Return the node-depth line of docs/ROS-INTERFACE.md for ``config``."""
    depths = contact_node_depths_m(config)
    return (f'{len(depths)} nodes, x (m) = '
            + ', '.join(f'{x:.2f}'.rstrip('0').rstrip('.') for x in depths))
