"""Options and error handling shared by the subcommands."""
from __future__ import annotations

import argparse
import sys

from drill_twin.config import ConfigError, DrillStringConfig, load_config

EXIT_USAGE = 2


def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    """--config FILE and repeatable --set key=value."""
    parser.add_argument('--config', metavar='FILE',
                        help='YAML file overriding any keys of the built-in defaults '
                             '(config/ritto2009.yaml)')
    parser.add_argument('--set', dest='overrides', metavar='KEY=VALUE', action='append',
                        default=[], help='override one value, e.g. '
                        '--set sections.drill_pipe.elements=40 (repeatable)')


def config_from_args(args: argparse.Namespace) -> DrillStringConfig:
    """Load the configuration named by --config/--set (raises ConfigError)."""
    return load_config(args.config, args.overrides)


class UsageError(Exception):
    """A bad command-line value: reported on one line, exit status 2."""


def report_and_exit_code(error: Exception) -> int:
    """Print a one-line message for a user error and return the exit status."""
    if isinstance(error, (ConfigError, UsageError)):
        print(f'drill-twin: {error}', file=sys.stderr)
        return EXIT_USAGE
    raise error
