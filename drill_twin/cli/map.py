"""``drill-twin map``: the stick-slip map over top-drive speed x weight on bit."""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import numpy as np

from drill_twin.cli.common import (UsageError, add_config_arguments, build_model_or_refuse,
                                   config_from_args, positive_seconds, require_memory)
from drill_twin.cli.output_paths import output_directory
from drill_twin.cli.progress import ProgressBar
from drill_twin.config.checks import ConfigValueError

SPEC_OPTIONS = {'speeds_rad_per_s': '--speeds', 'weights_on_bit_n': '--weights-on-bit',
                'duration': '--duration', 'window': '--window', 'perturbation': '--perturbation',
                'start': '--start', 'seed': '--seed'}
"""MapSpec's field names -> the options that set them (for one-line errors)."""
DEFAULT_WINDOW_S = 20.0
VALUE_BYTES = 128
"""Memory of one value of a list or range while it is parsed: numpy's, Python's float, the
list's and the duplicate check's entries."""
POINT_BYTES = 4096
"""Memory of one grid point in this process while the map runs: the executor's pending task
(about 2 kB) and the point's row of results (about 1.4 kB), as measured, rounded up."""
SERIES_COUNT = 4
"""Series a running point keeps over the window, one float each per step (bit speed, hole
depth, WOB, TOB)."""
VALUES_HELP = ('a comma-separated list of values and ranges START:STOP:COUNT (COUNT evenly '
               'spaced values, both ends included), e.g. 2:20:10 or 5,10,15 or 2:8:4,12,20')


def parse_values(option: str, text: str) -> tuple[float, ...]:
    """Values of a list/range argument (see VALUES_HELP), sorted; UsageError if malformed."""
    values = []
    for item in text.split(','):
        item = item.strip()
        parts = item.split(':')
        try:
            if len(parts) == 1:
                values.append(float(item))
            elif len(parts) == 3:
                start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
                if count < 2:
                    raise UsageError(f'{option}: {item!r}: a range needs COUNT >= 2')
                require_memory(option, f'{item!r}: {count} values', count * VALUE_BYTES)
                values.extend(np.linspace(start, stop, count).tolist())
            else:
                raise ValueError
        except ValueError:
            raise UsageError(f'{option}: {item!r} is neither a number nor START:STOP:COUNT '
                             f'(e.g. 2:20:10 or 5,10,15)') from None
    if not all(math.isfinite(v) for v in values):
        raise UsageError(f'{option}: values must be finite, got {text!r}')
    if len(set(values)) != len(values):
        raise UsageError(f'{option}: repeated values in {text!r}')
    return tuple(sorted(values))


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'map', help='stick-slip map over top-drive speed x weight on bit',
        description='Run the mean model at every point of a grid of top-drive speed x weight '
                    'on bit (set through the hook load) and write map.csv (statistics over '
                    'the last --window seconds and the linear stability of steady drilling '
                    'per point), linear_stability.csv, map.json, config.yaml and the heat '
                    'map map.png into DIR (docs/MAP.md).')
    add_config_arguments(parser)
    parser.add_argument('--speeds', required=True, metavar='LIST',
                        help='top-drive speeds in rad/s: ' + VALUES_HELP)
    parser.add_argument('--weights-on-bit', required=True, metavar='LIST',
                        help='static weights on bit in N, positive in compression: '
                             + VALUES_HELP + ' (e.g. 50e3:250e3:5)')
    parser.add_argument('--duration', type=float, default=80.0, metavar='S',
                        help='simulated time per point (s, default 80)')
    parser.add_argument('--window', type=float, default=None, metavar='S',
                        help='window at the end of each run for the statistics (s, default 20 '
                             'or the whole run if shorter)')
    parser.add_argument('--start', choices=('steady', 'configured'), default='steady',
                        help='initial state: steady drilling at the point with the bit speed '
                             'perturbed (default), or the configuration\'s (untwisted string)')
    parser.add_argument('--perturbation', type=float, default=0.5, metavar='RAD_PER_S',
                        help='bit-speed perturbation of the steady start (rad/s, default 0.5)')
    parser.add_argument('--seed', type=int, default=None,
                        help='draw the perturbation\'s shape over the torsional modes from the '
                             'stream (seed, point index) instead of the first torsional mode')
    group = parser.add_mutually_exclusive_group()
    group.add_argument('--workers', type=int, metavar='N',
                       help='local processes (default: all cores)')
    group.add_argument('--dask', '--scheduler', dest='dask', metavar='ADDRESS',
                       help='run on the Dask distributed scheduler at ADDRESS instead')
    parser.add_argument('--out', required=True, metavar='DIR', help='output directory')
    parser.add_argument('--no-figure', action='store_true', help='skip map.png')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    speeds = parse_values('--speeds', args.speeds)
    weights = parse_values('--weights-on-bit', args.weights_on_bit)
    positive_seconds('--duration', args.duration)
    if args.workers is not None and args.workers < 1:
        raise UsageError(f'--workers: must be at least 1, got {args.workers}')
    output_directory('--out', args.out)
    points = len(speeds) * len(weights)
    require_memory('--speeds, --weights-on-bit', f'a grid of {len(speeds)} x {len(weights)} '
                   f'= {points:.4g} points', points * POINT_BYTES)
    config = config_from_args(args)
    window = args.window if args.window is not None else min(DEFAULT_WINDOW_S, args.duration)
    from drill_twin.simulation.stick_slip_map import MapPointError, check_points, MapSpec, run_map
    from drill_twin.simulation.stick_slip_map_io import write_map
    from drill_twin.viz.map_figure import plot_map
    from drill_twin.uncertainty.executors import make_executor

    try:
        spec = MapSpec(speeds_rad_per_s=speeds, weights_on_bit_n=weights,
                       duration_s=args.duration, window_s=window,
                       perturbation_rad_per_s=args.perturbation, start=args.start,
                       seed=args.seed)
    except ValueError as error:
        raise _spec_error(error) from None
    _require_series_memory(config, spec, args.workers)
    build_model_or_refuse(config, args.overrides)
    try:
        check_points(config, spec)
    except MapPointError as error:
        raise _spec_error(error) from None
    executor = make_executor(args.workers, args.dask)
    try:
        result = run_map(config, spec, executor, progress=ProgressBar('map'))
    except ConfigValueError as error:       # a point's own check, from a worker: one line
        raise UsageError(f'a point of the map: {error}') from None
    finally:
        executor.close()
    write_map(result, args.out)
    if not args.no_figure:
        plot_map(result, Path(args.out) / 'map.png')
    print(_text(result, args.out))
    return 0


def _spec_error(error: ValueError) -> UsageError:
    """Return a MapSpec's error ('field: problem') as one line naming the option."""
    key, _, rest = str(error).partition(':')
    return UsageError(f'{SPEC_OPTIONS.get(key, key)}:{rest}')


def _require_series_memory(config, spec, workers: int | None) -> None:
    """Refuse a window whose series the running points cannot hold (UsageError)."""
    steps = spec.window_s / config.integration.time_step_s + 1
    running = min(workers or os.cpu_count() or 1, spec.shape[0] * spec.shape[1])
    require_memory('--window', f'{spec.window_s:g} s at {config.integration.time_step_s:g} s '
                   f'per step in {running} running point(s)',
                   8.0 * SERIES_COUNT * steps * running)


def _text(result, out) -> str:
    from drill_twin.simulation.stick_slip_map import RAD_PER_S_TO_RPM

    spec = result.spec
    lines = [f'{len(result.rows)} points ({spec.shape[1]} speeds x {spec.shape[0]} WOB), '
             f'{spec.duration_s:g} s each, statistics over the last {spec.window_s:g} s, in '
             f'{result.wall_s:.1f} s on {result.workers} worker(s)',
             '  speed rad/s (rpm)   WOB kN     SSI  bit speed min/mean   ROP mm/s  '
             'growth 1/s  freq Hz']
    for row in result.rows:
        speed = row['top_drive_speed_rad_per_s']
        head = (f'  {speed:6.2f} ({speed * RAD_PER_S_TO_RPM:5.1f})  '
                f'{row["weight_on_bit_n"] * 1e-3:8.1f}  ')
        if row['failed']:
            body = f'FAILED at t = {row["failed_time_s"]:.2f} s: {row["error"]}'
        else:
            body = (f'{row["stick_slip_severity"]:6.3f}  {row["bit_speed_min_rad_per_s"]:7.2f} / '
                    f'{row["bit_speed_mean_rad_per_s"]:6.2f}   {row["rop_m_per_s"] * 1e3:8.3f}')
        lines.append(head + body + f'  {row["growth_rate_per_s"]:+9.4f}  '
                                   f'{row["frequency_hz"]:6.3f}')
    failed = sum(row['failed'] for row in result.rows)
    lines.append(f'  failed points: {failed}; written to {out}')
    return '\n'.join(lines)
