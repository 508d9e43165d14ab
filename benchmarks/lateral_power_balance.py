"""Where the lateral modes' energy comes from, term by term, for a reading (issue 12).

    python benchmarks/lateral_power_balance.py [--seconds 60] [--set KEY=VALUE ...]

Runs the mean model of the paper's point (any configuration through --set) with
:class:`~drill_twin.dynamics.power_balance.LateralEnergyBalance` and prints, every 10 s, the
lateral energy and the work each term has done on the lateral DOFs since the start (J):
damping, f_se, f_ke, the wall, the imbalance, and the closure (zero up to the iteration
error). A term with positive work feeds the lateral motion from the axial and torsional
motion (the top drive in the end).
"""
from __future__ import annotations

import argparse
import time

from threadpoolctl import threadpool_limits

from drill_twin.config import load_config
from drill_twin.dynamics.power_balance import TERMS, LateralEnergyBalance
from drill_twin.dynamics.simulator import Simulator


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=60.0)
    parser.add_argument('--set', dest='overrides', action='append', default=[])
    args = parser.parse_args()
    config = load_config(None, args.overrides)
    start = time.perf_counter()
    with threadpool_limits(limits=1, user_api='blas'):
        simulator = Simulator(config)
        balance = LateralEnergyBalance(simulator)
        print(f'{"t (s)":>6} {"E_lat":>10} ' + ' '.join(f'{t:>16}' for t in TERMS)
              + f' {"closure":>10}')
        steps = int(round(args.seconds / simulator.dt))
        every = int(round(10.0 / simulator.dt))
        for step in range(1, steps + 1):
            simulator.step()
            balance.update()
            if step % every == 0 or step == steps:
                work = balance.work_j
                print(f'{simulator.time_s:6.1f} {balance.energy_j()[0]:10.4g} '
                      + ' '.join(f'{work[t][0]:16.5g}' for t in TERMS)
                      + f' {balance.closure_j()[0]:10.3g}', flush=True)
    print(f'initial lateral energy {balance.energy_at_start_j[0]:.4g} J; '
          f'wall {time.perf_counter() - start:.0f} s')


if __name__ == '__main__':
    main()
