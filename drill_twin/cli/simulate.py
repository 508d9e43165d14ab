"""``drill-twin simulate``: the deterministic mean model in time (paper Sect. 4)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from drill_twin.cli.common import (add_config_arguments, blamed, config_from_args,
                                   positive_seconds, positive_window, preflight_or_refuse,
                                   require_memory)
from drill_twin.cli.output_paths import distinct, output_file
from drill_twin.cli.progress import ProgressBar
from drill_twin.config.loader import config_to_dict


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'simulate', help='run the mean model in time',
        description='Integrate the non-linear mean model (Newmark on the reduced basis) at the '
                    'configured operating point (default: the paper\'s, 0.83 Hz at the top, '
                    'initial lateral deflection) and write its history, a JSON summary over '
                    'the stationary window and figures.')
    add_config_arguments(parser)
    parser.add_argument('--duration', type=float, required=True, metavar='S',
                        help='simulated time (s)')
    parser.add_argument('--window', type=float, default=50.0, metavar='S',
                        help='stationary window at the end of the run for the summary and '
                             'figures (s, default 50: the paper\'s 200-250 s)')
    parser.add_argument('--out', metavar='PATH',
                        help='write the history: .csv (header row) or .npz (named arrays)')
    parser.add_argument('--summary', metavar='FILE.json', help='write the JSON summary')
    parser.add_argument('--plot', metavar='FILE.png',
                        help='draw time histories and spectra (Figs. 8-11)')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    positive_seconds('--duration', args.duration)
    positive_window(args.window)
    output_file('--out', args.out, ('.csv', '.npz'))
    output_file('--summary', args.summary)
    output_file('--plot', args.plot, figure_suffixes() if args.plot else ())
    distinct({'--out': args.out, '--summary': args.summary, '--plot': args.plot})
    config = config_from_args(args)
    records, need = history_size(config, args.duration)
    require_memory('--duration', f'{args.duration:g} s recorded every '
                   f'{config.output.record_interval_s:g} s ({records:.3g} records)', need)
    checked = preflight_or_refuse(config, args.overrides)
    from drill_twin.integrator.simulator import SimulationDiverged
    from drill_twin.simulation.results_io import write_results
    from drill_twin.simulation.run import run_simulation
    from drill_twin.simulation.summary import summarize

    try:
        result = run_simulation(config, args.duration, system=checked.system,
                                progress=ProgressBar('simulate'))
    except SimulationDiverged as error:
        # Nothing but the configuration drives an offline run: it is to blame.
        raise blamed(config, args.overrides,
                     f'the run cannot be integrated: {error}') from None
    window = min(args.window, args.duration)
    summary = summarize(result, window, config.borehole.diameter_m)
    if args.out:
        write_results(result, args.out, metadata={'config': config_to_dict(config),
                                                  'summary': summary})
    if args.summary:
        Path(args.summary).write_text(json.dumps(summary, indent=2) + '\n')
    if args.plot:
        from drill_twin.viz.figures import plot_run
        clearance = (config.borehole.diameter_m - config.sections[0].outer_diameter_m) / 2
        plot_run(result, args.plot, window, clearance_m=clearance)
    print(_text(summary, args.duration, window))
    return 0


def figure_suffixes() -> tuple[str, ...]:
    """File name suffixes matplotlib writes figures in (.png, .pdf, .svg, ...)."""
    from matplotlib.backend_bases import FigureCanvasBase          # a second: --plot only

    kinds = sorted(FigureCanvasBase.get_supported_filetypes(), key=lambda k: (k != 'png', k))
    return tuple('.' + kind for kind in kinds)


def history_size(config, duration_s: float, members: int = 1) -> tuple[float, float]:
    """
    Return (records, bytes) of the history ``run_simulation`` keeps for ``duration_s``.

    The recorder's preallocated arrays and the result's copy of them.
    """
    from drill_twin.simulation.history import BIT_CHANNELS, SHARED_CHANNELS, STATION_FIELDS

    dt = config.integration.time_step_s
    every = max(1, round(config.output.record_interval_s / dt))
    records = duration_s / dt // every + 1
    stations = len(config.output.stations_m)
    per_member = 8 * (len(BIT_CHANNELS) + 2) + 4 * 8 * stations * len(STATION_FIELDS)
    per_record = 8 * (1 + len(SHARED_CHANNELS)) + members * per_member
    return records, 2.0 * records * per_record


def _text(summary: dict, duration: float, window: float) -> str:
    def line(label, key, scale, unit):
        s = summary[key]
        return (f'  {label:<16} mean {s["mean"] * scale:9.4g}  min {s["min"] * scale:9.4g}  '
                f'max {s["max"] * scale:9.4g} {unit}')
    return '\n'.join([
        f'mean model, {duration:g} s simulated; statistics over the last {window:g} s',
        line('ROP', 'rop_m_per_s', 1e3, 'mm/s'),
        line('bit speed', 'bit_speed_rad_per_s', 1.0, 'rad/s'),
        line('weight on bit', 'weight_on_bit_n', 1e-3, 'kN'),
        line('torque on bit', 'torque_on_bit_nm', 1e-3, 'kN m'),
        f'  stick-slip severity {summary["stick_slip_severity"]:.3f}, MSE '
        f'{summary["mse_pa"] / 1e6:.1f} MPa, impacts {summary["impact_count"]}, lift-offs '
        f'{summary["lift_off_count"]}',
        f'  real-time factor {summary["real_time_factor"]:.2f} '
        f'(time step {summary["time_step_s"] * 1e3:g} ms)'])
