"""``drill-twin view``: open a twin log in the rerun viewer with the shipped layout."""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import subprocess
import sys

from drill_twin.cli.common import EXIT_USAGE, UsageError
from drill_twin.cli.output_paths import output_file
from drill_twin.viz.rerun_entities import TABS


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'view', help='open a twin log in rerun',
        description='Open a log of the twin in the rerun viewer: tabs for the bit, the '
                    'driller, the lateral motion (orbits in the borehole, contact forces '
                    'along the string), the ensemble (mean and 95 %% band) and diagnostics, '
                    'on the run time in seconds. The viewer listens on 127.0.0.1 only. '
                    'Without a display, write a self-contained .rrd with --rrd or serve '
                    "rerun's web viewer on localhost with --web.")
    parser.add_argument('log', nargs='+', metavar='LOG',
                        help='a .mcap log, a bag directory, or the split files of one run')
    parser.add_argument('--tab', choices=TABS, default=None,
                        help=f'the tab shown first (default {TABS[0]}; for the estimate of '
                             '`drill-twin assimilate`, EST.mcap: ensemble)')
    parser.add_argument('--rrd', metavar='OUT', help='write OUT (.rrd: data and layout) '
                        'instead of opening a viewer')
    parser.add_argument('--web', action='store_true',
                        help="serve rerun's web viewer on http://127.0.0.1:WEB_PORT")
    parser.add_argument('--port', type=int, default=9876,
                        help="the viewer's gRPC port on 127.0.0.1 (default %(default)s)")
    parser.add_argument('--web-port', type=int, default=9090,
                        help='the web viewer\'s HTTP port on 127.0.0.1 (default %(default)s)')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from drill_twin.viz import rerun_view, run_columns

    for port, option in ((args.port, '--port'), (args.web_port, '--web-port')):
        if not 0 < port < 65536:
            raise UsageError(f'{option}: {port} is not a TCP port (1-65535)')
    for item in args.log:
        if not Path(item).exists():
            raise UsageError(f'{item}: no such file or directory')
    try:
        files = run_columns.log_files(args.log)
    except run_columns.LogNotFound as error:
        raise UsageError(str(error)) from None
    output_file('--rrd', args.rrd, ('.rrd',))
    if not args.rrd and not args.web and not rerun_view.has_display():
        print(f'drill-twin: view: {rerun_view.NO_DISPLAY_HINT}', file=sys.stderr)
        return EXIT_USAGE
    if args.rrd:
        out = rerun_view.save_rrd(files, args.rrd, active_tab=args.tab)
        print(f'wrote {out}')
        if not args.web:
            return 0
        process = _start(rerun_view, out, args)
    else:
        print(f'reading {files[0]}' + (f' and {len(files) - 1} more' if len(files) > 1
                                       else ''), file=sys.stderr)
        process = rerun_view.open_viewer(files, active_tab=args.tab, web=args.web,
                                         port=args.port, web_port=args.web_port)
    if args.web:
        print(f'web viewer: {rerun_view.web_url(args.port, args.web_port)} (Ctrl-C stops it)',
              file=sys.stderr)
    try:
        return process.wait()
    except KeyboardInterrupt:
        process.terminate()
        process.wait()
        return 0


def _start(rerun_view, rrd: os.PathLike, args: argparse.Namespace):
    return subprocess.Popen(rerun_view.viewer_command(rrd, web=True, port=args.port,
                                                      web_port=args.web_port))
