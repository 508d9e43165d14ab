"""``drill-twin replay``: republish a twin log, or re-run the twin on its commands."""
from __future__ import annotations

import argparse

from drill_twin.cli.common import UsageError
from drill_twin.cli.log_path import existing_log, HELP
from drill_twin.cli.progress import ProgressBar


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'replay', help='republish a twin log, or re-simulate it',
        description='Republish the topics of a twin log (bag directory or MCAP file) with '
                    'their recorded timing (scaled by --rate), or with --resimulate re-run '
                    'the twin on the '
                    'recorded commands and seed and report how far its bit state is from '
                    'the recorded one (zero for the same version of drill_twin).')
    parser.add_argument('log', metavar='LOG', help=HELP)
    parser.add_argument('--rate', type=float, default=1.0, help='playback speed factor')
    parser.add_argument('--delay', type=float, default=1.0, metavar='S',
                        help='wait S seconds before publishing, for subscribers to discover '
                             'the publishers (default 1)')
    parser.add_argument('--resimulate', action='store_true',
                        help='re-run the twin instead of republishing')
    parser.add_argument('--tolerance', type=float, default=0.0,
                        help='with --resimulate: largest accepted difference (default 0: '
                             'identical); exit status 1 beyond it')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    path = existing_log(args.log)
    if not args.rate > 0:
        raise UsageError(f'--rate: must be positive, got {args.rate}')
    if args.resimulate:
        from drill_twin.recording.resimulate import resimulate

        try:
            result = resimulate(path, progress=ProgressBar('resimulate'))
        except ValueError as error:
            raise UsageError(str(error)) from None
        ensemble = result.ensemble_max_difference or {}
        worst = max([*result.max_difference.values(), *ensemble.values()], default=0.0)
        print(f'resimulated {path}: {result.compared} bit states compared, '
              f'{result.commands} commands replayed (log from drill_twin '
              f'{result.recorded_version})')
        for field, value in result.max_difference.items():
            print(f'  max |difference| {field:<18} {value:.3g}')
        if result.assimilated:
            print('the ensemble assimilated the rig\'s samples: only the mean model is '
                  'resimulated')
        if ensemble:
            print(f'{result.ensemble_compared} ensemble mean and bound states compared')
            for field, value in ensemble.items():
                print(f'  max |difference| {field:<18} {value:.3g}')
        print('identical' if result.identical else f'largest difference {worst:.3g}')
        return 0 if result.compared and worst <= args.tolerance else 1
    from drill_twin.ros.replay import replay

    if args.delay < 0:
        raise UsageError(f'--delay: must be >= 0, got {args.delay}')
    return replay(path, args.rate, ['drill-twin'] + list(getattr(args, 'ros_args', [])),
                  delay_s=args.delay)
