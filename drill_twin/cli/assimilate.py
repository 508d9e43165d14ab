"""
``drill-twin assimilate``: the ensemble Kalman filter over a recorded rig log (issue 15).

EST.mcap holds, at the truth's instants (or at the analysis instants without a truth), in
model time from 0 (ns):

- /drill_twin/assimilation/bit_state/{mean,lower,upper}: the filter's bit speed (JointState
  'bit_rotation' velocity, rad/s): ensemble mean and 95 % bounds (assimilation.filter.bounds);
- /drill_twin/assimilation/open_loop/bit_state/{mean,lower,upper}: the same ensemble without
  analysis;
- /drill_twin/assimilation/germ/{mean,lower,upper}: the estimated bit-rock germ (std_msgs/
  Float64MultiArray [G11, G12, G22]) after each analysis, and with parameters 'law'
  /drill_twin/assimilation/law/{mean,lower,upper}: the factors of the law's a1 ... a5, and
  /drill_twin/assimilation/bias/{mean,lower,upper} the estimated sensor biases (SI, one
  dimension labelled with their channels) when a channel has ``bias_prior_std`` > 0;
- /diagnostics: per analysis the normalised innovation squared and its count of
  measurements (diagnostic_msgs/DiagnosticArray, name 'drill_twin: assimilation');
- the log's truth (/rig/truth/bit_state), when it has one.

It opens in rerun with ``drill-twin view EST.mcap`` (or ``--rrd OUT``): the ensemble tab shows the
estimated bit speed, its 95 % band, the truth and the open loop, and the estimated parameters.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from drill_twin import interface as itf
from drill_twin.cli.common import UsageError, add_config_arguments, blamed
from drill_twin.cli.progress import ProgressBar
from drill_twin.cli.rig import TRUTH_BIT, add_assimilation_argument, read_rig_log, split_settings

PREFIX = itf.ASSIMILATION_PREFIX
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
    if Path(args.out).suffix != '.mcap':
        raise UsageError(f'--out: {args.out}: use a .mcap file name')
    if not (math.isfinite(args.settle) and args.settle >= 0):
        raise UsageError(f'--settle: must be >= 0 (seconds), got {args.settle}')
    extra = []
    if args.members is not None:
        if args.members < 2:
            raise UsageError(f'--members: must be >= 2, got {args.members}')
        extra.append(f'assimilation.filter.members={args.members}')
    if args.measurements is not None:
        names = [n.strip() for n in args.measurements.split(',') if n.strip()]
        from drill_twin.assimilation.settings import SENSOR_OF
        for name in names:
            if name not in SENSOR_OF:
                raise UsageError(f'--measurements: unknown channel {name!r} (one of '
                                 f'{", ".join(SENSOR_OF)})')
        if not names:
            raise UsageError('--measurements: name at least one channel')
        extra.append('assimilation.filter.measurements=[' + ','.join(names) + ']')
    args.overrides = list(args.overrides) + extra
    config, settings = split_settings(args)
    log = read_rig_log(args.log, settings)
    if args.summary and log.truth is None:
        raise UsageError(f'--summary: {args.log} holds no truth ({TRUTH_BIT}) to score against')
    if args.summary and args.settle >= log.duration_s:
        raise UsageError(f'--settle: {args.settle:g} s is not shorter than the log '
                         f'({log.duration_s:g} s)')
    from drill_twin.assimilation.offline import run_filter, summarise
    from drill_twin.cli.common import preflight_or_refuse
    from drill_twin.integrator.stepping import TwinStalled

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


def write_estimate(path, estimate, log, method: str = 'student_t', log_path='') -> None:
    """EST.mcap (module docstring); ``log_path``: the rig log's, for the metadata record."""
    from drill_twin.recording.mcap_log import McapLog
    from drill_twin.recording.message_types import import_message_class

    joint_state = import_message_class('sensor_msgs/msg/JointState')
    array = import_message_class('std_msgs/msg/Float64MultiArray')
    dimension = import_message_class('std_msgs/msg/MultiArrayDimension')
    diag_array = import_message_class('diagnostic_msgs/msg/DiagnosticArray')
    diag_status = import_message_class('diagnostic_msgs/msg/DiagnosticStatus')
    key_value = import_message_class('diagnostic_msgs/msg/KeyValue')

    def stamp(message, t_ns):
        message.header.stamp.sec = t_ns // 1_000_000_000
        message.header.stamp.nanosec = t_ns % 1_000_000_000

    a = estimate.arrays()
    filtered, open_loop = estimate.bounds('filtered', method), estimate.bounds('open_loop', method)
    messages = []
    for k, time_s in enumerate(a['time_s']):
        t = int(round(time_s * 1e9))
        for prefix, values in ((itf.ASSIMILATION_BIT_STATE, filtered[k]),
                               (itf.ASSIMILATION_OPEN_LOOP_BIT_STATE, open_loop[k])):
            for column, name in enumerate(('mean', 'lower', 'upper')):
                message = joint_state()
                stamp(message, t)
                message.name = [itf.BIT_ROTATION]
                message.velocity = [float(values[column])]
                messages.append((t, f'{prefix}/{name}', message))
    for k, time_s in enumerate(a['analysis_time_s']):
        t = int(round(time_s * 1e9))
        for estimated in ('germ', 'law'):           # what the filter estimates (not NaN)
            if a[f'{estimated}_mean'].size and np.all(np.isfinite(a[f'{estimated}_mean'][k])):
                for name in ('mean', 'lower', 'upper'):
                    messages.append((t, f'{PREFIX}/{estimated}/{name}', array(
                        data=[float(v) for v in a[f'{estimated}_{name}'][k]])))
        if estimate.bias_channels:                  # labelled by channel, as the twin's
            for name in ('mean', 'lower', 'upper'):
                message = array(data=[float(v) for v in a[f'bias_{name}'][k]])
                message.layout.dim = [dimension(label=','.join(estimate.bias_channels),
                                                size=len(estimate.bias_channels),
                                                stride=len(estimate.bias_channels))]
                messages.append((t, f'{PREFIX}/bias/{name}', message))
        status = diag_status(level=b'\x00', name='drill_twin: assimilation',
                             message='analysis', hardware_id='drill_twin')
        status.values = [key_value(key='nis', value=f'{a["nis"][k]:.6g}'),
                         key_value(key='measurements', value=str(int(a['measurements'][k])))]
        message = diag_array()
        stamp(message, t)
        message.status = [status]
        messages.append((t, itf.DIAGNOSTICS, message))
    truth = log.truth
    if truth is not None:
        for k, time_s in enumerate(truth.time_s):
            t = int(round(time_s * 1e9))
            message = joint_state()
            stamp(message, t)
            message.name = [itf.BIT_AXIAL, itf.BIT_ROTATION]
            message.position = [float(truth.bit_depth_m[k]), float(truth.bit_angle_rad[k])]
            message.velocity = [float(truth.rop_m_per_s[k]), float(truth.bit_speed_rad_per_s[k])]
            message.effort = [float(truth.weight_on_bit_n[k]), float(truth.torque_on_bit_nm[k])]
            messages.append((t, TRUTH_BIT, message))
    messages.sort(key=lambda item: item[0])
    with McapLog(path) as out:
        out.add_metadata(itf.ESTIMATE_METADATA, {'clock_epoch_ns': '0', 'log': str(log_path)})
        for _, topic, message in messages:
            kind = type(message).__module__.split('.')[0] + '/msg/' + type(message).__name__
            out.add_topic(topic, kind)
            out.write(topic, message, _)
