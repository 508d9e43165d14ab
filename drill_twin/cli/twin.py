"""``drill-twin twin``: the ROS 2 twin node (the same node as ``ros2 run drill_twin twin``)."""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from drill_twin.cli import startup_signals
from drill_twin.cli.common import UsageError, positive_seconds, preflight_or_refuse
from drill_twin.config import ConfigError, load_config
from drill_twin.config.paths import config_directory
from drill_twin.ros.parameters import (PARAMETERS, ParameterError, check_parameter,
                                       model_overrides, parameters_from_ros_arguments,
                                       validate_ros_arguments)


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'twin', help='run the twin node (ROS 2)',
        description='Run the digital twin as a ROS 2 node beside the rig: it paces the model '
                    'by the wall clock, takes top-drive speed and hook-load commands, '
                    'publishes the bit, vibration, contacts, KPIs and ensemble bounds, and '
                    'logs everything to MCAP. Options set node parameters (config/twin.yaml '
                    'holds the defaults); anything after --ros-args goes to ROS.')
    parser.add_argument('--params-file', metavar='FILE',
                        help='node parameters (default: the shipped config/twin.yaml)')
    parser.add_argument('--config', metavar='FILE', help='model configuration YAML')
    parser.add_argument('--set', dest='overrides', action='append', default=[],
                        metavar='KEY=VALUE', help='override one value of the model configuration')
    parser.add_argument('--duration', type=float, metavar='S',
                        help='stop after S simulated seconds (default: run until stopped)')
    parser.add_argument('--log-dir', metavar='DIR', help='where the MCAP log goes (default runs/)')
    parser.add_argument('--no-log', action='store_true', help='do not record a log')
    parser.add_argument('--view', action='store_true',
                        help='stream to a rerun viewer on 127.0.0.1 while the twin runs '
                             '(the tabs of drill-twin view)')
    parser.add_argument('--web', action='store_true',
                        help="with --view: serve rerun's web viewer instead of a window")
    parser.add_argument('--fast', action='store_true',
                        help='run as fast as possible and publish /clock')
    default = {spec.name: spec.default for spec in PARAMETERS}
    parser.add_argument('--ensemble', type=int, metavar='N',
                        help=f'ensemble members (default {default["ensemble_members"]})')
    parser.add_argument('--delta', type=float, help='dispersion of the ensemble '
                        f'(default {default["ensemble_dispersion"]})')
    parser.add_argument('--seed', type=int,
                        help=f'seed of the ensemble (default {default["seed"]})')
    parser.add_argument('--ensemble-in-process', action='store_true',
                        help='integrate the ensemble in the node\'s process instead of a '
                             'worker process (one-core machines)')
    parser.add_argument('--assimilate', action='store_true',
                        help='correct the ensemble with the rig\'s measurements (/rig/top_drive, '
                             '/rig/hook: an ensemble Kalman filter, docs/ASSIMILATION.md)')
    parser.add_argument('--assimilation', metavar='FILE',
                        help='assimilation settings (default config/assimilation.yaml); '
                             'implies --assimilate')
    parser.set_defaults(run=run)


PARAMETER_OF_KEY = {'integration.time_step_s': 'time_step_s',
                    'top_drive.controller': 'top_drive_controller'}
"""Model configuration keys that a node parameter sets (ros.parameters.model_overrides)."""
OPTION_PARAMETERS = {'duration': ('--duration', 'duration_s'),
                     'ensemble': ('--ensemble', 'ensemble_members'),
                     'delta': ('--delta', 'ensemble_dispersion'),
                     'seed': ('--seed', 'seed')}
"""Options that set a node parameter with a range: option, parameter."""


def ros_arguments(args: argparse.Namespace) -> list[str]:
    """
    Return the ROS command line of the node for the parsed options.

    Each value is checked against the parameter's type and range (UsageError).
    """
    params_file = args.params_file or str(config_directory() / 'twin.yaml')
    if not Path(params_file).is_file():
        raise UsageError(f'--params-file: {params_file}: no such file')
    ros = ['--ros-args', '--params-file', params_file]

    def set_parameter(name, value):
        ros.extend(['-p', f'{name}:={json.dumps(value)}'])

    for attribute, (option, name) in OPTION_PARAMETERS.items():
        value = getattr(args, attribute)
        if value is None:
            continue
        if attribute == 'duration':
            positive_seconds(option, value)
        try:
            check_parameter(name, value)
        except ParameterError as error:
            raise UsageError(f'{option}: {error.message} (parameter {name})') from None
    if args.config:
        if not Path(args.config).is_file():
            raise UsageError(f'--config: {args.config}: no such file')
        set_parameter('model_config', str(Path(args.config).resolve()))
    if args.overrides:
        set_parameter('model_overrides', args.overrides)
    if args.duration is not None:
        set_parameter('duration_s', float(args.duration))
    if args.log_dir:
        set_parameter('log_dir', args.log_dir)
    if args.no_log:
        set_parameter('log_enabled', False)
    if args.fast:
        set_parameter('fast', True)
    if args.ensemble is not None:
        set_parameter('ensemble_members', args.ensemble)
    if args.delta is not None:
        set_parameter('ensemble_dispersion', float(args.delta))
    if args.seed is not None:
        set_parameter('seed', args.seed)
    if args.ensemble_in_process:
        set_parameter('ensemble_process', False)
    if args.assimilation:
        if not Path(args.assimilation).is_file():
            raise UsageError(f'--assimilation: {args.assimilation}: no such file')
        set_parameter('assimilation_config', str(Path(args.assimilation).resolve()))
    if args.assimilate or args.assimilation:
        set_parameter('assimilation_enabled', True)
    return ros + list(getattr(args, 'ros_args', []))


def checked_start(ros: list[str]) -> dict:
    """
    Check the node's parameters and model configuration before the node starts.

    The parameters are checked as the node would (params files and -p rules included), the
    model configuration is loaded and pre-flighted: every problem is one line (exit 2).
    Returns the parameters.
    """
    try:
        values = validate_ros_arguments(ros)
    except ParameterError as error:
        raise UsageError(str(error)) from None
    overrides = model_overrides(values)
    try:
        config = load_config(values['model_config'] or None, overrides)
    except ConfigError as error:
        raise _blamed_on_parameter(error, ros, values['model_overrides']) from None
    preflight_or_refuse(config, overrides)
    return values


def _blamed_on_parameter(error: ConfigError, ros: list[str], model_items) -> Exception:
    """
    Return a refused override as the node parameter that made it (UsageError), if one did.

    ``time_step_s`` and ``top_drive_controller`` become overrides of the model configuration
    (PARAMETER_OF_KEY); a refusal of one is blamed on where the parameter was given, unless a
    ``model_overrides`` item sets the same key (``error`` is then returned as it is).
    """
    name = PARAMETER_OF_KEY.get(error.key)
    own = any(item.split('=', 1)[0].strip() == error.key for item in model_items or ())
    origins = [origin for origin, found, _ in parameters_from_ros_arguments(ros)
               if found == name]
    if error.source != '--set' or name is None or own or not origins:
        return error
    return UsageError(f'{origins[-1]}: {name}: {error.message}')


DISCOVERY_RANGE = 'ROS_AUTOMATIC_DISCOVERY_RANGE'
"""How far ROS 2 discovery reaches (Jazzy: LOCALHOST, SUBNET, OFF, SYSTEM_DEFAULT)."""


def close_discovery(environ=os.environ) -> str:
    """
    Keep the twin's discovery on this host unless the environment already says otherwise.

    A rig network would otherwise let any host of the same ROS domain drive the top drive.
    Return the range in force; ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` opens the twin
    (docs/ROS-INTERFACE.md, "Who can command the twin").
    """
    return environ.setdefault(DISCOVERY_RANGE, 'LOCALHOST')


def run(args: argparse.Namespace) -> int:
    try:
        startup_signals.arm()         # a SIGINT or SIGTERM since start-up stops here
        close_discovery()
        ros = ros_arguments(args)
        if args.web and not args.view:
            raise UsageError('--web: only with --view (the live viewer)')
        if args.view and not args.web:
            from drill_twin.viz.rerun_view import has_display, LIVE_NO_DISPLAY_HINT
            if not has_display():
                raise UsageError(LIVE_NO_DISPLAY_HINT)
        checked_start(ros)
        from drill_twin.ros.twin_node import run as run_node

        return run_node(['drill-twin'] + ros,
                        view=('web' if args.web else 'native') if args.view else None)
    except KeyboardInterrupt:
        return 0                      # stopped while starting: nothing was opened yet
