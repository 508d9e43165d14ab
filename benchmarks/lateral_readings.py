"""Tabulate `drill-twin simulate` runs against the paper's lateral figures.

    python benchmarks/lateral_readings.py RUN.npz [RUN.npz ...] [--window 200 250] [--period 5]

For each run (the npz of ``drill-twin simulate --out``): the radial displacement at 700 m
over the window (largest, mean, share of the time at or above 2 cm, and its amplitude: the
smallest over consecutive spans of ``--period`` seconds, about one stick-slip cycle, of the
largest displacement in each; the paper's Figs. 11 and 14 show a sustained few centimetres
of a signed displacement that crosses zero) and its spectrum (shares of the energy of the radial
displacement below 0.1 Hz, 0.1-0.5 Hz and above 0.5 Hz, after removing the mean), wall
contact (impact episodes and lift-off episodes in the window and over the run, the largest
wall force), the bit speed (lowest: the paper's Figs. 10 and 13 fall to about zero), the
torque on bit (Fig. 9's range) and the top torque. docs/LATERAL.md, "Eq. 15 as printed",
holds its table for the readings of Eq. 15.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def row(path: Path, start: float, stop: float, period: float = 5.0) -> dict:
    d = np.load(path, allow_pickle=True)
    t = d['time_s']
    window = (t >= start - 1e-9) & (t <= stop + 1e-9)
    radial = d['x700m_radial_m'][window]
    centred = radial - radial.mean()
    spectrum = np.abs(np.fft.rfft(centred)) ** 2
    frequency = np.fft.rfftfreq(centred.size, d=float(np.median(np.diff(t))))
    total = spectrum.sum() or 1.0
    impacts = d['impacts_so_far']
    lift_offs = d['lift_offs_so_far']
    times = t[window]
    spans = np.arange(start, stop - period + 1e-9, period)
    amplitude = min(radial[(times >= a - 1e-9) & (times < a + period - 1e-9)].max()
                    for a in spans) if spans.size else float('nan')
    first = int(np.argmax(window))
    last = len(t) - 1 - int(np.argmax(window[::-1]))
    return {
        'run': path.stem,
        'radial_max_cm': 100 * radial.max(), 'radial_mean_cm': 100 * radial.mean(),
        'at_least_2cm': float(np.mean(radial >= 0.02)),
        'amplitude_min_cm': 100 * amplitude,
        'below_0.1Hz': spectrum[frequency < 0.1].sum() / total,
        '0.1-0.5Hz': spectrum[(frequency >= 0.1) & (frequency <= 0.5)].sum() / total,
        'above_0.5Hz': spectrum[frequency > 0.5].sum() / total,
        'impacts_window': int(impacts[last] - impacts[first]), 'impacts_run': int(impacts[-1]),
        'lift_offs_window': int(lift_offs[last] - lift_offs[first]),
        'lift_offs_run': int(lift_offs[-1]),
        'wall_force_max_kn': 1e-3 * float(np.max(d['max_contact_force_n'])),
        'bit_speed_min': float(d['bit_speed_rad_per_s'][window].min()),
        'bit_speed_max': float(d['bit_speed_rad_per_s'][window].max()),
        'tob_mean_knm': 1e-3 * float(d['torque_on_bit_nm'][window].mean()),
        'tob_min_knm': 1e-3 * float(d['torque_on_bit_nm'][window].min()),
        'tob_max_knm': 1e-3 * float(d['torque_on_bit_nm'][window].max()),
        'top_torque_min_knm': 1e-3 * float(d['top_torque_nm'][window].min()),
        'top_torque_max_knm': 1e-3 * float(d['top_torque_nm'][window].max()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('runs', type=Path, nargs='+')
    parser.add_argument('--window', type=float, nargs=2, default=(200.0, 250.0))
    parser.add_argument('--period', type=float, default=5.0,
                        help='span of the amplitude (s, default 5: a stick-slip cycle)')
    args = parser.parse_args()
    rows = [row(p, *args.window, args.period) for p in args.runs]
    for key in rows[0]:
        values = [r[key] for r in rows]
        text = [v if isinstance(v, str) else (f'{v:d}' if isinstance(v, int) else f'{v:.4g}')
                for v in values]
        print(f'{key:>20} ' + ' '.join(f'{v:>18}' for v in text))


if __name__ == '__main__':
    main()
