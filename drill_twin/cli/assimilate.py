"""
``drill-twin assimilate``: the ensemble Kalman filter over a recorded rig log.

It writes EST.mcap, whose layout :mod:`~drill_twin.cli.rig_files` describes. It opens in
rerun with ``drill-twin view EST.mcap`` (or ``--rrd OUT``): the ensemble tab shows the estimated
bit speed, its 95 % band, the truth and the open loop, and the estimated parameters.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from drill_twin import interface as itf
from drill_twin.assimilation.settings import SENSOR_OF
from drill_twin.cli.common import UsageError, add_config_arguments, blamed, preflight_or_refuse
from drill_twin.cli.log_path import existing_log
from drill_twin.cli.output_paths import distinct, output_file
from drill_twin.cli.progress import ProgressBar
from drill_twin.cli.rig import add_assimilation_argument, split_settings

SUMMARY_KEYS = ('bit_speed_rms_error_rad_per_s', 'open_loop_bit_speed_rms_error_rad_per_s',
                'bit_speed_coverage_95')


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'assimilate', help='ensemble Kalman filter over a rig log',
        description='Run the twin\'s ensemble over LOG.mcap (rig measurements and commands, '
                    'e.g. from drill-twin rig) with an ensemble Kalman analysis of the '
                    'measurements (config/assimilation.yaml), beside the same ensemble in '
                    'open loop, and write the estimated bit state with 95 %% bounds.')
    parser.add_argument('log', metavar='LOG.mcap', help='the rig log')
    add_config_arguments(parser)
    add_assimilation_argument(parser)
    parser.add_argument('--out', required=True, metavar='EST.mcap', help='estimate to write')
    parser.add_argument('--members', type=int, metavar='N',
                        help='ensemble members (default: assimilation.filter.members)')
    parser.add_argument('--measurements', metavar='CHANNELS',
                        help='comma-separated channels the filter uses (default: '
                             'assimilation.filter.measurements), among top_speed, top_torque, '
                             'hook_load, block_position, bit_speed, torque_on_bit, '
                             'weight_on_bit')
    parser.add_argument('--summary', metavar='S.json',
                        help='write the scores against the log\'s truth (JSON)')
    parser.add_argument('--settle', type=float, default=0.0, metavar='S',
                        help='score only after this much of the log (s, default 0)')
    parser.add_argument('--no-analysis', action='store_true',
                        help='run no analysis (the filtered estimate is then open loop too)')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    existing_log(args.log)
    output_file('--out', args.out, ('.mcap',))
    output_file('--summary', args.summary)
    distinct({'LOG': args.log, '--out': args.out, '--summary': args.summary})
    if not (math.isfinite(args.settle) and args.settle >= 0):
        raise UsageError(f'--settle: must be >= 0 (seconds), got {args.settle}')
    extra = []
    if args.members is not None:
        if args.members < 2:
            raise UsageError(f'--members: must be >= 2, got {args.members}')
        extra.append(f'assimilation.filter.members={args.members}')
    if args.measurements is not None:
        names = [n.strip() for n in args.measurements.split(',') if n.strip()]
        for name in names:
            if name not in SENSOR_OF:
                raise UsageError(f'--measurements: unknown channel {name!r} (one of '
                                 f'{", ".join(SENSOR_OF)})')
        if not names:
            raise UsageError('--measurements: name at least one channel')
        extra.append('assimilation.filter.measurements=[' + ','.join(names) + ']')
    args.overrides = list(args.overrides) + extra
    config, settings = split_settings(args)
    from drill_twin.assimilation.offline import run_filter, summarise
    from drill_twin.cli.rig_files import read_rig_log, write_estimate
    from drill_twin.integrator.stepping import TwinStalled

    log = read_rig_log(args.log, settings)
    if args.summary and log.truth is None:
        raise UsageError(f'--summary: {args.log} holds no truth ({itf.RIG_TRUTH_BIT_STATE}) to '
                         'score against')
    if args.summary and args.settle >= log.duration_s:
        raise UsageError(f'--settle: {args.settle:g} s is not shorter than the log '
                         f'({log.duration_s:g} s)')
    checked = preflight_or_refuse(config, args.overrides)
    try:
        estimate = run_filter(config, settings, log, analyse_on=not args.no_analysis,
                              system=checked.system, progress=ProgressBar('assimilate'))
    except TwinStalled as error:
        raise blamed(config, args.overrides, f'the ensemble cannot be integrated: {error}'
                     ) from None
    write_estimate(args.out, estimate, log, settings.filter.bounds, args.log)
    text = f'assimilate: {log.duration_s:g} s of {args.log}, {settings.filter.members} members'
    if log.truth is not None:
        summary = summarise(estimate, log, args.settle, settings.filter.bounds)
        summary['members'] = settings.filter.members
        summary['measurements'] = list(settings.filter.measurements)
        if args.summary:
            Path(args.summary).write_text(json.dumps(summary, indent=2) + '\n')
        text += (f'; after {args.settle:g} s: bit speed RMS error '
                 f'{summary[SUMMARY_KEYS[0]]:.3f} rad/s (open loop '
                 f'{summary[SUMMARY_KEYS[1]]:.3f}), truth inside the 95 % bounds '
                 f'{100 * summary[SUMMARY_KEYS[2]]:.0f} % of the time')
    print(text)
    return 0
