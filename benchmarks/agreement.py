"""Do two versions of the code compute the same run? Record with one, compare with the other.

    PYTHONPATH=<version A> python benchmarks/agreement.py record a.npz [--duration 20]
    PYTHONPATH=<version B> python benchmarks/agreement.py record b.npz [--duration 20]
    python benchmarks/agreement.py compare a.npz b.npz

``record`` runs the default (paper) model for ``--duration`` seconds, the mean model or, with
``--members N --delta D``, N realizations of the random bit-rock law (germs of the study
with seed 0), and saves the bit speed, ROP, WOB, TOB and the displacement (u, v, w) at the
700 m station at every recorded instant. ``compare`` prints, per quantity, the largest
difference relative to the quantity's largest magnitude over the run, and the largest
pointwise relative difference where the value is above 1e-6 of that magnitude.
"""
from __future__ import annotations

import argparse

import numpy as np

CHANNELS = ('bit_speed_rad_per_s', 'rop_m_per_s', 'weight_on_bit_n', 'torque_on_bit_nm')
STATION_M = 700.0


def record(path: str, duration_s: float, members: int, delta: float) -> None:
    from drill_twin.config import load_config
    from drill_twin.simulation.run import run_simulation

    config = load_config()
    germs = None
    if members > 1 or delta > 0:
        from drill_twin.uncertainty.germ import germs_for_realizations
        germs = germs_for_realizations(delta, 0, tuple(range(members)))
    result = run_simulation(config, duration_s, members=members, germs=germs)
    station = int(np.argmin(np.abs(result.stations_m - STATION_M)))
    data = {name: result.channels[name] for name in CHANNELS}
    data['station_700m_displacement_m'] = result.station_displacement_m[:, station]
    np.savez(path, time_s=result.time_s, **data)
    print(f'{path}: {members} member(s), {duration_s:g} s, wall {result.wall_time_s:.1f} s')


def compare(first: str, second: str) -> float:
    a, b = np.load(first), np.load(second)
    np.testing.assert_array_equal(a['time_s'], b['time_s'])
    worst = 0.0
    print(f'{"quantity":<30} {"max |a-b| / max |b|":>20} {"max pointwise rel.":>20}')
    for name in (*CHANNELS, 'station_700m_displacement_m'):
        x, y = a[name].astype(float), b[name].astype(float)
        scale = np.max(np.abs(y))
        relative = np.max(np.abs(x - y)) / scale
        big = np.abs(y) > 1e-6 * scale
        pointwise = np.max(np.abs(x - y)[big] / np.abs(y)[big])
        worst = max(worst, relative)
        print(f'{name:<30} {relative:>20.3e} {pointwise:>20.3e}')
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest='command', required=True)
    rec = sub.add_parser('record')
    rec.add_argument('path')
    rec.add_argument('--duration', type=float, default=20.0)
    rec.add_argument('--members', type=int, default=1)
    rec.add_argument('--delta', type=float, default=0.0)
    cmp = sub.add_parser('compare')
    cmp.add_argument('first')
    cmp.add_argument('second')
    args = parser.parse_args()
    if args.command == 'record':
        record(args.path, args.duration, args.members, args.delta)
    else:
        compare(args.first, args.second)


if __name__ == '__main__':
    main()
