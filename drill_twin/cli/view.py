"""``drill-twin view``: open a twin log in the rerun viewer with the shipped layout."""
from __future__ import annotations

import argparse
from pathlib import Path

from drill_twin.cli.common import UsageError


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'view', help='open a twin log in rerun',
        description='Open an MCAP log of the twin in the rerun viewer with its blueprint (bit '
                    'state, WOB/TOB, vibration, ensemble bounds, contacts, KPIs), or write a '
                    'self-contained .rrd with --rrd.')
    parser.add_argument('log', metavar='LOG.mcap')
    parser.add_argument('--rrd', metavar='OUT', help='write OUT.rrd instead of opening a viewer')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    path = Path(args.log)
    if not path.is_file():
        raise UsageError(f'{path}: no such file')
    from drill_twin.recording import rerun_view

    if args.rrd:
        out = rerun_view.save_rrd(path, args.rrd)
        print(f'wrote {out}')
        return 0
    process = rerun_view.open_viewer(path)
    return process.wait()
