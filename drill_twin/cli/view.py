"""``drill-twin view``: open a twin log in the rerun viewer with the shipped layout."""
from __future__ import annotations

import argparse

from drill_twin.cli.log_path import existing_log, HELP


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'view', help='open a twin log in rerun',
        description='Open a twin log (its bag directory or one MCAP file) in the rerun '
                    'viewer with its blueprint (bit state, WOB/TOB, vibration, ensemble '
                    'bounds, contacts, KPIs), or write a self-contained .rrd with --rrd.')
    parser.add_argument('log', metavar='LOG', help=HELP)
    parser.add_argument('--rrd', metavar='OUT', help='write OUT.rrd instead of opening a viewer')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    path = existing_log(args.log)
    from drill_twin.recording import rerun_view

    if args.rrd:
        out = rerun_view.save_rrd(path, args.rrd)
        print(f'wrote {out}')
        return 0
    process = rerun_view.open_viewer(path)
    return process.wait()
