"""``drill-twin montecarlo``: the stochastic study of the paper's Sect. 3-4."""
from __future__ import annotations

import argparse
from dataclasses import replace
import os
from pathlib import Path

from drill_twin.cli.common import (UsageError, add_config_arguments, blamed, config_from_args,
                                   positive_seconds, positive_window, preflight_or_refuse,
                                   require_memory)
from drill_twin.cli.output_paths import output_directory
from drill_twin.cli.progress import ProgressBar

WORKERS_PER_CORE_MAX = 4
"""--workers beyond four processes per core only compete for the cores (and each holds its
own copy of the model)."""


def workers_max() -> int:
    return WORKERS_PER_CORE_MAX * (os.cpu_count() or 1)


def window_records(config, window_s: float) -> int:
    """Instants every realization keeps: the stationary window at the record interval."""
    return int(window_s / config.output.record_interval_s) + 1


def study_bytes(samples: int, records: int) -> float:
    """
    Memory of a study's series.

    5 quantities per realization and instant, held by the chunks, the gathered arrays and the
    statistics' sorted copies (three times).
    """
    from drill_twin.uncertainty.montecarlo import QUANTITIES

    return 3.0 * 8 * len(QUANTITIES) * samples * records


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'montecarlo', help='Monte Carlo study of the uncertain bit-rock law',
        description='Integrate N realizations of the random bit-rock law (dispersion delta) and '
                    'the mean model, then write statistics, envelopes, the convergence '
                    'function of Eq. 54 and figures like the paper\'s Figs. 7-16 into DIR.')
    add_config_arguments(parser)
    parser.add_argument('--delta', type=float, required=True, help='dispersion of the germ')
    parser.add_argument('--samples', type=int, required=True, metavar='N',
                        help='number of realizations')
    parser.add_argument('--duration', type=float, required=True, metavar='S',
                        help='simulated time of every realization (s)')
    parser.add_argument('--out', required=True, metavar='DIR', help='output directory')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the study: realization j uses the stream (seed, j) '
                             '(default 0; recorded in summary.json)')
    parser.add_argument('--window', type=float, default=50.0, metavar='S',
                        help='stationary window at the end of each run (s, default 50)')
    parser.add_argument('--batch-size', type=int, metavar='B',
                        help='realizations integrated together (default: chunks of equal '
                             'size, at most 64, as many as a multiple of the workers)')
    parser.add_argument('--station', type=float, default=700.0, metavar='X',
                        help='depth of the radial-displacement statistics (m, default 700; '
                             'must be one of output.stations_m)')
    parser.add_argument('--workers', type=int, metavar='W',
                        help='local processes (default: all cores)')
    parser.add_argument('--scheduler', metavar='ADDRESS',
                        help='run on the Dask distributed scheduler at ADDRESS instead')
    parser.add_argument('--no-figures', action='store_true', help='skip the PNG figures')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    positive_seconds('--duration', args.duration)
    positive_window(args.window)
    if args.workers is not None and not 1 <= args.workers <= workers_max():
        raise UsageError(f'--workers: must lie in 1 ... {workers_max()} (four per core of this '
                         f'machine: more only compete for the cores), got {args.workers}')
    output_directory('--out', args.out)
    window = min(args.window, args.duration)
    config = config_from_args(args)
    from drill_twin.integrator.simulator import SimulationDiverged
    from drill_twin.uncertainty.executors import make_executor
    from drill_twin.uncertainty.montecarlo import StudySpec, default_batch_size
    from drill_twin.uncertainty.study import run_study
    from drill_twin.uncertainty.study_io import summary, write_study
    from drill_twin.viz.montecarlo_figures import plot_study

    try:
        spec = StudySpec(dispersion=args.delta, samples=args.samples, duration_s=args.duration,
                         seed=args.seed, window_s=window,
                         batch_size=1 if args.batch_size is None else args.batch_size,
                         station_m=args.station)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if not any(abs(x - args.station) < 1e-6 for x in config.output.stations_m):
        raise UsageError(f'--station: {args.station} m is not one of output.stations_m '
                         f'{list(config.output.stations_m)}')
    records = window_records(config, window)
    require_memory('--samples, --window', f'{args.samples} realizations of {records} records '
                   f'(--window {window:g} s)', study_bytes(args.samples, records))
    preflight_or_refuse(config, args.overrides)
    executor = make_executor(args.workers, args.scheduler)
    try:
        if args.batch_size is None:
            spec = replace(spec, batch_size=default_batch_size(spec.samples, executor.workers))
        result = run_study(config, spec, executor, progress=ProgressBar('montecarlo'))
    except SimulationDiverged as error:
        # Only the mean model's divergence ends a study (realizations are reported).
        raise blamed(config, args.overrides,
                     f'the mean model cannot be integrated: {error}') from None
    finally:
        executor.close()
    write_study(result, args.out)
    if not args.no_figures:
        plot_study(result, Path(args.out))
    s = summary(result)
    cov = s['coefficient_of_variation']
    print(f'{s["completed_realizations"]} realizations (delta = {spec.dispersion:g}, seed '
          f'{spec.seed}) in {s["wall_time_s"]:.1f} s on {s["workers"]} worker(s), batches of '
          f'{spec.batch_size}; '
          f'statistics over the last {spec.window_s:g} s')
    print('  coefficients of variation: ' + ', '.join(f'{k} {v:.3g}' for k, v in cov.items()))
    print(f'  realizations with impacts {s["realizations_with_impacts"]}, with lift-off '
          f'{s["realizations_with_lift_off"]}; failed {len(s["failed_realizations"])}')
    print(f'  written to {args.out}')
    return 0
