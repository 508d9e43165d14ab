"""Entry point of the ``drill-twin`` command."""
from __future__ import annotations

import argparse
import sys

from drill_twin import __version__
from drill_twin.cli import modes, montecarlo, simulate
from drill_twin.cli.common import report_and_exit_code

SUBCOMMANDS = (modes, simulate, montecarlo)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='drill-twin',
        description='Digital twin of a drill string (Ritto, Soize & Sampaio 2009).')
    parser.add_argument('--version', action='version', version=f'drill_twin {__version__}')
    subparsers = parser.add_subparsers(metavar='COMMAND', required=True)
    for module in SUBCOMMANDS:
        module.add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt:
        return 130
    except Exception as error:  # noqa: BLE001 - user errors become one line, others re-raise
        return report_and_exit_code(error)


if __name__ == '__main__':
    sys.exit(main())
