"""Entry point of the ``drill-twin`` command."""
from __future__ import annotations

import argparse
import sys

from drill_twin.cli import blas_threads, startup_signals

if startup_signals.wanted(sys.argv):
    startup_signals.install()       # before the heavy imports below: SIGINT honoured at once
blas_threads.limit_to_one()         # before numpy is imported

from drill_twin import __version__  # noqa: E402
from drill_twin.cli import map as map_command  # noqa: E402
from drill_twin.cli import modes, montecarlo, recover, replay, simulate, twin, view  # noqa: E402
from drill_twin.cli import assimilate, rig  # noqa: E402
from drill_twin.cli.common import OneLineArgumentParser, report_and_exit_code  # noqa: E402

SUBCOMMANDS = (modes, simulate, montecarlo, map_command, twin, view, replay, recover, rig,
               assimilate)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineArgumentParser(
        prog='drill-twin',
        description='Digital twin of a drill string (Ritto, Soize & Sampaio 2009).')
    parser.add_argument('--version', action='version', version=f'drill_twin {__version__}')
    subparsers = parser.add_subparsers(metavar='COMMAND', required=True)
    for module in SUBCOMMANDS:
        module.add_parser(subparsers)
    return parser


def split_ros_arguments(argv: list[str]) -> tuple[list[str], list[str]]:
    """(own arguments, ROS arguments): ROS's run from --ros-args to an optional --."""
    if '--ros-args' not in argv:
        return argv, []
    start = argv.index('--ros-args')
    end = argv.index('--', start) if '--' in argv[start:] else len(argv)
    ros = argv[start + 1:end]
    return argv[:start] + argv[end + 1:], ['--ros-args'] + ros


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    argv, ros_args = split_ros_arguments(argv)
    args = build_parser().parse_args(argv)
    args.ros_args = ros_args
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt:
        return 130
    except Exception as error:  # noqa: BLE001 - user errors become one line, others re-raise
        return report_and_exit_code(error)


if __name__ == '__main__':
    sys.exit(main())
