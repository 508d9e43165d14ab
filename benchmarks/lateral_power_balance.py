"""Where the lateral modes' energy comes from, term by term, for a reading.

    python benchmarks/lateral_power_balance.py [--seconds 60] [--window S] [--config F]
                                               [--set KEY=VALUE ...]

Runs the mean model of the paper's point (any configuration through --config and --set) with
:class:`~drill_twin.analysis.power_balance.LateralEnergyBalance` and prints, every 10 s, the
lateral energy and the work each term has done on the lateral DOFs since the start (J):
damping, f_se, f_ke, the wall, the imbalance, the rotating damping, and the closure (zero up to
the iteration error). A term with positive work feeds the lateral motion from the axial and
torsional motion (the top drive in the end).

With ``--window S`` it also cuts the last S seconds into stick-slip cycles (from one upward
crossing of the top-drive speed by the bit speed to the next) and prints, per cycle and as the
mean over the cycles, the change of the lateral energy and each term's work in that cycle,
with what the reading costs elsewhere over the same window: the range of the bit speed, the
torque on bit and the top torque (the paper's Fig. 9 and 10), and the 700 m station's radial
displacement (its Fig. 11). The top drive's work per cycle is printed beside it: the only
source of energy. docs/LATERAL.md, "What feeds the lateral modes", tabulates it per reading.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from threadpoolctl import threadpool_limits

from drill_twin.config import load_config
from drill_twin.analysis.power_balance import TERMS, LateralEnergyBalance
from drill_twin.integrator.simulator import Simulator

STATION_M = 700.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=60.0)
    parser.add_argument('--window', type=float, default=0.0,
                        help='per-cycle balance over the last S seconds (0: none)')
    parser.add_argument('--config', default=None)
    parser.add_argument('--set', dest='overrides', action='append', default=[])
    args = parser.parse_args()
    config = load_config(args.config, args.overrides)
    start = time.perf_counter()
    with threadpool_limits(limits=1, user_api='blas'):
        simulator = Simulator(config)
        stations = [s.x_m for s in simulator.system.stations]
        station = int(np.argmin(np.abs(np.array(stations) - STATION_M)))
        balance = LateralEnergyBalance(simulator)
        print(f'{"t (s)":>6} {"E_lat":>10} ' + ' '.join(f'{t:>16}' for t in TERMS)
              + f' {"closure":>10}')
        steps = int(round(args.seconds / simulator.dt))
        every = int(round(10.0 / simulator.dt))
        first_window_step = steps - int(round(args.window / simulator.dt))
        rows, top_work = [], 0.0
        for step in range(1, steps + 1):
            simulator.step()
            balance.update()
            if args.window > 0 and step >= first_window_step:
                o = simulator.observe(detailed=1)
                top_speed = float(simulator.state.top_speed_rad_per_s)
                top_work += float(o.top_torque_nm[0]) * top_speed * simulator.dt
                radial = float(np.hypot(*o.station_displacement_m[0, station, 1:]))
                rows.append((simulator.time_s, float(o.speed_rad_per_s[0]), top_speed,
                             float(o.torque_on_bit_nm[0]), float(o.top_torque_nm[0]), radial,
                             top_work, float(balance.energy_j()[0]), float(balance.closure_j()[0]),
                             *(float(balance.work_j[t][0]) for t in TERMS)))
            if step % every == 0 or step == steps:
                work = balance.work_j
                print(f'{simulator.time_s:6.1f} {balance.energy_j()[0]:10.4g} '
                      + ' '.join(f'{work[t][0]:16.5g}' for t in TERMS)
                      + f' {balance.closure_j()[0]:10.3g}', flush=True)
    print(f'initial lateral energy {balance.energy_at_start_j[0]:.4g} J; '
          f'wall {time.perf_counter() - start:.0f} s')
    if rows:
        _cycles(np.array(rows), stations[station])


def _cycles(rows: np.ndarray, station_m: float) -> None:
    """Print the per-cycle balance of the window's rows (columns as stored in main)."""
    t, omega, top = rows[:, 0], rows[:, 1], rows[:, 2]
    above = omega > top
    starts = np.flatnonzero(above[1:] & ~above[:-1]) + 1          # upward crossings
    print(f'\nwindow {t[0]:.1f} ... {t[-1]:.1f} s: bit speed {omega.min():.3f} ... '
          f'{omega.max():.3f} rad/s, TOB {rows[:, 3].min():.0f} ... {rows[:, 3].max():.0f} N m, '
          f'top torque {rows[:, 4].min():.0f} ... {rows[:, 4].max():.0f} N m, '
          f'radial at {station_m:.0f} m {rows[:, 5].min() * 100:.2f} ... '
          f'{rows[:, 5].max() * 100:.2f} cm (mean {rows[:, 5].mean() * 100:.2f} cm)')
    if starts.size < 2:
        print('fewer than two stick-slip cycles in the window (no upward crossing of the top '
              'speed): no per-cycle balance')
        return
    names = ('top drive', 'dE_lat', 'closure') + TERMS
    columns = (6, 7, 8) + tuple(range(9, 9 + len(TERMS)))
    print(f'{len(starts) - 1} cycles; per cycle (J):')
    print(f'{"from (s)":>9} {"T (s)":>6} ' + ' '.join(f'{n:>16}' for n in names))
    per_cycle = []
    for a, b in zip(starts[:-1], starts[1:]):
        change = [rows[b, c] - rows[a, c] for c in columns]
        per_cycle.append(change)
        print(f'{t[a]:9.2f} {t[b] - t[a]:6.2f} ' + ' '.join(f'{x:16.5g}' for x in change))
    per_cycle = np.array(per_cycle)
    print(f'{"mean":>9} {np.mean(np.diff(t[starts])):6.2f} '
          + ' '.join(f'{x:16.5g}' for x in per_cycle.mean(axis=0)))
    print(f'{"std":>9} {np.std(np.diff(t[starts])):6.2f} '
          + ' '.join(f'{x:16.5g}' for x in per_cycle.std(axis=0)))


if __name__ == '__main__':
    main()
