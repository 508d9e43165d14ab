"""
``drill-twin rig``: the rig emulator.

The model as the truth, logged as a rig measures it: RIG.mcap, whose layout
:mod:`~drill_twin.cli.rig_files` describes.
"""
from __future__ import annotations

import argparse
import json

from drill_twin.assimilation.settings import load_assimilation, model_overrides, SENSOR_OF
from drill_twin.cli.common import (UsageError, add_config_arguments, blamed,
                                   positive_seconds, preflight_or_refuse, require_memory)
from drill_twin.cli.output_paths import output_file
from drill_twin.cli.progress import ProgressBar
from drill_twin.config import load_config
from drill_twin.config.loader import config_to_dict
from drill_twin.uncertainty.germ import germs_for_realizations, MAX_DISPERSION


SAMPLE_BYTES = 512
"""Memory of one sample of the rig log (a sensor's reading or a row of the truth) while the
truth runs and the log is written: the schedule's entry, the values as Python objects, then as
arrays and messages (about 270 bytes measured while running, doubled)."""


def log_size(settings, duration_s: float) -> tuple[float, float]:
    """Return (samples, bytes) of a rig log of ``duration_s``: every sensor's and the truth's."""
    rate_hz = settings.rig.truth_rate_hz + sum(getattr(settings.sensors, name).rate_hz
                                               for name in set(SENSOR_OF.values()))
    samples = duration_s * rate_hz
    return samples, samples * SAMPLE_BYTES


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'rig', help='rig emulator: a log of what a rig measures, with the truth',
        description='Run the model as the truth under a schedule of set-points (default: the '
                    'paper\'s operating point, then a speed and a hook-load change) and write '
                    'what a rig measures (noise, bias, sample rate, telemetry delay of '
                    'config/assimilation.yaml), the commands, and the true downhole state on '
                    'topics of its own, to an MCAP file.')
    add_config_arguments(parser)
    add_assimilation_argument(parser)
    parser.add_argument('--duration', type=float, default=90.0, metavar='S',
                        help='simulated time (s, default 90)')
    parser.add_argument('--out', required=True, metavar='RIG.mcap', help='the log to write')
    parser.add_argument('--germ-dispersion', type=float, default=0.0, metavar='DELTA',
                        help='draw the truth\'s bit-rock germ at this dispersion (default 0: '
                             'the mean law of the configuration)')
    parser.add_argument('--germ-seed', type=int, default=0, metavar='SEED',
                        help='seed of that germ (realization 0 of the stream SEED)')
    parser.set_defaults(run=run)


def add_assimilation_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--assimilation', metavar='FILE',
                        help='YAML file with an assimilation: section overriding '
                             'config/assimilation.yaml (also --set assimilation.KEY=VALUE)')


def split_settings(args):
    """(model config, assimilation settings) of --config/--assimilation/--set."""
    settings = load_assimilation(args.assimilation, args.overrides)
    args.overrides = model_overrides(args.overrides)
    return load_config(args.config, args.overrides), settings


def run(args: argparse.Namespace) -> int:
    positive_seconds('--duration', args.duration)
    output_file('--out', args.out, ('.mcap',))
    if not 0.0 <= args.germ_dispersion < MAX_DISPERSION:
        raise UsageError(f'--germ-dispersion: must be in [0, {MAX_DISPERSION:.4f}), got '
                         f'{args.germ_dispersion}')
    if args.germ_seed < 0:
        raise UsageError(f'--germ-seed: must be >= 0, got {args.germ_seed}')
    config, settings = split_settings(args)
    samples, need = log_size(settings, args.duration)
    require_memory('--duration', f'{args.duration:g} s of rig log ({samples:.3g} samples)', need)
    from drill_twin.assimilation.rig_emulator import run_rig
    from drill_twin.cli.rig_files import write_rig_log
    from drill_twin.integrator.stepping import TwinStalled

    checked = preflight_or_refuse(config, args.overrides)
    germ = None
    if args.germ_dispersion > 0:
        germ = germs_for_realizations(args.germ_dispersion, args.germ_seed, [0])[0]
    try:
        log = run_rig(config, settings, args.duration, germ=germ, system=checked.system,
                      progress=ProgressBar('rig'))
    except TwinStalled as error:
        raise blamed(config, args.overrides, f'the truth cannot be integrated: {error}') from None
    metadata = {'duration_s': repr(log.duration_s),
                'germ': json.dumps(None if germ is None else germ.tolist()),
                'config': json.dumps(config_to_dict(config)),
                'sensors': json.dumps({name: {'topic': getattr(settings.sensors, name).topic}
                                       for name in log.sensors}),
                'channel_topics': json.dumps(settings.scalar_topics())}
    write_rig_log(args.out, log, settings, metadata)
    truth = log.truth
    print(f'rig: {log.duration_s:g} s written to {args.out}: '
          + ', '.join(f'{name} {s.stamp_s.size} samples' for name, s in log.sensors.items())
          + f'; truth bit speed mean {truth.bit_speed_rad_per_s.mean():.3f} rad/s, '
          f'min {truth.bit_speed_rad_per_s.min():.3f}, max {truth.bit_speed_rad_per_s.max():.3f}')
    return 0
