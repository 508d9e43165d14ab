"""Options and error handling shared by the subcommands."""
from __future__ import annotations

import argparse
import math
import os
import sys

from drill_twin.config import ConfigError, DrillStringConfig, load_config
from drill_twin.config.loader import source_of

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


class OneLineArgumentParser(argparse.ArgumentParser):
    """
    Parse like argparse, with errors of one line and exit status 2.

    argparse's parser whose errors (an option missing, a value of the wrong type) are one
    line and exit status 2, like every other bad input, instead of the usage and a line.
    """

    def error(self, message: str):
        self.exit(EXIT_USAGE, f'drill-twin: {message} (see {self.prog} --help)\n')


class UsageError(Exception):
    """A bad command-line value: reported on one line, exit status 2."""


def report_and_exit_code(error: Exception) -> int:
    """Print a one-line message for a user error and return the exit status."""
    if isinstance(error, (ConfigError, UsageError)):
        print(f'drill-twin: {error}', file=sys.stderr)
        return EXIT_USAGE
    raise error


# -- checks of the configuration beyond its schema ----------------------------------------------

def preflight_or_refuse(config: DrillStringConfig, overrides=(), short_run: bool = True):
    """
    Build the model and run :func:`drill_twin.analysis.preflight.preflight`.

    A refusal becomes a :class:`ConfigError` blamed on ``--set`` or the file (returns the
    ``PreflightResult``).
    """
    from drill_twin.analysis.preflight import SHORT_RUN_S, PreflightError, preflight

    try:
        return preflight(config, SHORT_RUN_S if short_run else 0.0)
    except PreflightError as error:
        raise blamed(config, overrides, error.message, error.key, error.related) from None


def build_model_or_refuse(config: DrillStringConfig, overrides=()):
    """(model, basis) of ``config``; a numerical failure is a one-line :class:`ConfigError`."""
    from drill_twin.analysis.preflight import PreflightError, build_model

    try:
        model, basis, _ = build_model(config, reduced_system=False)
    except PreflightError as error:
        raise blamed(config, overrides, error.message, error.key, error.related) from None
    return model, basis


def blamed(config: DrillStringConfig, overrides, message: str, key: str = '',
           related=()) -> ConfigError:
    """
    Return a problem of ``config`` as a ConfigError naming where ``key`` came from.

    ``--set`` if an override set it (or one of the ``related`` keys), else the file; a problem
    of the configuration as a whole (no key) names the file and every override.
    """
    overrides = list(overrides)
    if key:
        keys = (key, *related)
        source = ('--set' if any(source_of(k, config, overrides) == '--set' for k in keys)
                  else config.source)
        return ConfigError(source, key, message)
    source = config.source
    if overrides:
        source += ' with ' + ' '.join(f'--set {item}' for item in overrides)
    return ConfigError(source, '', message)


# -- command-line values -------------------------------------------------------------------------

def positive_seconds(option: str, value: float) -> float:
    """Return a finite positive duration, else raise a UsageError naming ``option``."""
    if not (math.isfinite(value) and value > 0):
        raise UsageError(f'{option}: must be positive and finite (seconds), got {value}')
    return value


def positive_window(value: float) -> float:
    """Return a positive ``--window`` (s, the stationary window at the end of a run)."""
    if not value > 0:
        raise UsageError(f'--window: must be positive, got {value}')
    return value


def available_memory_bytes() -> int:
    """
    Memory this process may still take.

    MemAvailable of /proc/meminfo (Linux), else the free physical pages.
    """
    try:
        with open('/proc/meminfo') as handle:
            for line in handle:
                if line.startswith('MemAvailable:'):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf('SC_AVPHYS_PAGES') * os.sysconf('SC_PAGE_SIZE')
    except (ValueError, OSError, AttributeError):
        return 1 << 62                                         # unknown: do not refuse


def require_memory(option: str, what: str, need_bytes: float) -> None:
    """Refuse (UsageError naming ``option``) when ``need_bytes`` exceed the memory available."""
    available = available_memory_bytes()
    if need_bytes > available:
        raise UsageError(f'{option}: {what} would need {_bytes(need_bytes)} of memory; '
                         f'{_bytes(available)} is available')


def _bytes(count: float) -> str:
    for unit, size in (('TiB', 1 << 40), ('GiB', 1 << 30), ('MiB', 1 << 20)):
        if count >= size:
            return f'{count / size:.3g} {unit}'
    return f'{count / 1024:.3g} KiB'
